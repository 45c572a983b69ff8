//! Foxglove's well-known message kinds, derived from flight-log records for the MCAP log.
//!
//! In: one flight-log record (the JSON object `FlightLog` writes, see the module doc of
//! `flightlog`) and the run's start on the wall clock. Out: the messages that record shows in
//! Foxglove, each with its topic and schema, JSON-encoded:
//! - a `pose` record: `foxglove.PoseInFrame` on `/<drone>/pose` (frame `world`, ENU) and
//!   `foxglove.FrameTransform` on `/tf` (`world` to the drone's own frame, named by its id);
//! - a `behavior` record, and `mission`, `safety`, `collision`, `error` records:
//!   `foxglove.Log` on `/events` (`name` is the drone; behaviors at INFO unless they failed,
//!   safety overrides at WARNING, collisions and errors at ERROR); a behavior record that
//!   starts, changes or ends a goal or a path is also a `foxglove.SceneUpdate` on
//!   `/<drone>/plan` (`scene`). The world's obstacles (`scene::world`) are the caller's, who
//!   loads the header's world.
//!
//! Nothing here reads a clock or a file: `FlightLog`'s records come in, messages go out.

use serde_json::{json, Value};

/// The frame every position of a flight log is in (the fleet's shared ENU frame).
pub const WORLD_FRAME: &str = "world";

/// A JSON schema of one of Foxglove's message kinds.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Schema {
    PoseInFrame,
    FrameTransform,
    Log,
    SceneUpdate,
    Grid,
}

impl Schema {
    /// The schema's name, as Foxglove recognises it.
    pub fn name(self) -> &'static str {
        match self {
            Schema::PoseInFrame => "foxglove.PoseInFrame",
            Schema::FrameTransform => "foxglove.FrameTransform",
            Schema::Log => "foxglove.Log",
            Schema::SceneUpdate => "foxglove.SceneUpdate",
            Schema::Grid => "foxglove.Grid",
        }
    }

    /// The JSON schema (`jsonschema` encoding) of the kind's messages.
    pub fn json_schema(self) -> Value {
        let props = match self {
            Schema::PoseInFrame => json!({
                "timestamp": time(),
                "frame_id": { "type": "string" },
                "pose": pose(),
            }),
            Schema::FrameTransform => json!({
                "timestamp": time(),
                "parent_frame_id": { "type": "string" },
                "child_frame_id": { "type": "string" },
                "translation": vector3(),
                "rotation": quaternion(),
            }),
            Schema::Log => json!({
                "timestamp": time(),
                "level": {
                    "type": "integer",
                    "description": "0 unknown, 1 debug, 2 info, 3 warning, 4 error, 5 fatal",
                    "minimum": 0, "maximum": 5,
                },
                "message": { "type": "string" },
                "name": { "type": "string" },
                "file": { "type": "string" },
                "line": { "type": "integer", "minimum": 0 },
            }),
            Schema::Grid => json!({
                "timestamp": time(),
                "frame_id": { "type": "string" },
                "pose": pose(),
                "column_count": { "type": "integer", "minimum": 0 },
                "cell_size": {
                    "type": "object",
                    "properties": { "x": { "type": "number" }, "y": { "type": "number" } },
                },
                "row_stride": { "type": "integer", "minimum": 0 },
                "cell_stride": { "type": "integer", "minimum": 0 },
                "fields": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "properties": {
                            "name": { "type": "string" },
                            "offset": { "type": "integer", "minimum": 0 },
                            "type": { "type": "integer", "description": "1 is UINT8" },
                        },
                    },
                },
                "data": { "type": "string", "contentEncoding": "base64" },
            }),
            Schema::SceneUpdate => json!({
                "deletions": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "properties": {
                            "timestamp": time(),
                            "type": { "type": "integer", "description": "0 matching id, 1 all" },
                            "id": { "type": "string" },
                        },
                    },
                },
                "entities": {
                    "type": "array",
                    "items": {
                        "type": "object",
                        "description": "timestamp, frame_id, id, lifetime, frame_locked, \
                            metadata, and lists of arrows, cubes, spheres, cylinders, lines, \
                            triangles, texts and models (Foxglove's SceneEntity)",
                        "properties": {
                            "timestamp": time(),
                            "frame_id": { "type": "string" },
                            "id": { "type": "string" },
                        },
                    },
                },
            }),
        };
        json!({ "title": self.name(), "type": "object", "properties": props })
    }
}

