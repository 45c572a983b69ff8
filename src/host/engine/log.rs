//! The host's flight log service: what the host writes of each tick, command and alert into
//! the [`FlightLog`] it was handed. Off until a log is set and after it is closed: then every
//! record is dropped and nothing is gathered for one.
//!
//! In: a drone's core and tick output, commands, alerts, the wall clock, the maps and the
//! frontier allocator's view at the map rate. Out: records written by `flightlog` (which knows
//! nothing of the host).

use crate::core::{DroneCore, TickOutput};
use crate::exploration::online::service::{ClaimView, FrontierView};
use crate::flightlog::map_record::known_box;
use crate::flightlog::FlightLog;
use crate::mapping::grid::CellBox;
use crate::mapping::merged::FleetMap;
use crate::types::Pose;
use serde_json::Value;
use std::collections::BTreeMap;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

#[derive(Default)]
pub(super) struct HostLog {
    log: Option<FlightLog>,
    maps: MapsLogged,
}

/// What the log holds of the maps and the frontiers.
#[derive(Default)]
struct MapsLogged {
    /// When `map` and `frontiers` records are next due; `None` before the first (which holds
    /// every known cell of each map).
    next: Option<Duration>,
    /// The cells of each drone's own map changed since its last `map` record.
    changed: BTreeMap<String, CellBox>,
    frontiers: Vec<FrontierView>,
    claims: Vec<ClaimView>,
}

impl HostLog {
    /// Writes into `log` from now on.
    pub(super) fn set(&mut self, log: FlightLog) {
        self.log = Some(log);
        self.maps = MapsLogged::default();
    }

    /// Whether records are written (callers skip gathering what would be dropped).
    pub(super) fn is_on(&self) -> bool {
        self.log.is_some()
    }

    /// A `clock` record: the wall clock `wall` at host time `t`.
    pub(super) fn wall_clock(&mut self, t: Duration, wall: SystemTime) {
        let unix_s = wall
            .duration_since(UNIX_EPOCH)
            .map_or(0.0, |d| d.as_secs_f64());
        if let Some(log) = self.log.as_mut() {
            log.clock(t, unix_s);
        }
    }

    /// Drone `core`'s tick: its pose (with `truth`, asked only when a record is written, for a
    /// drone whose estimate drifts) and its behaviors' events, each with the mission `item` it
    /// belongs to.
    pub(super) fn tick(
        &mut self,
        t: Duration,
        core: &DroneCore,
        out: &TickOutput,
        item: Option<&Value>,
        truth: impl FnOnce() -> Option<Pose>,
    ) {
        let Some(log) = self.log.as_mut() else {
            return;
        };
        let state = core.vehicle_state();
        let motion = core.server().motion().map(|(name, _)| name);
        log.pose(t, &state, motion, out.setpoint.as_ref(), truth().as_ref());
        for e in &out.events {
            log.behavior(t, core.drone_id(), e, item);
        }
        if let Some(region) = core.map().and_then(|m| m.last_changed()) {
            let slot = self
                .maps
                .changed
                .entry(core.drone_id().to_string())
                .or_insert(region);
            *slot = slot.union(region);
        }
    }

