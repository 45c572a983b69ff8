//! Whole flights in the thesis worlds: several drones, the demo missions, the flight log, seeds.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::Harness;
use common::SimConfig;
use kestrel::mission::{Action, MissionEnded, MissionUpdate};
use kestrel::scenario::demo::demo_missions;
use kestrel::sim::world::World;
use kestrel::sim::Environment;
use kestrel::types::Vec3;
use std::path::Path;

fn thesis_world(name: &str) -> World {
    World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join(format!("sitl/worlds/{name}.json")))
        .unwrap()
}

/// Flies the demo mission of every drone on the host, as `kestrel sim` does, until every
/// mission has ended; returns how each ended.
fn fly_demo(h: &mut Harness, limit_s: f64) -> Vec<Result<(), MissionEnded>> {
    let mut ids = Vec::new();
    for mission in demo_missions(h.world()) {
        let drone = mission["target"].as_str().unwrap().to_string();
        let updated = h
            .host
            .update(&MissionUpdate {
                drone_id: Some(drone),
                mission_id: None,
                item_id: None,
                action: Action::Execute,
                mission: Some(mission),
            })
            .unwrap();
        ids.push(updated.status.mission_id.unwrap());
    }
    let outcomes = |h: &Harness| -> Vec<Option<Result<(), MissionEnded>>> {
        let cores = h.host.cores();
        h.host
            .executors()
            .iter()
            .zip(cores)
            .zip(&ids)
            .map(|((ex, core), id)| ex.status(core).outcome(*id))
            .collect()
    };
    h.run_until(limit_s, "every demo mission to end", |h| {
        outcomes(h).iter().all(Option::is_some)
    });
    outcomes(h).into_iter().flatten().collect()
}

const DEMO_SEQUENCE: [&str; 8] = [
    "takeoff:started",
    "takeoff:finished:succeeded",
    "go_to:started",
    "go_to:finished:succeeded",
    "follow_path:started",
    "follow_path:finished:succeeded",
    "land:started",
    "land:finished:succeeded",
];

#[test]
fn seven_drones_take_off_and_land_at_the_thesis_start_poses_in_low() {
    let world = thesis_world("low");
    let starts = world.starts_xy_yaw["7"].clone();
    let mut h = Harness::new(world, 7);
    for (i, [x, y, yaw]) in starts.iter().enumerate() {
        let v = &h.world().vehicles[i];
        assert_eq!(
            v.state.position_m,
            Vec3::new(*x, *y, 0.0),
            "drone_{i} start"
        );
        assert_eq!(v.state.yaw_rad, kestrel::types::wrap_angle_rad(*yaw));
    }
    let results = fly_demo(&mut h, 120.0);
    assert!(results.iter().all(Result::is_ok), "{results:?}");
    let shapes = h.world().shapes().to_vec();
    for (i, [x, y, _]) in starts.iter().enumerate() {
        let start = Vec3::new(*x, *y, 0.0);
        let samples = &h.samples[i];
        // Takeoff is vertical: still above the start pad at 2.9 m.
        let top = samples
            .iter()
            .find(|s| s.position_m.z > 2.9)
            .unwrap()
            .position_m;
        assert!(
            (top.xy() - start.xy()).norm() < 0.05,
            "drone_{i} drifted on takeoff"
        );
        // Never near a pole, never near another drone.
        for s in samples {
            for shape in &shapes {
                assert!(
                    shape.distance_m(&s.position_m).is_none_or(|d| d > 0.5),
                    "drone_{i} passed {:?} m from a pole at {}",
                    shape.distance_m(&s.position_m),
                    s.position_m
                );
            }
        }
        for j in (i + 1)..7 {
            let closest = samples
                .iter()
                .zip(&h.samples[j])
                .map(|(a, b)| (a.position_m - b.position_m).norm())
                .fold(f64::INFINITY, f64::min);
            assert!(
                closest > 1.0,
                "drone_{i} and drone_{j} came {closest} m close"
            );
        }
        let end = samples.last().unwrap();
        assert!(
            !end.armed && end.position_m.z == 0.0,
            "drone_{i} landed and disarmed"
        );
        // It lands where the demo ends: 8 m to the left of its start heading (or the turned or
        // shrunk placement, never farther).
        let away = (end.position_m - start).norm();
        assert!(
            away <= 8.0 + 0.2,
            "drone_{i} landed {away} m from its start"
        );
        h.assert_log(i, &DEMO_SEQUENCE);
    }
    assert!(h.log_records().iter().all(|r| r["type"] != "collision"));
}

