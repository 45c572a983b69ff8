//! A flight log read for a report: poses and behavior activations per drone.
//!
//! In: any reader of a JSON-lines flight log (`flightlog`'s format). Out: [`Flight`]: the
//! header, every drone's pose records in file order and its behavior bars (`started` to
//! `finished`, or to the drone's last record when never finished), plus how many lines were
//! skipped as malformed. A line longer than [`MAX_LINE_BYTES`] or more than [`MAX_POSES`] pose
//! records is an error naming the line; a line that is not a JSON object with a `type`, or a
//! pose without numeric `t`, `x`, `y`, `z`, is skipped and counted (the log is outside input,
//! and a crash can cut its last line).

use super::ReportError;
use serde_json::Value;
use std::collections::BTreeMap;
use std::io::{BufRead, Read};

/// Longest line read (bytes), as `exploration::offline::evaluate`.
pub const MAX_LINE_BYTES: usize = 1 << 20;
/// Most pose records kept (a 7-drone hour at 20 Hz is 504 000; each costs about 150 bytes).
pub const MAX_POSES: usize = 5_000_000;
/// How many skipped line numbers the page lists.
const LISTED_SKIPS: usize = 10;

/// What the vehicle was told in a pose record's tick.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SetpointSample {
    /// Position setpoint (ENU m).
    Position([f64; 3]),
    /// Velocity setpoint (ENU m/s).
    Velocity([f64; 3]),
}

/// One `pose` record.
#[derive(Debug, Clone, PartialEq)]
pub struct Pose {
    pub t_s: f64,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub yaw_rad: f64,
    pub vx_mps: f64,
    pub vy_mps: f64,
    pub vz_mps: f64,
    pub armed: bool,
    /// `flight` is taking_off, flying or landing.
    pub airborne: bool,
    /// The active motion behavior.
    pub behavior: Option<String>,
    pub battery_fraction: Option<f64>,
    pub setpoint: Option<SetpointSample>,
    /// Where the drone really was (`x`, `y`, `z` in m, `yaw` in rad) when the record says so
    /// (a simulated drone whose estimate drifts); the fields above are its belief.
    pub truth: Option<[f64; 4]>,
    /// `flight` is crashed: the simulator ended the flight at a contact.
    pub crashed: bool,
}

/// One behavior's activation: a bar of the timeline.
#[derive(Debug, Clone, PartialEq)]
pub struct Activation {
    pub behavior: String,
    pub id: Option<u64>,
    pub start_s: f64,
    pub end_s: f64,
    /// `finished` was logged (false: still active when the log ends).
    pub finished: bool,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct DroneLog {
    pub poses: Vec<Pose>,
    pub activations: Vec<Activation>,
}

#[derive(Debug, Clone, Default, PartialEq)]
pub struct Flight {
    /// The `header` record, if the log has one.
    pub header: Option<Value>,
    pub drones: BTreeMap<String, DroneLog>,
    /// Lines skipped as malformed, and the first few of their numbers.
    pub skipped_lines: usize,
    pub skipped_examples: Vec<usize>,
    /// Last `t` of any record (s).
    pub end_s: f64,
}

impl Flight {
    /// The header's `command` (sim / run / explore).
    pub fn command(&self) -> Option<&str> {
        self.header.as_ref()?.get("command")?.as_str()
    }

    /// The header's `world` path.
    pub fn world(&self) -> Option<&str> {
        self.header.as_ref()?.get("world")?.as_str()
    }