    /// At the map rate (`merged`'s update period, in host time): the cells of each drone's map
    /// and of the merged map changed since their last records (all known cells the first
    /// time), and the frontiers and the goals held when they changed. Nothing without a merged
    /// map (mapping off).
    pub(super) fn maps(
        &mut self,
        t: Duration,
        cores: &[DroneCore],
        merged: Option<&mut FleetMap>,
        exploration: (&[FrontierView], &[ClaimView]),
    ) {
        let (Some(log), Some(merged)) = (self.log.as_mut(), merged) else {
            return;
        };
        let first = match self.maps.next {
            Some(next) if t < next => return,
            Some(_) => false,
            None => true,
        };
        self.maps.next = Some(t + merged.update_period());
        for core in cores {
            let Some(map) = core.map() else { continue };
            let changed = self.maps.changed.remove(core.drone_id());
            let region = if first {
                known_box(map.grid())
            } else {
                changed
            };
            if let Some(region) = region {
                log.map(t, Some(core.drone_id()), map.grid(), region);
            }
        }
        let changed = merged.take_logged();
        let region = if first {
            known_box(merged.merged())
        } else {
            changed
        };
        if let Some(region) = region {
            log.map(t, None, merged.merged(), region);
        }
        let (frontiers, claims) = exploration;
        if frontiers != self.maps.frontiers || claims != self.maps.claims {
            log.frontiers(t, frontiers, claims);
            self.maps.frontiers = frontiers.to_vec();
            self.maps.claims = claims.to_vec();
        }
    }

    /// A command to `drone` and its fields.
    pub(super) fn command(&mut self, t: Duration, drone: &str, command: &str, fields: Value) {
        if let Some(log) = self.log.as_mut() {
            log.command(t, drone, command, fields);
        }
    }

    /// Something operators were told about `drone`, of kind `kind` (`mission`, `safety`, ...).
    pub(super) fn event(&mut self, t: Duration, drone: &str, kind: &str, reason: &str) {
        if let Some(log) = self.log.as_mut() {
            log.event(t, drone, kind, reason);
        }
    }

    pub(super) fn flush(&mut self) {
        if let Some(log) = self.log.as_mut() {
            log.flush();
        }
    }

    /// Flushes the log and lets it go: a log written in place (an MCAP log's summary) is
    /// finished, and nothing is written after this.
    pub(super) fn close(&mut self) {
        self.flush();
        self.log = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::{BehaviorEvent, Registry};
    use crate::core::CoreConfig;
    use crate::types::{Capabilities, Vec3};
    use std::io::Write;
    use std::sync::{Arc, Mutex};

    /// What a log wrote, readable while the log holds its writer.
    #[derive(Clone, Default)]
    struct Written(Arc<Mutex<Vec<u8>>>);

    impl Write for Written {
        fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
            self.0.lock().unwrap().extend_from_slice(buf);
            Ok(buf.len())
        }
        fn flush(&mut self) -> std::io::Result<()> {
            Ok(())
        }
    }

    impl Written {
        fn records(&self) -> Vec<Value> {
            let text = String::from_utf8(self.0.lock().unwrap().clone()).unwrap();
            crate::flightlog::read(&text).unwrap()
        }
    }

    fn log_into(written: &Written) -> HostLog {
        let mut log = HostLog::default();
        log.set(FlightLog::new(Box::new(written.clone()), 10.0));
        log
    }

    fn core() -> DroneCore {
        let capabilities = Capabilities::setpoints_only();
        DroneCore::new(
            CoreConfig::new("drone_0"),
            capabilities,
            Registry::with_motion_behaviors(),
        )
    }

    /// Without a log nothing is gathered: the truth of a drone is not asked for.
    #[test]
    fn off_it_asks_for_nothing() {
        let mut log = HostLog::default();
        assert!(!log.is_on());
        let out = TickOutput::default();
        log.tick(Duration::ZERO, &core(), &out, None, || panic!("no log"));
        log.event(Duration::ZERO, "drone_0", "mission", "dropped");
        log.close();
    }

