//! Return to launch, collisions and behaviors that cannot progress, in the simulator.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::SimConfig;
use common::{world_with_pole, Harness};
use kestrel::behavior::BehaviorResult;
use kestrel::core::BehaviorCommand;
use kestrel::sim::world::World;
use kestrel::sim::Environment;
use kestrel::types::{FlightStatus, Vec3};
use serde_json::json;

fn failed_with(result: &BehaviorResult, words: &str) -> bool {
    matches!(result, BehaviorResult::Failed { reason, .. } if reason.contains(words))
}

#[test]
fn rtl_climbs_returns_and_lands() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    h.fly(
        0,
        "go_to",
        json!({ "x": 8.0, "y": 6.0, "z": 2.0, "speed": 2.0 }),
        30.0,
    );
    let start = h.now_s();
    let id = h.start(0, "rtl", json!({ "height": 4.0, "speed": 2.0 }));
    assert_eq!(h.wait_for(0, id, 60.0), BehaviorResult::Succeeded);
    let p = h.position(0);
    assert!(p.xy().norm() < 0.2, "landed at {p}, not home");
    assert_eq!(p.z, 0.0);
    assert!(!h.world().vehicles[0].is_armed());
    let flight = h.samples_between(0, start, h.now_s());
    // It climbs to the return height before heading home, and flies home at that height.
    let left = flight
        .iter()
        .find(|s| (s.position_m.xy() - Vec3::new(8.0, 6.0, 0.0).xy()).norm() > 0.3)
        .unwrap();
    assert!(left.position_m.z > 3.8, "left at {} m", left.position_m.z);
    let top = flight.iter().map(|s| s.position_m.z).fold(0.0, f64::max);
    assert!(top < 4.2, "overshot to {top} m");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:succeeded",
            "rtl:started",
            "rtl:finished:succeeded",
        ],
    );
}

#[test]
fn a_drone_flown_into_a_pole_reports_a_collision() {
    let mut h = Harness::new(world_with_pole(5.0, 0.0, 0.3), 1);
    h.take_off(0, 2.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 10.0, "y": 0.0, "z": 2.0, "speed": 2.0 }),
    );
    let result = h.wait_for(0, id, 20.0);
    assert!(
        failed_with(&result, "collision with obstacle"),
        "{result:?}"
    );
    // Hit at the pole's surface (radius 0.3 + vehicle 0.15).
    let hit_x = h.position(0).x;
    assert!((hit_x - 4.55).abs() < 0.1, "hit at x = {hit_x}");
    // The flight is over: motors off, it falls and stays down, and cannot take off again.
    h.run_for(3.0);
    let v = &h.world().vehicles[0];
    assert_eq!(v.flight_status(), FlightStatus::Crashed);
    assert_eq!(v.state.position_m.z, 0.0);
    assert!(!v.is_armed());
    let retry = h
        .try_command(
            0,
            BehaviorCommand::Start {
                behavior: "takeoff".into(),
                goal: json!({ "height": 1.0 }),
            },
        )
        .unwrap_err();
    assert!(retry.to_string().contains("collision"), "{retry}");
    let records = h.log_records();
    let collisions: Vec<_> = records
        .iter()
        .filter(|r| r["type"] == "collision")
        .collect();
    assert_eq!(collisions.len(), 1, "one collision record");
    assert!(collisions[0]["reason"]
        .as_str()
        .unwrap()
        .contains("obstacle"));
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:failed",
        ],
    );
}

#[test]
fn two_drones_flown_into_each_other_both_report_it() {
    let mut h = Harness::new(World::empty(), 2);
    // Default starts: a row along x, 2 m apart.
    assert_eq!(h.position(1), Vec3::new(2.0, 0.0, 0.0));
    h.take_off(0, 2.0);
    h.take_off(1, 2.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 4.0, "y": 0.0, "z": 2.0, "speed": 1.0 }),
    );
    let result = h.wait_for(0, id, 20.0);
    assert!(failed_with(&result, "collision with drone_1"), "{result:?}");
    h.step();
    for d in 0..2 {
        assert_eq!(h.world().vehicles[d].flight_status(), FlightStatus::Crashed);
    }
    let records = h.log_records();
    for d in ["drone_0", "drone_1"] {
        assert!(records
            .iter()
            .any(|r| r["type"] == "collision" && r["drone"] == d));
    }
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:failed",
        ],
    );
    h.assert_log(1, &["takeoff:started", "takeoff:finished:succeeded"]);
}

#[test]
fn a_go_to_against_an_overwhelming_wind_fails_with_a_reason() {
    let mut h = Harness::one_drone();
    h.take_off(0, 5.0);
    // A storm stronger than the vehicle's tilt limit can hold against.
    h.world_mut().environment.wind_mps = Vec3::new(30.0, 0.0, 0.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": -20.0, "y": 0.0, "z": 5.0, "speed": 3.0 }),
    );
    let result = h.wait_for(0, id, 60.0);
    assert!(failed_with(&result, "no progress"), "{result:?}");
    // Then the server holds the vehicle as well as it can: still flying, still armed.
    assert!(h.world().vehicles[0].is_armed());
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:failed",
        ],
    );
}

#[test]
fn a_follow_path_the_vehicle_cannot_fly_fails_with_a_reason() {
    let mut h = Harness::one_drone();
    h.take_off(0, 5.0);
    h.world_mut().environment.wind_mps = Vec3::new(30.0, 0.0, 0.0);
    let id = h.start(
        0,
        "follow_path",
        json!({ "path": [[-5.0, 0.0, 5.0], [-10.0, 5.0, 5.0]], "speed": 2.0 }),
    );
    let result = h.wait_for(0, id, 60.0);
    assert!(failed_with(&result, "no progress"), "{result:?}");
    let took = h.finished_at(0, id).unwrap() - h.finished_at(0, 1).unwrap();
    assert!(took < 25.0, "gave up after {took} s");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "follow_path:started",
            "follow_path:finished:failed",
        ],
    );
}

#[test]
fn hover_holds_position_in_a_steady_wind_with_gusts() {
    let config = SimConfig {
        seed: 3,
        environment: Environment {
            wind_mps: Vec3::new(4.0, -2.0, 0.0),
            turbulence_mps2: 0.5,
        },
        ..SimConfig::default()
    };
    let mut h = Harness::with_config(World::empty(), config);
    h.take_off(0, 3.0);
    h.fly(
        0,
        "go_to",
        json!({ "x": 5.0, "y": 5.0, "z": 3.0, "speed": 2.0 }),
        30.0,
    );
    let id = h.start(0, "hover", json!({}));
    h.run_for(10.0);
    let t = h.now_s();
    h.run_for(10.0);
    let goal = Vec3::new(5.0, 5.0, 3.0);
    let worst = common::max_distance(&h.samples_between(0, t, h.now_s()), &goal);
    assert!(worst < 0.3, "wandered {worst} m from the hover point");
    h.command(0, BehaviorCommand::Stop(id));
    h.step();
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:succeeded",
            "hover:started",
            "hover:finished:aborted",
        ],
    );
}
