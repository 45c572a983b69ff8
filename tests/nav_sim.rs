//! `navigate_to` in the simulator: across a seeded 20 m x 20 m world of poles (0.1 poles per
//! square metre) to a goal, with only the four-beam multi-ranger or with a lidar, never closer
//! to a pole than the safety distance, and failing with the planner's reason for a goal inside
//! a pole.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::Harness;
use common::SimConfig;
use kestrel::behavior::{BehaviorResult, FailureCode};
use kestrel::core::BehaviorCommand;
use kestrel::mapping::config::MapSection;
use kestrel::mapping::{GridSpec, OccupancyGrid};
use kestrel::sim::world::World;
use kestrel::types::Vec3;
use nalgebra::Vector2;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use serde_json::{json, Value};
use std::sync::Arc;

const START: [f64; 2] = [-8.0, -8.0];
const GOAL: [f64; 2] = [8.0, 8.0];
const HEIGHT_M: f64 = 1.0;
const SAFETY_M: f64 = 0.3;

/// 40 poles (radius 0.1-0.25 m) placed uniformly in [-10, 10]^2 by `seed`, none within 1.5 m of
/// the start or the goal, as a world file.
fn pole_world(seed: u64, sensor: Value) -> World {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut cylinders = Vec::new();
    while cylinders.len() < 40 {
        let (x, y): (f64, f64) = (rng.gen_range(-10.0..10.0), rng.gen_range(-10.0..10.0));
        let r: f64 = rng.gen_range(0.1..0.25);
        let clear_of = |p: [f64; 2]| (x - p[0]).hypot(y - p[1]) > 1.5 + r;
        if clear_of(START) && clear_of(GOAL) {
            cylinders.push(json!({ "xy_m": [x, y], "radius_m": r, "height_m": 5.0 }));
        }
    }
    let world = json!({
        "name": format!("poles-{seed}"),
        "bounds_m": { "x": [-10.0, 10.0], "y": [-10.0, 10.0] },
        "starts_xy_yaw": { "1": [[START[0], START[1], 0.0]] },
        "cylinders": cylinders,
        "sensor": sensor,
    });
    serde_json::from_value(world).unwrap()
}

/// A harness whose drone maps a 24 m x 24 m grid around the world.
fn harness(world: World) -> Harness {
    let section = MapSection {
        size_m: Some([24.0, 24.0]),
        ..MapSection::default()
    };
    let map = section.config(None).unwrap();
    Harness::with_core_config(world, SimConfig::default(), move |c| {
        c.map.clone_from(&map);
    })
}

/// Smallest distance (m) from any flight-log pose to any pole surface.
fn min_pole_clearance(h: &mut Harness) -> f64 {
    let poles: Vec<(Vec3, f64)> = h
        .world()
        .world
        .cylinders
        .iter()
        .map(|c| (Vec3::new(c.xy_m[0], c.xy_m[1], 0.0), c.radius_m))
        .collect();
    h.log_records()
        .iter()
        .filter(|r| r["type"] == "pose" && r["behavior"] == "navigate_to")
        .map(|r| {
            let p = Vec3::new(r["x"].as_f64().unwrap(), r["y"].as_f64().unwrap(), 0.0);
            poles
                .iter()
                .map(|(c, radius)| (p - c).norm() - radius)
                .fold(f64::INFINITY, f64::min)
        })
        .fold(f64::INFINITY, f64::min)
}

/// Starts navigate_to and runs until it ends; returns the result and the last feedback.
fn navigate(h: &mut Harness, goal: Value, limit_s: f64) -> (BehaviorResult, Value) {
    let id = h.start(0, "navigate_to", goal);
    let mut feedback = Value::Null;
    h.run_until(limit_s, "navigate_to to finish", |h| {
        if let Some(a) = h.host.cores()[0].server().active().first() {
            feedback = a.feedback.clone();
        }
        h.result(0, id).is_some()
    });
    (h.result(0, id).unwrap(), feedback)
}

