//! The built-in demo flight, as a mission per drone: take off, go to a point, follow a short
//! path, land, placed from each drone's start pose clear of obstacles and of the others.
//!
//! In: the simulator's world (start poses, obstacles) or one start pose. Out: mission JSON
//! (Aerostack2's format) that the host validates and flies like any other.

use crate::sim::world::Shape;
use crate::sim::SimWorld;
use crate::types::{Vec2, Vec3};
use serde_json::{json, Value};

/// One step of a plan: behavior name and goal arguments.
pub type PlanItem = (String, Value);

/// Demo waypoints in the drone's start frame (x forward, y left, z up; m): a go_to, then a
/// three-point path. Takeoff and landing are vertical.
const DEMO_GO_TO: [f64; 3] = [0.0, 5.0, 3.0];
const DEMO_PATH: [[f64; 3]; 3] = [[3.0, 5.0, 3.5], [3.0, 8.0, 3.5], [0.0, 8.0, 3.0]];
/// Headings tried (multiples of 45 deg from the start heading) and shrink factors, in order.
const TURNS: usize = 8;
const SCALES: [f64; 3] = [1.0, 0.6, 0.3];
/// Clearance kept from obstacle surfaces and from other drones' demo tracks (m).
const OBSTACLE_MARGIN_M: f64 = 0.8;
const DRONE_SEPARATION_M: f64 = 1.5;

/// The demo from a start pose: take off to 3 m, go to 5 m left of the start, follow a short
/// path, land. Waypoints are in `earth`, relative to the start position and heading.
pub fn demo_plan(start_m: Vec3, yaw_rad: f64) -> Vec<PlanItem> {
    plan_from(&demo_track(start_m, yaw_rad, 1.0))
}

/// One demo per vehicle of `world`, each placed (turned about its start, or shrunk) to keep
/// clear of obstacles and of the demos of the drones before it. A drone with no clear
/// placement takes off, hovers and lands where it stands.
pub fn demo_plans(world: &SimWorld) -> Vec<Vec<PlanItem>> {
    let mut taken: Vec<Vec<Vec3>> = Vec::new();
    let mut plans = Vec::new();
    for v in &world.vehicles {
        let start = v.state.position_m;
        let reach_m = demo_reach_m() + v.params.radius_m + OBSTACLE_MARGIN_M;
        let nearby: Vec<Shape> = world
            .shapes()
            .iter()
            .filter(|s| {
                s.distance_m(&Vec3::new(start.x, start.y, 0.0))
                    .is_none_or(|d| d < reach_m)
            })
            .copied()
            .collect();
        let clear = |points: &[Vec3]| {
            keeps_clear(points, &nearby, v.params.radius_m + OBSTACLE_MARGIN_M)
                && taken
                    .iter()
                    .all(|other| tracks_apart(points, other, DRONE_SEPARATION_M))
        };
        let chosen = SCALES
            .iter()
            .flat_map(|&scale| {
                (0..TURNS).map(move |k| {
                    let turn = std::f64::consts::TAU * k as f64 / TURNS as f64;
                    demo_track(start, v.state.yaw_rad + turn, scale)
                })
            })
            .map(|track| {
                let points = samples(&track);
                (track, points)
            })
            .find(|(_, points)| clear(points));
        match chosen {
            Some((track, points)) => {
                plans.push(plan_from(&track));
                taken.push(points);
            }
            None => {
                plans.push(hover_plan());
                taken.push(samples(&[start, start + Vec3::new(0.0, 0.0, 3.0)]));
            }
        }
    }
    plans
}

/// How far the demo goes from its start, horizontally (m).
fn demo_reach_m() -> f64 {
    std::iter::once(DEMO_GO_TO)
        .chain(DEMO_PATH)
        .map(|[x, y, _]| x.hypot(y))
        .fold(0.0, f64::max)
}

/// The demo's polyline in `earth`: start, above the start, the go_to point, the path.
fn demo_track(start_m: Vec3, yaw_rad: f64, scale: f64) -> Vec<Vec3> {
    let (s, c) = yaw_rad.sin_cos();
    let place = |[x, y, z]: [f64; 3]| {
        let (x, y) = (x * scale, y * scale);
        Vec3::new(
            start_m.x + c * x - s * y,
            start_m.y + s * x + c * y,
            start_m.z + z,
        )
    };
    let mut track = vec![
        start_m,
        start_m + Vec3::new(0.0, 0.0, 3.0),
        place(DEMO_GO_TO),
    ];
    track.extend(DEMO_PATH.iter().map(|&p| place(p)));
    track
}

/// The plan flying a track from [`demo_track`].
fn plan_from(track: &[Vec3]) -> Vec<PlanItem> {
    let xyz = |p: &Vec3| [p.x, p.y, p.z];
    let go_to = track.get(2).map(xyz).unwrap_or_default();
    let path: Vec<[f64; 3]> = track.iter().skip(3).map(xyz).collect();
    vec![
        ("takeoff".into(), json!({ "height": 3.0, "speed": 1.0 })),
        (
            "go_to".into(),
            json!({ "x": go_to[0], "y": go_to[1], "z": go_to[2], "speed": 1.5 }),
        ),
        (
            "follow_path".into(),
            json!({ "path": path, "speed": 1.0, "yaw_mode": "path_facing" }),
        ),
        ("land".into(), json!({ "speed": 0.5 })),
    ]
}

