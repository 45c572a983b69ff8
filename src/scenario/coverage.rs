//! A scenario's coverage area split among the drones (the thesis's multi-drone solar-park
//! inspection): one boustrophedon piece each, flown as its own mission.
//!
//! In: the scenario's `coverage` section (polygon in one of its frames, street spacing, height,
//! speed, an optional gimbal target), each drone's id and start (ENU `earth`, m), and the frames
//! (to bring the polygon into `earth`). Out: one mission per drone: takeoff, point the gimbal,
//! sweep its piece, fly back above its start, land there.

use crate::estimator::frames::FrameTree;
use crate::host::coverage::{plan, CoverageError};
use crate::types::Vec3;
use nalgebra::Vector2;
use serde::Deserialize;
use serde_json::{json, Value};
use std::sync::atomic::AtomicBool;
use std::time::Duration;

/// Most polygon vertices a scenario may give.
const MAX_VERTICES: usize = 1000;

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CoverageSpec {
    /// Frame of the polygon and the gimbal target (registered by the scenario, or `earth`).
    #[serde(default = "earth")]
    pub frame_id: String,
    /// Polygon vertices [x, y] in `frame_id` (m).
    pub polygon_m: Vec<[f64; 2]>,
    /// Distance between sweep lines (m).
    pub street_spacing_m: f64,
    /// Sweep direction in `earth` (deg, CCW from east); absent = across the narrowest direction.
    #[serde(default)]
    pub angle_deg: Option<f64>,
    /// Flight height (m above the `earth` origin).
    pub height_m: f64,
    /// Sweep speed (m/s).
    #[serde(default = "default_speed")]
    pub speed_m_s: f64,
    /// What the gimbal follows during the sweep, in `frame_id` (m).
    #[serde(default)]
    pub gimbal_target_m: Option<[f64; 3]>,
}

fn earth() -> String {
    "earth".into()
}

fn default_speed() -> f64 {
    2.0
}

#[derive(Debug, thiserror::Error)]
pub enum SplitError {
    #[error("coverage/polygon_m: {0}")]
    Polygon(String),
    #[error("coverage/{field}: {message}")]
    Value {
        field: &'static str,
        message: String,
    },
    #[error("coverage: {0}")]
    Plan(#[from] CoverageError),
}

/// One mission per drone (in the order of `drones`), each sweeping its piece of the area.
pub fn fleet_missions(
    spec: &CoverageSpec,
    frames: &FrameTree,
    drones: &[(String, Vec3)],
) -> Result<Vec<Value>, SplitError> {
    check(spec)?;
    let polygon = spec
        .polygon_m
        .iter()
        .map(|[x, y]| {
            frames
                .point_to_earth(&Vec3::new(*x, *y, 0.0), &spec.frame_id, Duration::ZERO)
                .map(|p| Vector2::new(p.x, p.y))
                .map_err(|e| SplitError::Polygon(format!("frame `{}`: {e}", spec.frame_id)))
        })
        .collect::<Result<Vec<_>, _>>()?;
    let starts: Vec<Vector2<f64>> = drones.iter().map(|(_, p)| Vector2::new(p.x, p.y)).collect();
    let sweep = plan(
        &polygon,
        spec.street_spacing_m,
        spec.angle_deg.map(f64::to_radians),
        &starts,
        spec.height_m,
        &AtomicBool::new(false),
    )?;
    Ok(drones
        .iter()
        .zip(&sweep.pieces)
        .map(|((id, start), piece)| mission(spec, id, start, piece))
        .collect())
}

fn check(spec: &CoverageSpec) -> Result<(), SplitError> {
    if spec.polygon_m.len() < 3 || spec.polygon_m.len() > MAX_VERTICES {
        return Err(SplitError::Polygon(format!(
            "3 to {MAX_VERTICES} vertices, got {}",
            spec.polygon_m.len()
        )));
    }
    let positive = |field: &'static str, v: f64, unit: &str| {
        if v.is_finite() && v > 0.0 {
            Ok(())
        } else {
            Err(SplitError::Value {
                field,
                message: format!("must be a positive number of {unit}, got {v}"),
            })
        }
    };
    positive("street_spacing_m", spec.street_spacing_m, "metres")?;
    positive("height_m", spec.height_m, "metres")?;
    positive("speed_m_s", spec.speed_m_s, "m/s")
}

