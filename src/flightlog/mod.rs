//! Flight log: one JSON object per line, written for every flight (real or simulated).
//!
//! Every record has `t` (seconds since the start of the run), `drone` and `type`:
//! - `header`: the first record (`drone` null): `version`, `command` (sim / run / explore),
//!   `start_time` (wall clock, RFC 3339 UTC), `drones`, `seed`, `world`, `scenario`, `mission`,
//!   `geo_origin` (`lat_deg`, `lon_deg`, `alt_m` of the ENU origin) and the whole `config`.
//! - `pose`: `x`, `y`, `z` (ENU m), `yaw` (rad), `vx`, `vy`, `vz` (m/s), `armed`, `flight`,
//!   `behavior` (the active motion behavior or null: never a gimbal or camera behavior),
//!   `mode`, `link`, `battery_v`, `battery_fraction` (null when unknown) and `setpoint` (what
//!   the controller sent the vehicle this tick: `kind` velocity / position with its fields, for
//!   tracking error; null when none); at `pose_rate_hz` (default 10 Hz). The pose is what the
//!   drone believes; where a simulated drone's estimate drifts (`[sim] position_drift_mps`) the
//!   record also has `truth` (`x`, `y`, `z`, `yaw`: where it really was), which evaluators use.
//!   While the map correction moves the vehicle's reported position (`[estimator.map_correction]`)
//!   the record has `map_offset` (`x`, `y`, ENU m: what it adds to the report to give `x`, `y`);
//!   the setpoint is in the same frame as the pose.
//! - `behavior`: a behavior event (`event` = started / paused / resumed / modified / finished,
//!   `id`, `behavior`, and `goal` or `result`), with `mission` (`mission_id`, `item_index`,
//!   `item`: the mission item running when it happened) or null outside missions.
//! - `command`: a command received from outside (`command` and its `fields`; uploads and
//!   MissionUpdates carry the mission itself in `fields.mission`).
//! - `collision` / `error`: what ended or disturbed the flight (`reason`).
//! - `map`: the cells of a drone's own map (`map` = `own`) or of the merged map (`map` =
//!   `merged`, `drone` null) that changed, at the map rate (`[map] update_rate_hz`, in the
//!   run's time), only when some did; the first of each map holds all its known cells
//!   ([`map_record`] has the fields).
//! - `frontiers` (`drone` null): the frontier allocator's `frontiers` (`centroid_enu_m`,
//!   `goal_enu_m`, `size_m`, `orientation_rad`) and `claims` (`drone`, `goal_enu_m`: the goal
//!   each drone holds), at the map rate when they changed.
//! - `clock` (`drone` null): `unix_s`, the wall clock (s since 1970, UTC) at this record's `t`;
//!   written when a real-time run's control loop starts, so the logs of a fleet's nodes can be
//!   put on one clock (`kestrel evaluate --log A --log B`).
//!
//! Outside tools read it line by line; later records never change earlier ones. The files
//! themselves (one per run, named by its start, pruned to a limit) are [`files`]'s.
//!
//! With [`LogFormat::Mcap`] the same records go into an MCAP file instead ([`mcap_log`]: the
//! records unchanged on their own channel, plus Foxglove's channels made of them by
//! [`foxglove`], and the grids kept from the `map` records by [`grids`]); [`reader`] reads
//! either format back as JSON lines.

pub mod files;
pub mod foxglove;
pub mod grid;
pub mod grids;
pub mod map_record;
pub mod mcap_log;
pub mod reader;
pub mod scene;
pub mod writer;

use crate::behavior::BehaviorEvent;
use crate::exploration::online::service::{ClaimView, FrontierView};
use crate::mapping::grid::{CellBox, OccupancyGrid};
use crate::types::{Pose, Setpoint, Vec3, VehicleState};
use serde_json::{json, Value};
use std::collections::HashMap;
use std::io::Write;
use std::time::Duration;

