//! The per-drone numbers of a report.
//!
//! In: one drone's [`DroneLog`]. Out: [`DroneStats`]: distance flown (3-D, summed between
//! consecutive pose records), flight time (the time after pose records whose `flight` is
//! taking_off / flying / landing), time per behavior (the timeline's bars summed), battery used
//! (first minus last known `battery_fraction`) and tracking errors: position error = |setpoint
//! position - logged position| over the records with a position setpoint; velocity error =
//! |setpoint velocity - logged velocity| over the airborne records with a velocity setpoint
//! (the velocity the controller asked for in that tick against the one the vehicle had then,
//! so it includes the vehicle's response lag).

use super::read::{DroneLog, SetpointSample};
use std::collections::BTreeMap;

/// Mean and largest of an error (m or m/s), over `samples` records.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorStats {
    pub mean: f64,
    pub max: f64,
    pub samples: usize,
}

#[derive(Debug, Clone, PartialEq)]
pub struct DroneStats {
    pub distance_m: f64,
    pub flight_time_s: f64,
    pub behavior_time_s: BTreeMap<String, f64>,
    /// First minus last known battery fraction (0..1).
    pub battery_used_fraction: Option<f64>,
    pub position_error_m: Option<ErrorStats>,
    pub velocity_error_mps: Option<ErrorStats>,
}

pub fn stats(log: &DroneLog) -> DroneStats {
    let mut distance_m = 0.0;
    let mut flight_time_s = 0.0;
    for pair in log.poses.windows(2) {
        if let [a, b] = pair {
            let d = [b.x_m - a.x_m, b.y_m - a.y_m, b.z_m - a.z_m];
            distance_m += d.iter().map(|v| v * v).sum::<f64>().sqrt();
            if a.airborne {
                flight_time_s += (b.t_s - a.t_s).max(0.0);
            }
        }
    }
    let mut behavior_time_s = BTreeMap::new();
    for a in &log.activations {
        *behavior_time_s.entry(a.behavior.clone()).or_insert(0.0) += a.end_s - a.start_s;
    }
    let first = log.poses.iter().find_map(|p| p.battery_fraction);
    let last = log.poses.iter().rev().find_map(|p| p.battery_fraction);
    let battery_used_fraction = first.zip(last).map(|(a, b)| a - b);
    let mut position = Vec::new();
    let mut velocity = Vec::new();
    for p in &log.poses {
        match p.setpoint {
            Some(SetpointSample::Position(s)) => {
                position.push(norm([s[0] - p.x_m, s[1] - p.y_m, s[2] - p.z_m]));
            }
            Some(SetpointSample::Velocity(s)) if p.airborne => {
                velocity.push(norm([s[0] - p.vx_mps, s[1] - p.vy_mps, s[2] - p.vz_mps]));
            }
            _ => {}
        }
    }
    DroneStats {
        distance_m,
        flight_time_s,
        behavior_time_s,
        battery_used_fraction,
        position_error_m: error_stats(&position),
        velocity_error_mps: error_stats(&velocity),
    }
}

fn norm(v: [f64; 3]) -> f64 {
    v.iter().map(|c| c * c).sum::<f64>().sqrt()
}

fn error_stats(errors: &[f64]) -> Option<ErrorStats> {
    if errors.is_empty() {
        return None;
    }
    Some(ErrorStats {
        mean: errors.iter().sum::<f64>() / errors.len() as f64,
        max: errors.iter().copied().fold(0.0, f64::max),
        samples: errors.len(),
    })
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::super::read::read;
    use super::*;

    #[test]
    fn distance_time_battery_and_errors() {
        let log = [
            r#"{"t":0,"drone":"a","type":"pose","x":0,"y":0,"z":0,"flight":"flying","battery_fraction":0.9,"setpoint":{"kind":"position","position_enu_m":[0,0,1]}}"#,
            r#"{"t":1,"drone":"a","type":"pose","x":3,"y":4,"z":0,"flight":"flying","vx":1,"setpoint":{"kind":"velocity","velocity_enu_mps":[1,2,0]}}"#,
            r#"{"t":3,"drone":"a","type":"pose","x":3,"y":4,"z":0,"flight":"landed","battery_fraction":0.7}"#,
        ]
        .join("\n");
        let f = read(log.as_bytes()).unwrap();
        let s = stats(&f.drones["a"]);
        assert!((s.distance_m - 5.0).abs() < 1e-9);
        assert!((s.flight_time_s - 3.0).abs() < 1e-9);
        assert!((s.battery_used_fraction.unwrap() - 0.2).abs() < 1e-9);
        assert_eq!(s.position_error_m.unwrap().max, 1.0);
        assert_eq!(s.velocity_error_mps.unwrap().mean, 2.0);
    }
}
