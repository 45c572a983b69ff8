//! Pose samples out of a JSON-lines flight log (`flightlog`'s `pose` records, or any record
//! with `t`, `drone`, `x`, `y`, `z`, `yaw` and no `type`).
//!
//! In: the log's text. Out: the [`PoseSample`]s in file order: where the drone really was, so
//! a record's `truth` (a simulated drone whose estimate drifts) is taken over its own `x`, `y`,
//! `z` and `yaw`, which are the drone's belief. Records of other types and blank lines are
//! skipped, and so are poses whose `flight` says the motors are off (`disarmed`): such a
//! vehicle is on the ground whatever height it reads (PX4 reports a vehicle resting on the
//! ground up to 1 m above its home, and its estimate may creep there). A pose whose `flight`
//! is `crashed` is kept and marked, and so is a drone's latest pose before a `collision`
//! record: the simulator ended that flight at a contact. A line over
//! 1 MiB, a line that is not JSON, or a pose record missing a numeric field is an error naming
//! the line.
//!
//! A fleet flown by several Kestrels (the fleet bus) leaves one log per node:
//! [`poses_from_logs`] puts them on one clock through each log's first `clock` record.

use super::{EvalError, PoseSample};
use serde::Deserialize;

/// Longest line read (bytes).
pub const MAX_LINE_BYTES: usize = 1 << 20;

#[derive(Deserialize)]
struct Record {
    #[serde(rename = "type")]
    kind: Option<serde_json::Value>,
    t: Option<f64>,
    drone: Option<DroneId>,
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    yaw: Option<f64>,
    unix_s: Option<f64>,
    flight: Option<String>,
    truth: Option<Truth>,
}

/// A pose record's `truth`.
#[derive(Deserialize)]
struct Truth {
    x: Option<f64>,
    y: Option<f64>,
    z: Option<f64>,
    yaw: Option<f64>,
}

#[derive(Deserialize)]
#[serde(untagged)]
enum DroneId {
    Name(String),
    Number(i64),
}

impl DroneId {
    fn name(&self) -> String {
        match self {
            DroneId::Name(s) => s.clone(),
            DroneId::Number(k) => k.to_string(),
        }
    }
}

pub fn poses_from_log(text: &str) -> Result<Vec<PoseSample>, EvalError> {
    let mut out: Vec<PoseSample> = Vec::new();
    for (n, line) in text.lines().enumerate() {
        let line_no = n + 1;
        if line.len() > MAX_LINE_BYTES {
            return Err(EvalError::LineTooLong {
                line: line_no,
                max_bytes: MAX_LINE_BYTES,
            });
        }
        if line.trim().is_empty() {
            continue;
        }
        let r: Record = serde_json::from_str(line).map_err(|source| EvalError::Json {
            line: line_no,
            source,
        })?;
        let typed_pose = match r.kind.as_ref().map(serde_json::Value::as_str) {
            Some(Some("pose")) => true,
            Some(Some("collision")) => {
                let drone = r.drone.as_ref().map(DroneId::name);
                if let Some(last) = out
                    .iter_mut()
                    .rev()
                    .find(|p| Some(&p.drone) == drone.as_ref())
                {
                    last.crashed = true;
                }
                continue;
            }
            Some(_) => continue,
            None => false,
        };
        if r.flight.as_deref() == Some("disarmed") {
            continue;
        }
        let fields = [r.t, r.x, r.y, r.z, r.yaw];
        if !typed_pose && (r.drone.is_none() || fields.iter().any(Option::is_none)) {
            continue;
        }
        let field = |v: Option<f64>, name: &'static str| {
            v.ok_or(EvalError::PoseField {
                line: line_no,
                field: name,
            })
        };
        let drone = match r.drone {
            Some(id) => id.name(),
            None => {
                return Err(EvalError::PoseField {
                    line: line_no,
                    field: "drone",
                })
            }
        };
        let (x_m, y_m, z_m, yaw_rad) = match &r.truth {
            Some(q) => (
                field(q.x, "truth.x")?,
                field(q.y, "truth.y")?,
                field(q.z, "truth.z")?,
                field(q.yaw, "truth.yaw")?,
            ),
            None => (
                field(r.x, "x")?,
                field(r.y, "y")?,
                field(r.z, "z")?,
                field(r.yaw, "yaw")?,
            ),
        };
        out.push(PoseSample {
            t_s: field(r.t, "t")?,
            drone,
            x_m,
            y_m,
            z_m,
            yaw_rad,
            crashed: r.flight.as_deref() == Some("crashed"),
        });
    }
    Ok(out)
}