/// The file format of a flight log (`--log-format`, `[drone] log_format`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum LogFormat {
    /// One JSON record a line (`.jsonl`).
    #[default]
    Jsonl,
    /// MCAP with Foxglove's channels (`.mcap`).
    Mcap,
}

impl LogFormat {
    /// The file extension of the format, without its dot.
    pub fn extension(self) -> &'static str {
        match self {
            LogFormat::Jsonl => "jsonl",
            LogFormat::Mcap => "mcap",
        }
    }
}

/// A `--log-format` that is neither `jsonl` nor `mcap`.
#[derive(Debug, thiserror::Error)]
#[error("unknown log format {0:?} (jsonl or mcap)")]
pub struct UnknownLogFormat(String);

impl std::str::FromStr for LogFormat {
    type Err = UnknownLogFormat;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        match s {
            "jsonl" => Ok(LogFormat::Jsonl),
            "mcap" => Ok(LogFormat::Mcap),
            other => Err(UnknownLogFormat(other.to_string())),
        }
    }
}

pub struct FlightLog {
    out: Box<dyn Write + Send>,
    pose_period: Duration,
    next_pose: HashMap<String, Duration>,
    failed: Option<String>,
}

impl FlightLog {
    pub fn new(out: Box<dyn Write + Send>, pose_rate_hz: f64) -> Self {
        Self {
            out,
            pose_period: Duration::from_secs_f64(1.0 / pose_rate_hz.max(0.1)),
            next_pose: HashMap::new(),
            failed: None,
        }
    }

    /// Writes to a new file at `path`; an existing file is never overwritten.
    pub fn create(path: &std::path::Path) -> std::io::Result<Self> {
        let file = files::create_at(path, false)?;
        Ok(Self::new(Box::new(std::io::BufWriter::new(file)), 10.0))
    }

    /// The first write error, if any; logging never stops the flight.
    pub fn error(&self) -> Option<&str> {
        self.failed.as_deref()
    }

    fn write(&mut self, record: Value) {
        if self.failed.is_some() {
            return;
        }
        let line = record.to_string();
        if let Err(e) = writeln!(self.out, "{line}") {
            self.failed = Some(e.to_string());
        }
    }

    /// Whether a pose record of `drone` is due at `t` (so callers can skip gathering it).
    pub fn pose_due(&self, t: Duration, drone: &str) -> bool {
        self.next_pose.get(drone).is_none_or(|next| t >= *next)
    }

    /// The first record: what this run is (see the module doc); `fields` is an object.
    pub fn header(&mut self, fields: Value) {
        let mut record = json!({ "t": 0.0, "drone": null, "type": "header" });
        if let (Value::Object(map), Value::Object(extra)) = (&mut record, fields) {
            map.extend(extra);
        }
        self.write(record);
    }

    /// Writes a pose record if one is due for this drone, with the true pose where the
    /// estimate is known to differ from it.
    pub fn pose(
        &mut self,
        t: Duration,
        state: &VehicleState,
        behavior: Option<&str>,
        setpoint: Option<&Setpoint>,
        truth: Option<&Pose>,
        map_offset_m: Vec3,
    ) {
        if !self.pose_due(t, &state.drone) {
            return;
        }
        self.next_pose
            .insert(state.drone.clone(), t + self.pose_period);
        let p = state.estimate.pose.position_m;
        let v = state.estimate.velocity_enu_mps;
        let mut record = json!({
            "t": t.as_secs_f64(), "drone": state.drone, "type": "pose",
            "x": p.x, "y": p.y, "z": p.z, "yaw": state.estimate.pose.yaw_rad(),
            "vx": v.x, "vy": v.y, "vz": v.z,
            "armed": state.platform.armed, "flight": state.platform.flight, "behavior": behavior,
            "mode": state.platform.mode, "link": state.platform.link,
            "battery_v": state.platform.battery.map(|b| b.voltage_v),
            "battery_fraction": state.platform.battery.and_then(|b| b.remaining_fraction),
            "setpoint": setpoint,
        });
        if let Value::Object(map) = &mut record {
            if let Some(truth) = truth {
                let q = truth.position_m;
                map.insert(
                    "truth".into(),
                    json!({"x": q.x, "y": q.y, "z": q.z, "yaw": truth.yaw_rad()}),
                );
            }
            if map_offset_m != Vec3::zeros() {
                let o = map_offset_m;
                map.insert("map_offset".into(), json!({"x": o.x, "y": o.y}));
            }
        }
        self.write(record);
    }

