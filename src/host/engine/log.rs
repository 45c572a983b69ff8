//! The host's flight log service: what the host writes of each tick, command and alert into
//! the [`FlightLog`] it was handed. Off until a log is set and after it is closed: then every
//! record is dropped and nothing is gathered for one.
//!
//! In: a drone's core and tick output, commands, alerts, the wall clock, the maps and the
//! frontier allocator's view at the map rate. Out: records written by `flightlog` (which knows
//! nothing of the host). A map's changed region is written in bands of rows, at most
//! [`MAP_CELLS_PER_TICK`] cells a tick, so a large one (the first, or a peer's whole layer)
//! spreads over a few ticks instead of lengthening one.

use crate::core::{DroneCore, TickOutput};
use crate::exploration::online::service::{ClaimView, FrontierView};
use crate::flightlog::map_record::{known_box, MAX_BAND_CELLS};
use crate::flightlog::FlightLog;
use crate::mapping::grid::{Cell, CellBox, OccupancyGrid};
use crate::mapping::merged::FleetMap;
use crate::types::Pose;
use serde_json::Value;
use std::collections::{BTreeMap, VecDeque};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

/// Most map cells made into records on one tick (32 Ki: a whole 400 x 400 map's record took
/// 6-7.5 ms in the debug build, BENCHMARKS.md "MCAP flight logs", so this share about 1.5 ms).
const MAP_CELLS_PER_TICK: u32 = 1 << 15;

#[derive(Default)]
pub(super) struct HostLog {
    log: Option<FlightLog>,
    maps: MapsLogged,
}

/// What the log holds of the maps and the frontiers.
struct MapsLogged {
    /// When `map` and `frontiers` records are next due; `None` before the first (which holds
    /// every known cell of each map).
    next: Option<Duration>,
    /// The cells of each drone's own map changed since its last `map` record.
    changed: BTreeMap<String, CellBox>,
    /// Regions being written, oldest first; at most one started and one waiting per map.
    queue: VecDeque<Queued>,
    cells_per_tick: u32,
    frontiers: Vec<FrontierView>,
    claims: Vec<ClaimView>,
}

impl Default for MapsLogged {
    fn default() -> Self {
        Self {
            next: None,
            changed: BTreeMap::new(),
            queue: VecDeque::new(),
            cells_per_tick: MAP_CELLS_PER_TICK,
            frontiers: Vec::new(),
            claims: Vec::new(),
        }
    }
}

/// A map region to write: whose map (`None`: the merged one) and the first row not written.
struct Queued {
    drone: Option<String>,
    region: CellBox,
    next_row: u32,
}

impl MapsLogged {
    /// Queues `region` of `drone`'s map (the merged map for `None`), inside `grid`; joins the
    /// region waiting for the same map, if one is.
    fn enqueue(&mut self, drone: Option<&str>, grid: &OccupancyGrid, region: CellBox) {
        let Some(region) = region.intersect(grid.spec().full_box()) else {
            return;
        };
        let waiting = self
            .queue
            .iter_mut()
            .find(|q| q.drone.as_deref() == drone && q.next_row == q.region.min.y);
        match waiting {
            Some(q) => {
                q.region = q.region.union(region);
                q.next_row = q.region.min.y;
            }
            None => self.queue.push_back(Queued {
                drone: drone.map(str::to_string),
                region,
                next_row: region.min.y,
            }),
        }
    }

    /// Writes bands of the queued regions, at most `cells_per_tick` cells (one row at least).
    fn write_some(
        &mut self,
        log: &mut FlightLog,
        t: Duration,
        cores: &[DroneCore],
        merged: &FleetMap,
    ) {
        let mut budget = self.cells_per_tick;
        while budget > 0 {
            let Some(q) = self.queue.front_mut() else {
                return;
            };
            let grid = match &q.drone {
                Some(d) => cores
                    .iter()
                    .find(|c| c.drone_id() == d)
                    .and_then(|c| c.map())
                    .map(|m| m.grid()),
                None => Some(merged.merged()),
            };
            let width = q.region.width_cells().max(1);
            let left = q.region.max.y.saturating_sub(q.next_row) + 1;
            let rows = (budget.min(MAX_BAND_CELLS) / width).clamp(1, left);
            let band = CellBox {
                min: Cell {
                    x: q.region.min.x,
                    y: q.next_row,
                },
                max: Cell {
                    x: q.region.max.x,
                    y: q.next_row + rows - 1,
                },
            };
            let more = rows < left;
            if let Some(grid) = grid {
                log.map_band(t, q.drone.as_deref(), grid, band, more);
            }
            budget = budget.saturating_sub(rows * width);
            if more && grid.is_some() {
                q.next_row += rows;
            } else {
                self.queue.pop_front();
            }
        }
    }
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
    /// belongs to; the cells its map changed are kept for the next `map` record.
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
        let offset = core.map_offset_m();
        log.pose(
            t,
            &state,
            motion,
            out.setpoint.as_ref(),
            truth().as_ref(),
            offset,
        );
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
    /// time) are queued, and the frontiers and the goals held written when they changed. On
    /// every tick, bands of what is queued are written. Nothing without a merged map (mapping
    /// off).
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
        let maps = &mut self.maps;
        let first = maps.next.is_none();
        if maps.next.is_none_or(|next| t >= next) {
            maps.next = Some(t + merged.update_period());
            for core in cores {
                let Some(map) = core.map() else { continue };
                let changed = maps.changed.remove(core.drone_id());
                let region = if first {
                    known_box(map.grid())
                } else {
                    changed
                };
                if let Some(region) = region {
                    maps.enqueue(Some(core.drone_id()), map.grid(), region);
                }
            }
            let changed = merged.take_logged();
            let region = if first {
                known_box(merged.merged())
            } else {
                changed
            };
            if let Some(region) = region {
                maps.enqueue(None, merged.merged(), region);
            }
            let (frontiers, claims) = exploration;
            if frontiers != maps.frontiers || claims != maps.claims {
                log.frontiers(t, frontiers, claims);
                maps.frontiers = frontiers.to_vec();
                maps.claims = claims.to_vec();
            }
        }
        maps.write_some(log, t, cores, merged);
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
    use crate::flightlog::map_record::decode;
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

