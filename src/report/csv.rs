//! The report's CSV exports.
//!
//! In: the read flight, the evaluator's area curve. Out: `poses.csv` (one row per pose record,
//! in drone then time order: t, drone, x, y, z, yaw, vx, vy, vz, behavior, battery_fraction; SI
//! units, ENU; empty cells where the log has null) and `area.csv` (t_s, area_pct).

use super::read::Flight;
use crate::exploration::offline::evaluate::CurvePoint;
use std::fmt::Write;

/// A text cell, quoted when it holds a comma, quote or line break.
pub(super) fn cell(s: &str) -> String {
    if s.contains([',', '"', '\n', '\r']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

pub fn poses(flight: &Flight) -> String {
    let mut out = String::from("t,drone,x,y,z,yaw,vx,vy,vz,behavior,battery_fraction\n");
    for (drone, log) in &flight.drones {
        let drone = cell(drone);
        for p in &log.poses {
            let _ = writeln!(
                out,
                "{},{drone},{},{},{},{},{},{},{},{},{}",
                p.t_s,
                p.x_m,
                p.y_m,
                p.z_m,
                p.yaw_rad,
                p.vx_mps,
                p.vy_mps,
                p.vz_mps,
                p.behavior.as_deref().map(cell).unwrap_or_default(),
                p.battery_fraction
                    .map(|b| b.to_string())
                    .unwrap_or_default(),
            );
        }
    }
    out
}

pub fn area(curve: &[CurvePoint]) -> String {
    let mut out = String::from("t_s,area_pct\n");
    for p in curve {
        let _ = writeln!(out, "{},{}", p.t_s, p.area_pct);
    }
    out
}
