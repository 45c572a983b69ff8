//! Exploration of a walled room on `kestrel run` (tests/run_explore.rs, tests/run_fleet.rs): waiting
//! for the exploration to end over the API, and judging the served map and the true tracks
//! against the room.

use super::{Api, Fake, Kestrel};
use kestrel::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD;
use kestrel::sim::world::{Shape, World};
use kestrel::types::Vec3;
use serde_json::Value;
use std::time::{Duration, Instant};

/// The rooms' outer walls are this thick, inside the world's bounds (m).
pub const WALL_M: f64 = 0.2;
/// The whole exploration, take-off to disarm (wall clock; about 35-70 s here).
pub const EXPLORATION_TIMEOUT: Duration = Duration::from_secs(150);

/// Horizontal distance from `p` to the nearest obstacle surface (m).
pub fn clearance_m(shapes: &[Shape], p: Vec3) -> f64 {
    shapes
        .iter()
        .filter_map(|s| s.distance_m(&p))
        .fold(f64::INFINITY, f64::min)
}

/// Polls `GET /api/exploration` until the run has finished; returns the last answer.
pub fn wait_explored(api: &Api, kestrel: &Kestrel, fake: &Fake) -> Value {
    let deadline = Instant::now() + EXPLORATION_TIMEOUT;
    loop {
        let view = api.get("/api/exploration");
        if view["progress"]["finished"] == true {
            return view;
        }
        assert!(
            Instant::now() < deadline,
            "not explored within {EXPLORATION_TIMEOUT:?}: {view}\n{}\n{}",
            fake.diagnostics(),
            kestrel.output()
        );
        std::thread::sleep(Duration::from_millis(500));
    }
}

/// Known share (%) of the room's floor (inside its outer walls, outside every obstacle), and the obstacle cells of the map
/// farther than `tolerance_m` from every true obstacle.
pub fn judge_map(map: &Value, w: &World, tolerance_m: f64) -> (f64, Vec<[f64; 2]>) {
    let spec = &map["spec"];
    let res = spec["resolution_m"].as_f64().unwrap();
    let width = spec["width_cells"].as_u64().unwrap() as usize;
    let origin = [
        spec["origin_enu_m"][0].as_f64().unwrap(),
        spec["origin_enu_m"][1].as_f64().unwrap(),
    ];
    let threshold = i64::from(DEFAULT_OCCUPIED_THRESHOLD);
    let shapes = w.shapes();
    let (mut floor, mut known) = (0usize, 0usize);
    let mut stray = Vec::new();
    for (k, v) in map["data"].as_array().unwrap().iter().enumerate() {
        let v = v.as_i64().unwrap();
        let x = origin[0] + ((k % width) as f64 + 0.5) * res;
        let y = origin[1] + ((k / width) as f64 + 0.5) * res;
        let d = clearance_m(&shapes, Vec3::new(x, y, 1.0));
        let inside = x > w.bounds_m.x[0] + WALL_M
            && x < w.bounds_m.x[1] - WALL_M
            && y > w.bounds_m.y[0] + WALL_M
            && y < w.bounds_m.y[1] - WALL_M;
        if inside && d > 0.0 {
            floor += 1;
            known += usize::from(v >= 0);
        }
        if v >= threshold && d > tolerance_m {
            stray.push([x, y]);
        }
    }
    (100.0 * known as f64 / floor.max(1) as f64, stray)
}