    pub fn pose_count(&self) -> usize {
        self.drones.values().map(|d| d.poses.len()).sum()
    }
}

/// Reads a whole log; see the module doc for what is skipped and what is an error.
pub fn read(reader: impl BufRead) -> Result<Flight, ReportError> {
    let mut flight = Flight::default();
    let mut open: BTreeMap<(String, u64), usize> = BTreeMap::new();
    let mut reader = reader;
    let mut buf = Vec::new();
    let mut line_no = 0usize;
    let mut poses = 0usize;
    loop {
        buf.clear();
        let n = (&mut reader)
            .take(MAX_LINE_BYTES as u64 + 1)
            .read_until(b'\n', &mut buf)
            .map_err(|e| ReportError::Io(format!("reading line {}: {e}", line_no + 1)))?;
        if n == 0 {
            break;
        }
        line_no += 1;
        if buf.len() > MAX_LINE_BYTES {
            return Err(ReportError::LineTooLong {
                line: line_no,
                max_bytes: MAX_LINE_BYTES,
            });
        }
        if buf.iter().all(u8::is_ascii_whitespace) {
            continue;
        }
        let record = serde_json::from_slice::<Value>(&buf).ok();
        match record.and_then(|r| take(&mut flight, &mut open, r)) {
            Some(Taken::Pose) => {
                poses += 1;
                if poses > MAX_POSES {
                    return Err(ReportError::TooManyPoses {
                        line: line_no,
                        max: MAX_POSES,
                    });
                }
            }
            Some(Taken::Other) => {}
            None => {
                flight.skipped_lines += 1;
                if flight.skipped_examples.len() < LISTED_SKIPS {
                    flight.skipped_examples.push(line_no);
                }
            }
        }
    }
    let end_s = flight.end_s;
    for drone in flight.drones.values_mut() {
        let last = drone.poses.last().map_or(end_s, |p| p.t_s);
        for a in drone.activations.iter_mut().filter(|a| !a.finished) {
            a.end_s = a.end_s.max(last);
        }
    }
    Ok(flight)
}

enum Taken {
    Pose,
    Other,
}

/// Files one record; `None` when it is malformed.
fn take(flight: &mut Flight, open: &mut BTreeMap<(String, u64), usize>, r: Value) -> Option<Taken> {
    let kind = r.get("type")?.as_str()?;
    let t_s = r.get("t").and_then(Value::as_f64).filter(|t| t.is_finite());
    if let Some(t) = t_s {
        flight.end_s = flight.end_s.max(t);
    }
    if kind == "header" {
        flight.header = Some(r);
        return Some(Taken::Other);
    }
    let drone = r.get("drone").and_then(Value::as_str).map(str::to_string);
    match kind {
        "pose" => {
            let pose = pose(&r, t_s?)?;
            flight.drones.entry(drone?).or_default().poses.push(pose);
            Some(Taken::Pose)
        }
        "behavior" => {
            let (drone, t) = (drone?, t_s?);
            let behavior = r.get("behavior")?.as_str()?.to_string();
            let id = r.get("id").and_then(Value::as_u64);
            let log = flight.drones.entry(drone.clone()).or_default();
            match r.get("event")?.as_str()? {
                "started" => {
                    if let Some(id) = id {
                        open.insert((drone, id), log.activations.len());
                    }
                    log.activations.push(Activation {
                        behavior,
                        id,
                        start_s: t,
                        end_s: t,
                        finished: false,
                    });
                }
                "finished" => {
                    let index = id.and_then(|id| open.remove(&(drone, id)));
                    if let Some(a) = index.and_then(|i| log.activations.get_mut(i)) {
                        a.end_s = t;
                        a.finished = true;
                    }
                }
                _ => {}
            }
            Some(Taken::Other)
        }
        _ => Some(Taken::Other),
    }
}

fn pose(r: &Value, t_s: f64) -> Option<Pose> {
    let num = |k: &str| r.get(k).and_then(Value::as_f64).filter(|v| v.is_finite());
    let or_zero = |k: &str| num(k).unwrap_or(0.0);
    let flight = r.get("flight").and_then(Value::as_str).unwrap_or("");
    Some(Pose {
        t_s,
        x_m: num("x")?,
        y_m: num("y")?,
        z_m: num("z")?,
        yaw_rad: or_zero("yaw"),
        vx_mps: or_zero("vx"),
        vy_mps: or_zero("vy"),
        vz_mps: or_zero("vz"),
        armed: r.get("armed").and_then(Value::as_bool).unwrap_or(false),
        airborne: matches!(flight, "taking_off" | "flying" | "landing"),
        crashed: flight == "crashed",
        behavior: r
            .get("behavior")
            .and_then(Value::as_str)
            .map(str::to_string),
        battery_fraction: num("battery_fraction"),
        setpoint: r.get("setpoint").and_then(setpoint),
        truth: r.get("truth").and_then(|q| {
            let num = |k: &str| q.get(k).and_then(Value::as_f64).filter(|v| v.is_finite());
            Some([num("x")?, num("y")?, num("z")?, num("yaw")?])
        }),
    })
}

fn setpoint(s: &Value) -> Option<SetpointSample> {
    let vec3 = |k: &str| -> Option<[f64; 3]> {
        let a = s.get(k)?.as_array()?;
        let v = |i: usize| a.get(i)?.as_f64().filter(|v| v.is_finite());
        Some([v(0)?, v(1)?, v(2)?])
    };
    match s.get("kind")?.as_str()? {
        "position" => vec3("position_enu_m").map(SetpointSample::Position),
        "velocity" => vec3("velocity_enu_mps").map(SetpointSample::Velocity),
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    #[test]
    fn bars_close_on_finished_and_malformed_lines_are_counted() {
        let log = concat!(
            r#"{"t":0,"drone":null,"type":"header","command":"sim"}"#,
            "\n",
            r#"{"t":1,"drone":"a","type":"behavior","event":"started","id":1,"behavior":"takeoff"}"#,
            "\nnot json\n",
            r#"{"t":1.5,"drone":"a","type":"pose","x":0,"y":0,"z":1,"flight":"flying","setpoint":{"kind":"position","position_enu_m":[0,0,2]}}"#,
            "\n",
            r#"{"t":2,"drone":"a","type":"behavior","event":"finished","id":1,"behavior":"takeoff"}"#,
            "\n",
            r#"{"t":2.5,"drone":"a","type":"behavior","event":"started","id":2,"behavior":"go_to"}"#,
            "\n",
            r#"{"t":3,"drone":"a","type":"pose","x":1,"y":0}"#,
            "\n",
            r#"{"t":4,"drone":"a","type":"pose","x":1,"y":0,"z":1}"#,
        );
        let f = read(log.as_bytes()).unwrap();
        assert_eq!(f.command(), Some("sim"));
        assert_eq!(
            (f.skipped_lines, f.skipped_examples.clone()),
            (2, vec![3, 7])
        );
        let a = &f.drones["a"];
        assert_eq!(a.poses.len(), 2);
        assert!(a.poses[0].airborne);
        assert_eq!(
            a.poses[0].setpoint,
            Some(SetpointSample::Position([0.0, 0.0, 2.0]))
        );
        let bars: Vec<_> = a
            .activations
            .iter()
            .map(|b| (b.behavior.as_str(), b.start_s, b.end_s, b.finished))
            .collect();
        assert_eq!(
            bars,
            vec![("takeoff", 1.0, 2.0, true), ("go_to", 2.5, 4.0, false)]
        );
    }

    #[test]
    fn an_overlong_line_is_an_error_naming_it() {
        let log = format!("\n{}\n", "x".repeat(MAX_LINE_BYTES + 5));
        let e = read(log.as_bytes()).unwrap_err();
        assert!(e.to_string().contains("line 2"), "{e}");
    }
}
