//! Pose samples out of a JSON-lines flight log (`flightlog`'s `pose` records, or any record
//! with `t`, `drone`, `x`, `y`, `z`, `yaw` and no `type`).
//!
//! In: the log's text. Out: the [`PoseSample`]s in file order. Records of other types and
//! blank lines are skipped; a line over 1 MiB, a line that is not JSON, or a pose record
//! missing a numeric field is an error naming the line.

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
}

#[derive(Deserialize)]
#[serde(untagged)]
enum DroneId {
    Name(String),
    Number(i64),
}

pub fn poses_from_log(text: &str) -> Result<Vec<PoseSample>, EvalError> {
    let mut out = Vec::new();
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
        let typed_pose = match &r.kind {
            Some(kind) if kind.as_str() == Some("pose") => true,
            Some(_) => continue,
            None => false,
        };
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
            Some(DroneId::Name(s)) => s,
            Some(DroneId::Number(k)) => k.to_string(),
            None => {
                return Err(EvalError::PoseField {
                    line: line_no,
                    field: "drone",
                })
            }
        };
        out.push(PoseSample {
            t_s: field(r.t, "t")?,
            drone,
            x_m: field(r.x, "x")?,
            y_m: field(r.y, "y")?,
            z_m: field(r.z, "z")?,
            yaw_rad: field(r.yaw, "yaw")?,
        });
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