#[test]
fn the_demo_avoids_poles_in_the_densest_world() {
    let mut h = Harness::new(thesis_world("high"), 7);
    let results = fly_demo(&mut h, 120.0);
    assert!(results.iter().all(Result::is_ok), "{results:?}");
}

#[test]
fn flight_log_has_poses_at_10_hz_for_every_drone() {
    let mut h = Harness::new(World::empty(), 2);
    fly_demo(&mut h, 60.0);
    let records = h.log_records();
    for drone in ["drone_0", "drone_1"] {
        let poses: Vec<_> = records
            .iter()
            .filter(|r| r["type"] == "pose" && r["drone"] == drone)
            .collect();
        for r in &poses {
            for key in ["t", "x", "y", "z", "yaw", "vx", "vy", "vz"] {
                assert!(r[key].is_number(), "{key} missing in {r}");
            }
        }
        let times: Vec<f64> = poses.iter().map(|r| r["t"].as_f64().unwrap()).collect();
        let worst_gap = times.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
        assert!(
            worst_gap <= 0.1 + 1e-6,
            "{drone}: {worst_gap} s between poses"
        );
        let span = times.last().unwrap() - times.first().unwrap();
        assert!(span > 20.0, "{drone}: poses over {span} s only");
        // The pose records name the behavior flying at that moment.
        assert!(poses.iter().any(|r| r["behavior"] == "follow_path"));
    }
}

fn noisy_flight(seed: u64) -> Vec<serde_json::Value> {
    let config = SimConfig {
        drones: 2,
        seed,
        environment: Environment {
            wind_mps: Vec3::new(1.0, 0.5, 0.0),
            turbulence_mps2: 0.8,
        },
        ..SimConfig::default()
    };
    let mut h = Harness::with_config(thesis_world("low"), config);
    fly_demo(&mut h, 120.0);
    h.log_records()
}

#[test]
fn the_same_seed_gives_the_same_flight() {
    let a = noisy_flight(11);
    assert_eq!(a, noisy_flight(11), "same seed, same log");
    assert_ne!(a, noisy_flight(12), "another seed, another flight");
}

#[test]
fn every_drone_sees_the_others_positions_and_goals_in_the_fleet_view() {
    let mut h = Harness::new(World::empty(), 2);
    h.take_off(0, 2.0);
    let goal = Vec3::new(6.0, 3.0, 2.0);
    h.start(
        0,
        "go_to",
        serde_json::json!({ "x": goal.x, "y": goal.y, "z": goal.z, "speed": 1.0 }),
    );
    h.run_for(2.0);
    let view = h.host.fleet_view().clone();
    assert_eq!(view.drones.len(), 2);
    let d0 = view.get("drone_0").unwrap();
    assert!(d0.flying && d0.local);
    assert_eq!(d0.motion_behavior.as_deref(), Some("go_to"));
    assert_eq!(d0.goal_enu_m, Some(goal));
    let truth = h.world().vehicles[0].state.position_m;
    assert!(
        (d0.position_enu_m - truth).norm() < 0.1,
        "{:?} vs {truth:?}",
        d0.position_enu_m
    );
    let d1 = view.get("drone_1").unwrap();
    assert!(!d1.flying && d1.motion_behavior.is_none());
    assert_eq!(view.others("drone_1").count(), 1);
}