    /// A behavior event, with the mission item it belongs to (`mission`, null outside missions).
    pub fn behavior(
        &mut self,
        t: Duration,
        drone: &str,
        event: &BehaviorEvent,
        mission: Option<&Value>,
    ) {
        let mut record = serde_json::to_value(event).unwrap_or(Value::Null);
        if let Value::Object(map) = &mut record {
            map.insert("mission".into(), mission.cloned().unwrap_or(Value::Null));
            map.insert("t".into(), json!(t.as_secs_f64()));
            map.insert("drone".into(), json!(drone));
            map.insert("type".into(), json!("behavior"));
        }
        self.write(record);
    }

    pub fn command(&mut self, t: Duration, drone: &str, command: &str, fields: Value) {
        self.write(json!({ "t": t.as_secs_f64(), "drone": drone, "type": "command", "command": command, "fields": fields }));
    }

    pub fn event(&mut self, t: Duration, drone: &str, kind: &str, reason: &str) {
        self.write(json!({ "t": t.as_secs_f64(), "drone": drone, "type": kind, "reason": reason }));
    }

    /// One `map` record: the cells of `grid` in `band` (`drone`'s own map, or the merged map
    /// for `None`; at most [`map_record::MAX_BAND_CELLS`]), `more` when bands of the same update
    /// follow.
    pub fn map_band(
        &mut self,
        t: Duration,
        drone: Option<&str>,
        grid: &OccupancyGrid,
        band: CellBox,
        more: bool,
    ) {
        if let Some(record) = map_record::record(t, drone, grid, band, more) {
            self.write(record);
        }
    }

    /// The frontier allocator's frontiers and the goals the drones hold, to the millimetre
    /// (and milliradian): dozens of frontiers at the map rate, the digits beyond are bytes only.
    pub fn frontiers(&mut self, t: Duration, frontiers: &[FrontierView], claims: &[ClaimView]) {
        let mm = |v: f64| (v * 1000.0).round() / 1000.0;
        let xy = |[x, y]: [f64; 2]| [mm(x), mm(y)];
        let frontiers: Vec<Value> = frontiers
            .iter()
            .map(|f| {
                json!({
                    "centroid_enu_m": xy(f.centroid_enu_m), "goal_enu_m": xy(f.goal_enu_m),
                    "size_m": mm(f.size_m), "orientation_rad": mm(f.orientation_rad),
                })
            })
            .collect();
        let claims: Vec<Value> = claims
            .iter()
            .map(|c| json!({ "drone": c.drone, "goal_enu_m": xy(c.goal_enu_m) }))
            .collect();
        self.write(json!({
            "t": t.as_secs_f64(), "drone": null, "type": "frontiers",
            "frontiers": frontiers, "claims": claims,
        }));
    }

    pub fn clock(&mut self, t: Duration, unix_s: f64) {
        self.write(
            json!({ "t": t.as_secs_f64(), "drone": null, "type": "clock", "unix_s": unix_s }),
        );
    }

    pub fn flush(&mut self) {
        if let Err(e) = self.out.flush() {
            self.failed.get_or_insert(e.to_string());
        }
    }
}

/// Reads a flight log back (for tests and plotting tools).
pub fn read(text: &str) -> Result<Vec<Value>, serde_json::Error> {
    text.lines()
        .filter(|l| !l.trim().is_empty())
        .map(serde_json::from_str)
        .collect()
}