fn assert_crossed_safely(h: &mut Harness) {
    let records = h.log_records();
    assert!(
        !records.iter().any(|r| r["type"] == "collision"),
        "collision in the flight log"
    );
    let goal = Vec3::new(GOAL[0], GOAL[1], HEIGHT_M);
    let off = (h.position(0) - goal).norm();
    assert!(off < 0.3, "{off:.2} m from the goal");
    let clearance = min_pole_clearance(h);
    assert!(
        clearance >= SAFETY_M,
        "came within {clearance:.3} m of a pole (safety distance {SAFETY_M} m)"
    );
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "navigate_to:started",
            "navigate_to:finished:succeeded",
        ],
    );
}

#[test]
fn with_only_the_four_beam_sensor_it_crosses_the_poles_without_coming_close() {
    // Seeds whose straight line crosses a pole; without spinning, seed 8 ends in a collision.
    for seed in [5, 7, 8] {
        let world = pole_world(seed, json!({ "kind": "multiranger" }));
        assert!(
            straight_line_clearance(&world) < 0.0,
            "seed {seed}: a pole in the way"
        );
        let mut h = harness(world);
        h.take_off(0, HEIGHT_M);
        let (result, feedback) = navigate(
            &mut h,
            json!({ "x": GOAL[0], "y": GOAL[1], "z": HEIGHT_M, "speed": 0.5,
                    "safety_distance": SAFETY_M, "spin_rate": 1.0 }),
            240.0,
        );
        assert_eq!(result, BehaviorResult::Succeeded, "seed {seed}");
        assert!(
            feedback["replans"].as_u64().unwrap() >= 1,
            "seed {seed}: {feedback}"
        );
        assert_crossed_safely(&mut h);
    }
}

#[test]
fn with_a_lidar_and_no_prior_map_it_crosses_the_poles() {
    let world = pole_world(11, json!({ "kind": "lidar360" }));
    assert!(straight_line_clearance(&world) < 0.0, "a pole in the way");
    let mut h = harness(world);
    h.take_off(0, HEIGHT_M);
    let (result, feedback) = navigate(
        &mut h,
        json!({ "x": GOAL[0], "y": GOAL[1], "z": HEIGHT_M, "speed": 1.0,
                "safety_distance": SAFETY_M, "yaw_mode": "path_facing" }),
        120.0,
    );
    assert_eq!(result, BehaviorResult::Succeeded);
    assert_crossed_safely(&mut h);
    let path = feedback["planned_path"].as_array().unwrap();
    assert!(path.len() >= 2, "{feedback}");
    assert!(
        feedback["distance_remaining"].as_f64().unwrap() < 1.0,
        "{feedback}"
    );
    assert!(feedback["estimated_time_remaining_s"].as_f64().is_some());
}

/// The pole nearest to (or farthest from) the start.
fn pole_by_distance(world: &World, nearest: bool) -> [f64; 2] {
    let d = |c: &&kestrel::sim::world::Cylinder| (c.xy_m[0] - START[0]).hypot(c.xy_m[1] - START[1]);
    let pick = if nearest {
        world.cylinders.iter().min_by(|a, b| d(a).total_cmp(&d(b)))
    } else {
        world.cylinders.iter().max_by(|a, b| d(a).total_cmp(&d(b)))
    };
    pick.unwrap().xy_m
}