fn time() -> Value {
    json!({
        "type": "object",
        "properties": {
            "sec": { "type": "integer", "minimum": 0 },
            "nsec": { "type": "integer", "minimum": 0, "maximum": 999_999_999 },
        },
    })
}

fn vector3() -> Value {
    json!({
        "type": "object",
        "properties": {
            "x": { "type": "number" }, "y": { "type": "number" }, "z": { "type": "number" },
        },
    })
}

fn quaternion() -> Value {
    json!({
        "type": "object",
        "properties": {
            "x": { "type": "number" }, "y": { "type": "number" },
            "z": { "type": "number" }, "w": { "type": "number" },
        },
    })
}

fn pose() -> Value {
    json!({
        "type": "object",
        "properties": { "position": vector3(), "orientation": quaternion() },
    })
}

/// `foxglove.Log` levels.
const INFO: u8 = 2;
const WARNING: u8 = 3;
const ERROR: u8 = 4;

/// One message for the MCAP log: where it goes, its kind and its JSON body.
#[derive(Debug, Clone, PartialEq)]
pub struct Derived {
    pub topic: String,
    pub schema: Schema,
    pub message: Value,
}

/// The Foxglove messages of one record stamped `log_time_ns` (ns since 1970, UTC); none for
/// records Foxglove has no kind for (the header, commands, clocks).
pub fn derive(record: &Value, log_time_ns: u64) -> Vec<Derived> {
    let stamp = json!({
        "sec": log_time_ns / 1_000_000_000,
        "nsec": log_time_ns % 1_000_000_000,
    });
    let drone = record.get("drone").and_then(Value::as_str).unwrap_or("");
    match record.get("type").and_then(Value::as_str) {
        Some("pose") => poses(record, drone, stamp),
        Some("behavior") => {
            let plan = super::scene::plan(record, &stamp).map(|message| Derived {
                topic: format!("/{drone}/plan"),
                schema: Schema::SceneUpdate,
                message,
            });
            let text = behavior_text(record);
            let mut out = vec![log(stamp, drone, behavior_level(record), text)];
            out.extend(plan);
            out
        }
        Some(kind @ ("mission" | "safety" | "collision" | "error")) => {
            let level = match kind {
                "mission" => INFO,
                "safety" => WARNING,
                _ => ERROR,
            };
            let reason = record.get("reason").and_then(Value::as_str).unwrap_or("");
            vec![log(stamp, drone, level, format!("{kind}: {reason}"))]
        }
        _ => Vec::new(),
    }
}

fn poses(record: &Value, drone: &str, stamp: Value) -> Vec<Derived> {
    let num = |k: &str| record.get(k).and_then(Value::as_f64);
    let (Some(x), Some(y), Some(z)) = (num("x"), num("y"), num("z")) else {
        return Vec::new();
    };
    let half_yaw = num("yaw").unwrap_or(0.0) / 2.0;
    let position = json!({ "x": x, "y": y, "z": z });
    let orientation = json!({ "x": 0.0, "y": 0.0, "z": half_yaw.sin(), "w": half_yaw.cos() });
    vec![
        Derived {
            topic: format!("/{drone}/pose"),
            schema: Schema::PoseInFrame,
            message: json!({
                "timestamp": stamp, "frame_id": WORLD_FRAME,
                "pose": { "position": position, "orientation": orientation },
            }),
        },
        Derived {
            topic: "/tf".into(),
            schema: Schema::FrameTransform,
            message: json!({
                "timestamp": stamp, "parent_frame_id": WORLD_FRAME, "child_frame_id": drone,
                "translation": position, "rotation": orientation,
            }),
        },
    ]
}