    /// A tick writes the drone's pose, the truth beside it, and each behavior event with its
    /// mission item; the wall clock, commands and alerts are records of their own.
    #[test]
    fn it_writes_ticks_commands_alerts_and_the_clock() {
        let written = Written::default();
        let mut log = log_into(&written);
        assert!(log.is_on());
        let t = Duration::from_secs(2);
        log.wall_clock(t, UNIX_EPOCH + Duration::from_secs(1_700_000_000));
        let out = TickOutput {
            events: vec![BehaviorEvent::Paused {
                id: 3,
                behavior: "go_to".into(),
            }],
            ..TickOutput::default()
        };
        let truth = Pose::from_position_yaw(Vec3::new(1.0, 2.0, 3.0), 0.0);
        let item = serde_json::json!({ "mission_id": 1 });
        log.tick(t, &core(), &out, Some(&item), || Some(truth));
        log.command(
            t,
            "drone_0",
            "upload",
            serde_json::json!({ "mission_id": 1 }),
        );
        log.event(t, "drone_0", "safety", "too close");
        log.flush();
        let records = written.records();
        let kinds: Vec<&str> = records.iter().filter_map(|r| r["type"].as_str()).collect();
        assert_eq!(kinds, ["clock", "pose", "behavior", "command", "safety"]);
        assert_eq!(records[0]["unix_s"], 1.7e9);
        assert_eq!(records[1]["truth"]["y"], 2.0);
        assert_eq!(records[2]["mission"], item);
        assert_eq!(records[4]["reason"], "too close");
    }

    /// The maps at the map rate: every known cell first, then only what changed, nothing when
    /// nothing did; the frontiers when they changed.
    #[test]
    fn maps_and_frontiers_at_the_map_rate() {
        use crate::mapping::config::MapConfig;
        use crate::mapping::scan::{Beam, RangeScan};
        let scan = |x: f64, range_m: f64| RangeScan {
            origin_enu_m: nalgebra::Vector3::new(x, 0.05, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(range_m),
            }],
        };
        let written = Written::default();
        let mut log = log_into(&written);
        let mut merged = FleetMap::new(&MapConfig::open_field().unwrap()).unwrap();
        merged.insert("drone_0", &scan(0.05, 1.0)).unwrap();
        let frontier = FrontierView {
            centroid_enu_m: [1.0, 2.000_000_3],
            goal_enu_m: [0.5, 2.0],
            size_m: 1.0,
            orientation_rad: 0.0,
        };
        let cores = [core()];
        let at = |s: f64| Duration::from_secs_f64(s);
        let frontiers = [frontier];
        log.maps(at(0.0), &cores, Some(&mut merged), (&frontiers, &[]));
        merged.insert("drone_0", &scan(3.05, 0.5)).unwrap();
        log.maps(at(0.4), &cores, Some(&mut merged), (&frontiers, &[]));
        log.maps(at(0.5), &cores, Some(&mut merged), (&frontiers, &[]));
        log.maps(at(1.0), &cores, Some(&mut merged), (&frontiers, &[]));
        let records = written.records();
        let kinds: Vec<(&str, f64)> = records
            .iter()
            .map(|r| (r["type"].as_str().unwrap(), r["t"].as_f64().unwrap()))
            .collect();
        assert_eq!(kinds, [("map", 0.0), ("frontiers", 0.0), ("map", 0.5)]);
        let first = crate::flightlog::map_record::decode(&records[0]).unwrap();
        assert_eq!(first.region.width_cells(), 11, "the first scan's cells");
        let second = crate::flightlog::map_record::decode(&records[2]).unwrap();
        assert_eq!(
            second.region.width_cells(),
            6,
            "only the second scan's cells"
        );
        assert_eq!(
            records[1]["frontiers"][0]["goal_enu_m"],
            serde_json::json!([0.5, 2.0])
        );
    }

    /// Once closed, records are dropped.
    #[test]
    fn nothing_is_written_after_close() {
        let written = Written::default();
        let mut log = log_into(&written);
        log.event(Duration::ZERO, "drone_0", "mission", "kept");
        log.close();
        assert!(!log.is_on());
        log.event(Duration::ZERO, "drone_0", "mission", "dropped");
        log.command(Duration::ZERO, "drone_0", "upload", Value::Null);
        log.wall_clock(Duration::ZERO, SystemTime::now());
        let reasons: Vec<Value> = written
            .records()
            .iter()
            .map(|r| r["reason"].clone())
            .collect();
        assert_eq!(reasons, ["kept"]);
    }
}