#[test]
fn a_goal_inside_a_seen_pole_is_refused_with_the_planners_reason() {
    let world = pole_world(7, json!({ "kind": "lidar360" }));
    let pole = pole_by_distance(&world, true);
    assert!(
        (pole[0] - START[0]).hypot(pole[1] - START[1]) < 9.0,
        "within the lidar's 10 m"
    );
    let mut h = harness(world);
    h.take_off(0, HEIGHT_M);
    let err = h
        .try_command(
            0,
            BehaviorCommand::Start {
                behavior: "navigate_to".into(),
                goal: json!({ "x": pole[0], "y": pole[1], "z": HEIGHT_M, "speed": 1.0,
                              "safety_distance": SAFETY_M }),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("goal is occupied"), "{err}");
}

#[test]
fn a_goal_inside_a_pole_seen_on_the_way_fails_with_the_planners_reason() {
    let world = pole_world(7, json!({ "kind": "lidar360" }));
    let pole = pole_by_distance(&world, false);
    assert!(
        (pole[0] - START[0]).hypot(pole[1] - START[1]) > 12.0,
        "beyond the lidar's 10 m"
    );
    let mut h = harness(world);
    h.take_off(0, HEIGHT_M);
    let (result, _) = navigate(
        &mut h,
        json!({ "x": pole[0], "y": pole[1], "z": HEIGHT_M, "speed": 1.0,
                "safety_distance": SAFETY_M }),
        120.0,
    );
    match result {
        BehaviorResult::Failed { code, reason } => {
            assert!(reason.contains("goal is occupied"), "{reason}");
            assert_eq!(code, FailureCode::GoalInObstacle);
        }
        other => panic!("expected a failure, got {other:?}"),
    }
    assert!(min_pole_clearance(&mut h) >= SAFETY_M);
}

/// Smallest distance (m) from the straight start-goal segment to a pole surface (negative:
/// the segment crosses a pole).
fn straight_line_clearance(world: &World) -> f64 {
    let (a, b) = (
        Vec3::new(START[0], START[1], 0.0),
        Vec3::new(GOAL[0], GOAL[1], 0.0),
    );
    world
        .cylinders
        .iter()
        .map(|c| {
            let p = Vec3::new(c.xy_m[0], c.xy_m[1], 0.0);
            let t = ((p - a).dot(&(b - a)) / (b - a).norm_squared()).clamp(0.0, 1.0);
            (a + (b - a) * t - p).norm() - c.radius_m
        })
        .fold(f64::INFINITY, f64::min)
}

/// The world's poles as a known map: cells whose centre lies inside a pole occupied, the rest
/// free.
fn known_map(world: &World, spec: GridSpec) -> OccupancyGrid {
    let mut grid = OccupancyGrid::from_data(spec, vec![0; spec.cell_count()]).unwrap();
    for i in 0..spec.cell_count() {
        let c = spec.cell_of_index(i).unwrap();
        let p = spec.cell_center_enu_m(c);
        let inside = world
            .cylinders
            .iter()
            .any(|k| (p - Vector2::new(k.xy_m[0], k.xy_m[1])).norm() <= k.radius_m);
        if inside {
            grid.set(c, 100).unwrap();
        }
    }
    grid
}

#[test]
fn with_a_known_map_and_no_sensor_it_flies_mapped_free_space_only() {
    let world = pole_world(8, json!({ "kind": "none" }));
    assert!(straight_line_clearance(&world) < 0.0, "a pole in the way");
    let section = MapSection {
        size_m: Some([24.0, 24.0]),
        ..MapSection::default()
    };
    let mut map = section.config(None).unwrap().unwrap();
    map.initial = Arc::new(known_map(&world, *map.initial.spec()));
    let mut h = Harness::with_core_config(world, SimConfig::default(), move |c| {
        c.map = Some(map.clone());
    });
    h.take_off(0, HEIGHT_M);
    let (result, feedback) = navigate(
        &mut h,
        json!({ "x": GOAL[0], "y": GOAL[1], "z": HEIGHT_M, "speed": 1.0,
                "safety_distance": SAFETY_M, "unknown": "blocked", "planner": "voronoi" }),
        120.0,
    );
    assert_eq!(result, BehaviorResult::Succeeded);
    assert_eq!(feedback["replans"], 0, "nothing new to see: {feedback}");
    assert_crossed_safely(&mut h);
}

#[test]
fn without_a_map_navigate_to_is_refused() {
    let mut h = Harness::with_core_config(World::empty(), SimConfig::default(), |c| {
        c.map = None;
    });
    h.take_off(0, HEIGHT_M);
    let err = h
        .try_command(
            0,
            BehaviorCommand::Start {
                behavior: "navigate_to".into(),
                goal: json!({ "x": 3.0, "y": 0.0, "z": 1.0, "speed": 1.0 }),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("mapping is off"), "{err}");
}