    fn scan_at(x: f64, y: f64, range_m: f64) -> crate::mapping::scan::RangeScan {
        crate::mapping::scan::RangeScan {
            origin_enu_m: nalgebra::Vector3::new(x, y, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams: vec![crate::mapping::scan::Beam {
                angle_rad: 0.0,
                range_m: Some(range_m),
            }],
        }
    }

    fn open_field() -> FleetMap {
        FleetMap::new(&crate::mapping::config::MapConfig::open_field().unwrap()).unwrap()
    }

    fn at(s: f64) -> Duration {
        Duration::from_secs_f64(s)
    }

    /// The maps at the map rate: every known cell first, then only what changed, nothing when
    /// nothing did; the frontiers when they changed, to the millimetre.
    #[test]
    fn maps_and_frontiers_at_the_map_rate() {
        let written = Written::default();
        let mut log = log_into(&written);
        let mut merged = open_field();
        merged.insert("drone_0", &scan_at(0.05, 0.05, 1.0)).unwrap();
        let frontier = FrontierView {
            centroid_enu_m: [1.0, 2.000_000_3],
            goal_enu_m: [0.5, 2.0],
            size_m: 1.0,
            orientation_rad: 0.0,
        };
        let cores = [core()];
        let frontiers = [frontier];
        log.maps(at(0.0), &cores, Some(&mut merged), (&frontiers, &[]));
        merged.insert("drone_0", &scan_at(3.05, 0.05, 0.5)).unwrap();
        log.maps(at(0.4), &cores, Some(&mut merged), (&frontiers, &[]));
        log.maps(at(0.5), &cores, Some(&mut merged), (&frontiers, &[]));
        log.maps(at(1.0), &cores, Some(&mut merged), (&frontiers, &[]));
        let records = written.records();
        let kinds: Vec<(&str, f64)> = records
            .iter()
            .map(|r| (r["type"].as_str().unwrap(), r["t"].as_f64().unwrap()))
            .collect();
        assert_eq!(kinds, [("frontiers", 0.0), ("map", 0.0), ("map", 0.5)]);
        let first = decode(&records[1]).unwrap();
        assert_eq!(first.region.width_cells(), 11, "the first scan's cells");
        let second = decode(&records[2]).unwrap();
        assert_eq!(second.region.width_cells(), 6, "only the second scan's");
        let f = &records[0]["frontiers"][0];
        assert_eq!(f["goal_enu_m"], serde_json::json!([0.5, 2.0]));
        assert_eq!(
            f["centroid_enu_m"],
            serde_json::json!([1.0, 2.0]),
            "to the mm"
        );
    }

    /// A region larger than a tick's share is written in bands over the next ticks, all but
    /// the last saying more follow; together they are the map.
    #[test]
    fn a_large_region_is_written_over_several_ticks() {
        let written = Written::default();
        let mut log = log_into(&written);
        log.maps.cells_per_tick = 22;
        let mut merged = open_field();
        merged.insert("drone_0", &scan_at(0.05, 0.05, 1.0)).unwrap();
        merged.insert("drone_0", &scan_at(0.05, 0.35, 1.0)).unwrap();
        let cores = [core()];
        for tick in 0..4 {
            log.maps(
                at(0.01 * f64::from(tick)),
                &cores,
                Some(&mut merged),
                (&[], &[]),
            );
        }
        let records = written.records();
        assert_eq!(records.len(), 2, "11 x 4 cells, 2 rows a tick");
        let (a, b) = (decode(&records[0]).unwrap(), decode(&records[1]).unwrap());
        assert!(a.more && !b.more);
        assert_eq!((a.region.height_cells(), b.region.height_cells()), (2, 2));
        assert_eq!(
            (records[0]["t"].as_f64(), records[1]["t"].as_f64()),
            (Some(0.0), Some(0.01))
        );
        assert_eq!(a.region.max.y + 1, b.region.min.y);
        let whole = merged.merged().patch(a.region.union(b.region)).unwrap();
        assert_eq!([a.cells, b.cells].concat(), whole.data);
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