/// Why several logs could not be put together.
#[derive(Debug, thiserror::Error)]
pub enum MergeError {
    #[error("log {log}: {source}")]
    Log { log: usize, source: EvalError },
    #[error("log {log} has no clock record (a real-time run's): its clock cannot be matched to the others'")]
    NoStart { log: usize },
    #[error("drone {drone} is in log {first} and in log {second}: one drone's poses must come from one log")]
    DroneTwice {
        drone: String,
        first: usize,
        second: usize,
    },
}

/// The wall clock (s since 1970) at a log's `t` = 0, from its first `clock` record, if any.
pub fn start_unix_s(text: &str) -> Option<f64> {
    text.lines()
        .filter(|l| l.len() <= MAX_LINE_BYTES && l.contains("\"clock\""))
        .filter_map(|l| serde_json::from_str::<Record>(l).ok())
        .find(|r| r.kind.as_ref().and_then(|k| k.as_str()) == Some("clock"))
        .and_then(|r| Some(r.unix_s? - r.t?))
        .filter(|s| s.is_finite())
}

/// The poses of several logs (numbered from 0 in errors) on the clock of the earliest: each
/// log's `t` is shifted by how much later its `t` = 0 was on the wall clock ([`start_unix_s`]).
/// One log is read as it is, clock or not.
pub fn poses_from_logs(texts: &[&str]) -> Result<Vec<PoseSample>, MergeError> {
    if let [one] = texts {
        return poses_from_log(one).map_err(|source| MergeError::Log { log: 0, source });
    }
    let starts = texts
        .iter()
        .enumerate()
        .map(|(log, t)| start_unix_s(t).ok_or(MergeError::NoStart { log }))
        .collect::<Result<Vec<f64>, _>>()?;
    let earliest = starts.iter().copied().fold(f64::INFINITY, f64::min);
    let mut owner: std::collections::HashMap<String, usize> = Default::default();
    let mut out = Vec::new();
    for (log, (text, start)) in texts.iter().zip(&starts).enumerate() {
        let poses = poses_from_log(text).map_err(|source| MergeError::Log { log, source })?;
        for p in &poses {
            match owner.get(&p.drone) {
                Some(&first) if first != log => {
                    return Err(MergeError::DroneTwice {
                        drone: p.drone.clone(),
                        first,
                        second: log,
                    })
                }
                Some(_) => {}
                None => {
                    owner.insert(p.drone.clone(), log);
                }
            }
        }
        let shift = start - earliest;
        out.extend(poses.into_iter().map(|p| PoseSample {
            t_s: p.t_s + shift,
            ..p
        }));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reads_pose_records_and_untyped_poses_and_skips_the_rest() {
        let text = r#"{"t":0.0,"drone":"d0","type":"pose","x":1,"y":2,"z":0,"yaw":0.5,"vx":0,"armed":true,"behavior":null}
{"t":0.1,"drone":"d0","type":"behavior","event":"started","x":9}

{"t":0.2,"drone":3,"x":1.5,"y":2,"z":1,"yaw":0}
{"t":0.3,"drone":"d1","x":1.5}
"#;
        let poses = poses_from_log(text).unwrap();
        assert_eq!(poses.len(), 2);
        assert_eq!(poses[0].drone, "d0");
        assert_eq!((poses[0].x_m, poses[0].yaw_rad), (1.0, 0.5));
        assert_eq!((poses[1].drone.as_str(), poses[1].z_m), ("3", 1.0));
    }

    #[test]
    fn a_disarmed_vehicle_is_on_the_ground_whatever_height_it_reads() {
        let text = r#"{"t":0.0,"drone":"d0","type":"pose","x":1,"y":2,"z":0.4,"yaw":0,"flight":"disarmed"}
{"t":0.1,"drone":"d0","type":"pose","x":1,"y":2,"z":0.4,"yaw":0,"flight":"landed"}
{"t":0.2,"drone":"d0","type":"pose","x":1,"y":2,"z":1.0,"yaw":0,"flight":"flying"}
"#;
        let poses = poses_from_log(text).unwrap();
        let times: Vec<f64> = poses.iter().map(|p| p.t_s).collect();
        assert_eq!(times, [0.1, 0.2]);
        assert!(poses.iter().all(|p| !p.crashed));
        let crashed = text.replace(r#""flight":"flying""#, r#""flight":"crashed""#);
        let poses = poses_from_log(&crashed).unwrap();
        assert!(poses[1].crashed, "a crashed vehicle is kept, marked");
        // The simulator's collision record, logged after the last pose of the flight.
        let collided = format!(
            "{text}{}\n",
            r#"{"t":0.21,"drone":"d0","type":"collision","reason":"collision with obstacle 3"}"#
        );
        let poses = poses_from_log(&collided).unwrap();
        let marked: Vec<bool> = poses.iter().map(|p| p.crashed).collect();
        assert_eq!(marked, [false, true]);
    }

    #[test]
    fn a_records_truth_is_where_the_drone_was() {
        let text = r#"{"t":1.0,"drone":"d0","type":"pose","x":1,"y":2,"z":1,"yaw":0.5,"truth":{"x":1.3,"y":1.9,"z":1,"yaw":0.5}}
"#;
        let p = &poses_from_log(text).unwrap()[0];
        assert_eq!((p.x_m, p.y_m, p.z_m, p.yaw_rad), (1.3, 1.9, 1.0, 0.5));
        let partial = text.replace(r#","yaw":0.5}"#, "}");
        assert!(matches!(
            poses_from_log(&partial),
            Err(EvalError::PoseField {
                line: 1,
                field: "truth.yaw"
            })
        ));
    }

    #[test]
    fn logs_of_several_nodes_are_put_on_the_earliest_clock() {
        let a = r#"{"t":0,"drone":null,"type":"header"}
{"t":0.5,"drone":null,"type":"clock","unix_s":1000.75}
{"t":1.0,"drone":"d0","type":"pose","x":1,"y":2,"z":1,"yaw":0}
"#;
        let b = r#"{"t":0.0,"drone":null,"type":"clock","unix_s":1002.0}
{"t":1.0,"drone":"d1","type":"pose","x":5,"y":2,"z":1,"yaw":0}
"#;
        let poses = poses_from_logs(&[a, b]).unwrap();
        let t: Vec<(&str, f64)> = poses.iter().map(|p| (p.drone.as_str(), p.t_s)).collect();
        assert_eq!(t, [("d0", 1.0), ("d1", 2.75)]);
        // One drone in two logs, or a log without a start, cannot be merged.
        let again = b.replace("d1", "d0");
        assert!(matches!(
            poses_from_logs(&[a, &again]),
            Err(MergeError::DroneTwice {
                first: 0,
                second: 1,
                ..
            })
        ));
        let bare = "{\"t\":1.0,\"drone\":\"d2\",\"x\":0,\"y\":0,\"z\":1,\"yaw\":0}\n";
        assert!(matches!(
            poses_from_logs(&[a, bare]),
            Err(MergeError::NoStart { log: 1 })
        ));
        // One log needs no header.
        assert_eq!(poses_from_logs(&[bare]).unwrap().len(), 1);
    }

    #[test]
    fn bad_lines_are_errors_that_name_the_line() {
        let missing = "{\"t\":0,\"drone\":\"a\",\"type\":\"pose\",\"x\":1,\"y\":2,\"z\":1}\n";
        assert!(matches!(
            poses_from_log(missing),
            Err(EvalError::PoseField {
                line: 1,
                field: "yaw"
            })
        ));
        assert!(matches!(
            poses_from_log("\n{not json\n"),
            Err(EvalError::Json { line: 2, .. })
        ));
        let long = format!("{{\"pad\":\"{}\"}}", "x".repeat(MAX_LINE_BYTES));
        assert!(matches!(
            poses_from_log(&long),
            Err(EvalError::LineTooLong { line: 1, .. })
        ));
    }
}