fn mission(spec: &CoverageSpec, drone: &str, start: &Vec3, piece: &[Vec3]) -> Value {
    let h = spec.height_m;
    let mut plan = vec![json!({"behavior": "takeoff", "args": {"height": h, "speed": 1.0}})];
    if let Some([x, y, z]) = spec.gimbal_target_m {
        plan.push(json!({"behavior": "point_gimbal", "args": {
            "x": x, "y": y, "z": z, "frame_id": spec.frame_id, "follow": true, "wait": false}}));
    }
    let path: Vec<[f64; 3]> = piece.iter().map(|p| [p.x, p.y, h]).collect();
    if !path.is_empty() {
        plan.push(json!({"behavior": "follow_path", "args": {
            "path": path, "speed": spec.speed_m_s, "yaw_mode": "path_facing", "frame_id": "earth"}}));
    }
    plan.push(json!({"behavior": "go_to", "args": {
        "x": start.x, "y": start.y, "z": h, "speed": spec.speed_m_s, "frame_id": "earth"}}));
    plan.push(json!({"behavior": "land", "args": {}}));
    json!({"target": drone, "plan": plan})
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn spec() -> CoverageSpec {
        serde_json::from_value(json!({
            "polygon_m": [[0, 0], [30, 0], [30, 20], [0, 20]],
            "street_spacing_m": 5.0, "height_m": 8.0,
            "gimbal_target_m": [15, 10, 0]
        }))
        .unwrap()
    }

    #[test]
    fn each_drone_sweeps_a_piece_and_lands_at_its_start() {
        let drones: Vec<(String, Vec3)> = (0..3)
            .map(|i| (format!("drone_{i}"), Vec3::new(-2.0, 2.0 * i as f64, 0.0)))
            .collect();
        let missions = fleet_missions(&spec(), &FrameTree::new(), &drones).unwrap();
        assert_eq!(missions.len(), 3);
        let mut points = 0;
        for (m, (id, start)) in missions.iter().zip(&drones) {
            assert_eq!(m["target"], id.as_str());
            let names: Vec<&str> = m["plan"]
                .as_array()
                .unwrap()
                .iter()
                .map(|i| i["behavior"].as_str().unwrap())
                .collect();
            assert_eq!(
                names,
                ["takeoff", "point_gimbal", "follow_path", "go_to", "land"]
            );
            let path = m["plan"][2]["args"]["path"].as_array().unwrap();
            assert!(path.len() >= 2, "{m}");
            points += path.len();
            for p in path {
                let (x, y) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
                assert!((-0.01..=30.01).contains(&x) && (-0.01..=20.01).contains(&y));
                assert_eq!(p[2], 8.0);
            }
            assert_eq!(m["plan"][3]["args"]["x"], start.x);
            assert_eq!(m["plan"][3]["args"]["y"], start.y);
        }
        assert!(
            points >= 3 * 2 + 4,
            "the sweep has 5 streets: {points} points"
        );
    }

    #[test]
    fn bad_values_say_which_field() {
        let mut s = spec();
        s.street_spacing_m = 0.0;
        let e = fleet_missions(&s, &FrameTree::new(), &[("d".into(), Vec3::zeros())]);
        assert!(e
            .unwrap_err()
            .to_string()
            .contains("coverage/street_spacing_m"));
        let mut s = spec();
        s.frame_id = "nowhere".into();
        let e = fleet_missions(&s, &FrameTree::new(), &[("d".into(), Vec3::zeros())]);
        assert!(e.unwrap_err().to_string().contains("nowhere"));
    }
}
