//! The host's flight log service: what the host writes of each tick, command and alert into
//! the [`FlightLog`] it was handed. Off until a log is set and after it is closed: then every
//! record is dropped and nothing is gathered for one.
//!
//! In: a drone's core and tick output, commands, alerts, the wall clock. Out: records written
//! by `flightlog` (which knows nothing of the host).

use crate::core::{DroneCore, TickOutput};
use crate::flightlog::FlightLog;
use crate::types::Pose;
use serde_json::Value;
use std::time::{Duration, SystemTime, UNIX_EPOCH};

#[derive(Default)]
pub(super) struct HostLog {
    log: Option<FlightLog>,
}

impl HostLog {
    /// Writes into `log` from now on.
    pub(super) fn set(&mut self, log: FlightLog) {
        self.log = Some(log);
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