fn hover_plan() -> Vec<PlanItem> {
    vec![
        ("takeoff".into(), json!({ "height": 3.0, "speed": 1.0 })),
        ("hover".into(), json!({ "duration": 5.0 })),
        ("land".into(), json!({ "speed": 0.5 })),
    ]
}

/// Spacing of the points checked along a track (m).
const SAMPLE_SPACING_M: f64 = 0.2;

/// A polyline as points at most [`SAMPLE_SPACING_M`] apart.
fn samples(track: &[Vec3]) -> Vec<Vec3> {
    let mut out: Vec<Vec3> = track.first().copied().into_iter().collect();
    for pair in track.windows(2) {
        let (a, b) = (pair[0], pair[1]);
        let n = ((b - a).norm() / SAMPLE_SPACING_M).ceil().max(1.0) as usize;
        out.extend((1..=n).map(|i| a + (b - a) * (i as f64 / n as f64)));
    }
    out
}

/// True when every point stays `margin_m` from the surface of every shape beside it.
fn keeps_clear(points: &[Vec3], shapes: &[Shape], margin_m: f64) -> bool {
    points.iter().all(|p| {
        shapes
            .iter()
            .all(|s| s.distance_m(p).is_none_or(|d| d >= margin_m))
    })
}

/// True when two sampled polylines stay `separation_m` apart horizontally.
fn tracks_apart(a: &[Vec3], b: &[Vec3], separation_m: f64) -> bool {
    let flat = |p: &Vec3| Vec2::new(p.x, p.y);
    a.iter()
        .all(|p| b.iter().all(|q| (flat(p) - flat(q)).norm() >= separation_m))
}

/// A plan as the mission of `drone`.
pub fn as_mission(drone: &str, plan: Vec<PlanItem>) -> Value {
    let plan: Vec<Value> = plan
        .into_iter()
        .map(|(behavior, args)| json!({"behavior": behavior, "args": args}))
        .collect();
    json!({"target": drone, "plan": plan})
}

/// The demo mission of every vehicle of `world` (`drone_0` ...), see [`demo_plans`].
pub fn demo_missions(world: &SimWorld) -> Vec<Value> {
    demo_plans(world)
        .into_iter()
        .enumerate()
        .map(|(i, plan)| as_mission(&format!("drone_{i}"), plan))
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::sim::world::{Cylinder, World};
    use crate::sim::Environment;

    fn go_to_xy(plan: &[PlanItem]) -> (f64, f64) {
        let goal = &plan[1].1;
        (goal["x"].as_f64().unwrap(), goal["y"].as_f64().unwrap())
    }

    #[test]
    fn demo_is_relative_to_the_start_pose() {
        let plan = demo_plan(Vec3::new(10.0, -2.0, 0.0), std::f64::consts::FRAC_PI_2);
        // 5 m to the left of a drone facing north is 5 m west.
        let (x, y) = go_to_xy(&plan);
        assert!(
            (x - 5.0).abs() < 1e-9 && (y + 2.0).abs() < 1e-9,
            "({x}, {y})"
        );
        let names: Vec<&str> = plan.iter().map(|(n, _)| n.as_str()).collect();
        assert_eq!(names, ["takeoff", "go_to", "follow_path", "land"]);
    }

    #[test]
    fn demo_turns_away_from_a_pole_in_its_way() {
        let mut world = World::empty();
        world.cylinders.push(Cylinder {
            xy_m: [0.0, 3.0],
            radius_m: 0.3,
            height_m: 10.0,
        });
        let sim = SimWorld::new(world, 1, 0, Environment::default());
        let plans = demo_plans(&sim);
        let (x, y) = go_to_xy(&plans[0]);
        assert!((x.hypot(y) - 5.0).abs() < 1e-9, "the full-size demo");
        assert!(x.abs() > 1.0, "turned away from the pole: ({x}, {y})");
        let mut track = vec![
            Vec3::zeros(),
            Vec3::new(0.0, 0.0, 3.0),
            Vec3::new(x, y, 3.0),
        ];
        for p in plans[0][2].1["path"].as_array().unwrap() {
            let p: Vec<f64> = serde_json::from_value(p.clone()).unwrap();
            track.push(Vec3::new(p[0], p[1], p[2]));
        }
        assert!(keeps_clear(&samples(&track), sim.shapes(), 0.9));
    }

    #[test]
    fn boxed_in_drones_only_hover() {
        let mut world = World::empty();
        for (x, y) in [(1.4, 0.0), (-1.4, 0.0), (0.0, 1.4), (0.0, -1.4)] {
            world.cylinders.push(Cylinder {
                xy_m: [x, y],
                radius_m: 0.3,
                height_m: 10.0,
            });
        }
        let sim = SimWorld::new(world, 1, 0, Environment::default());
        assert_eq!(sim.vehicles[0].state.position_m, Vec3::zeros());
        let names: Vec<String> = demo_plans(&sim)[0].iter().map(|(n, _)| n.clone()).collect();
        assert_eq!(names, ["takeoff", "hover", "land"]);
    }
}