fn log(stamp: Value, drone: &str, level: u8, message: String) -> Derived {
    Derived {
        topic: "/events".into(),
        schema: Schema::Log,
        message: json!({
            "timestamp": stamp, "level": level, "message": message, "name": drone,
            "file": "", "line": 0,
        }),
    }
}

/// A finished behavior that did not succeed is a warning; everything else information.
fn behavior_level(record: &Value) -> u8 {
    let failed = record
        .get("result")
        .and_then(|r| r.get("result"))
        .and_then(Value::as_str)
        .is_some_and(|s| s != "succeeded");
    if failed {
        WARNING
    } else {
        INFO
    }
}

/// `<behavior> <event>` with the goal or the result, and the mission item when there is one.
fn behavior_text(record: &Value) -> String {
    let field = |k: &str| record.get(k).and_then(Value::as_str).unwrap_or("?");
    let mut text = format!("{} {}", field("behavior"), field("event"));
    for key in ["goal", "result"] {
        if let Some(v) = record.get(key).filter(|v| !v.is_null()) {
            text.push_str(&format!(" {key} {v}"));
        }
    }
    if let Some(m) = record.get("mission").filter(|m| !m.is_null()) {
        let id = m.get("mission_id").and_then(Value::as_str).unwrap_or("?");
        let item = m.get("item_index").and_then(Value::as_u64).unwrap_or(0);
        text.push_str(&format!(" (mission {id} item {item})"));
    }
    text
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_pose_is_a_pose_in_frame_and_a_transform_from_the_world() {
        let record = json!({ "t": 1.5, "drone": "drone_1", "type": "pose",
            "x": 1.0, "y": 2.0, "z": 3.0, "yaw": std::f64::consts::FRAC_PI_2 });
        let out = derive(&record, 1_700_000_001_500_000_000);
        assert_eq!(out.len(), 2);
        assert_eq!(out[0].topic, "/drone_1/pose");
        assert_eq!(
            out[0].message["timestamp"],
            json!({"sec": 1_700_000_001u64, "nsec": 500_000_000})
        );
        assert_eq!(
            out[0].message["pose"]["position"],
            json!({"x": 1.0, "y": 2.0, "z": 3.0})
        );
        let w = out[0].message["pose"]["orientation"]["w"]
            .as_f64()
            .unwrap_or(0.0);
        assert!((w - std::f64::consts::FRAC_1_SQRT_2).abs() < 1e-12);
        assert_eq!(out[1].schema, Schema::FrameTransform);
        assert_eq!(out[1].message["child_frame_id"], "drone_1");
        assert_eq!(out[1].message["parent_frame_id"], WORLD_FRAME);
    }

    #[test]
    fn events_are_logs_with_a_level() {
        let safety =
            json!({ "t": 2.0, "drone": "drone_0", "type": "safety", "reason": "geofence" });
        let out = derive(&safety, 0);
        assert_eq!(out[0].schema, Schema::Log);
        assert_eq!(out[0].message["level"], WARNING);
        assert_eq!(out[0].message["message"], "safety: geofence");
        let started = json!({ "t": 0.1, "drone": "drone_0", "type": "behavior", "event": "started",
            "id": 1, "behavior": "takeoff", "goal": { "height_m": 2.0 }, "mission": null });
        let out = derive(&started, 0);
        assert_eq!(out[0].message["level"], INFO);
        assert_eq!(out[0].message["name"], "drone_0");
        assert!(out[0].message["message"]
            .as_str()
            .unwrap_or("")
            .starts_with("takeoff started"));
        assert!(derive(&json!({ "t": 0.0, "drone": null, "type": "header" }), 0).is_empty());
    }
}
