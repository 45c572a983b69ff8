//! Exploration of a walled room on `kestrel run` (tests/run_explore.rs, tests/run_fleet.rs): waiting
//! for the exploration to end over the API, and judging the served map and the true tracks
//! against the room.

use super::{Api, Fake, Kestrel};
use kestrel::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD;
use kestrel::sim::world::{Shape, World};
use kestrel::types::Vec3;
use serde_json::{json, Value};
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

/// Least distance between two drones the tests accept (m, centre to centre, 3-D).
pub const MIN_SEPARATION_M: f64 = 0.5;

/// The least clearance to an obstacle of an airborne drone: how much, which, when and where.
pub struct Clearance {
    pub m: f64,
    pub drone: usize,
    pub sample: usize,
    pub at: Vec3,
}

/// What the true tracks show: the least distance between two drones (and at which sample), the
/// least clearance to an obstacle of an airborne drone, and the airborne samples per drone.
pub struct Tracks {
    pub closest_pair: (f64, usize),
    pub clearance: Clearance,
    pub airborne: Vec<usize>,
}

/// A fake state's `position_enu_m`.
pub fn position(state: &Value) -> Vec3 {
    let p = &state["position_enu_m"];
    Vec3::new(
        p[0].as_f64().unwrap(),
        p[1].as_f64().unwrap(),
        p[2].as_f64().unwrap(),
    )
}

/// Judges the fake's true states (`Fake::poll_fleet_states` samples) against the world.
pub fn judge_tracks(samples: &[Value], w: &World) -> Tracks {
    let shapes = w.shapes();
    let mut t = Tracks {
        closest_pair: (f64::INFINITY, 0),
        clearance: Clearance {
            m: f64::INFINITY,
            drone: 0,
            sample: 0,
            at: Vec3::zeros(),
        },
        airborne: Vec::new(),
    };
    for (k, sample) in samples.iter().enumerate() {
        let at: Vec<Vec3> = sample.as_array().unwrap().iter().map(position).collect();
        t.airborne.resize(t.airborne.len().max(at.len()), 0);
        for (i, p) in at.iter().enumerate() {
            if p.z > 0.3 {
                t.airborne[i] += 1;
                let c = clearance_m(&shapes, *p);
                if c < t.clearance.m {
                    t.clearance = Clearance {
                        m: c,
                        drone: i,
                        sample: k,
                        at: *p,
                    };
                }
            }
            for q in &at[i + 1..] {
                let d = (p - q).norm();
                if d < t.closest_pair.0 {
                    t.closest_pair = (d, k);
                }
            }
        }
    }
    t
}

impl Tracks {
    /// No airborne drone within `min_clearance_m` of an obstacle and no two drones closer than
    /// `min_separation_m`; panics saying where otherwise.
    pub fn assert_safe(&self, samples: &[Value], min_clearance_m: f64, min_separation_m: f64) {
        let c = &self.clearance;
        assert!(
            c.m > min_clearance_m,
            "drone_{} {:.2} m from an obstacle at {:?}, sample {} of {}",
            c.drone,
            c.m,
            c.at,
            c.sample,
            samples.len()
        );
        let (d, k) = self.closest_pair;
        assert!(
            d >= min_separation_m,
            "two drones {d:.2} m apart at sample {k} of {}: {}",
            samples.len(),
            samples[k]
        );
    }
}

/// No collision in the fake's log of any of its first `vehicles`.
pub fn assert_no_collision(fake: &Fake, vehicles: usize) {
    for i in 0..vehicles {
        let log = fake.cmd(json!({"cmd": "log", "vehicle": i}));
        let collisions: Vec<&Value> = log["entries"]
            .as_array()
            .unwrap()
            .iter()
            .filter(|e| e["kind"] == "collision")
            .collect();
        assert!(collisions.is_empty(), "vehicle {i}: {collisions:?}");
    }
}
