//! Return to launch, collisions and behaviors that cannot progress, in the simulator.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::SimConfig;
use common::{world_with_pole, Harness};
use kestrel::behavior::BehaviorResult;
use kestrel::core::BehaviorCommand;
use kestrel::host::{FrameRegistration, HostError, LoadOptions};
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
    // The safety stage would keep them apart: switched off, the simulator's own contact
    // detection is what is tested.
    let mut config = SimConfig {
        drones: 2,
        ..SimConfig::default()
    };
    config.settings.safety.min_separation_m = 0.0;
    let mut h = Harness::with_config(World::empty(), config);
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

/// Registers `frame_id` in `earth` at `z_m` for every drone, moving up at `climb_mps`.
fn frame_at(h: &mut Harness, frame_id: &str, z_m: f64, climb_mps: f64) -> Result<(), HostError> {
    h.host.set_frame(FrameRegistration {
        frame_id: frame_id.into(),
        parent: "earth".into(),
        translation_m: [0.0, 0.0, z_m],
        yaw_rad: 0.0,
        velocity_mps: [0.0, 0.0, climb_mps],
        yaw_rate_radps: 0.0,
        drone_id: None,
    })
}

#[test]
fn a_goal_in_a_frame_that_rises_past_the_ceiling_never_takes_the_vehicle_out() {
    // go_to gives up when it gets no closer for a while; here it must keep chasing the frame.
    let mut config = SimConfig::default();
    config.settings.behaviors.no_progress_timeout_s = 3600.0;
    let mut h = Harness::with_config(World::empty(), config);
    frame_at(&mut h, "balloon", 0.0, 0.0).unwrap();
    h.take_off(0, 2.0);
    h.start(
        0,
        "go_to",
        json!({ "x": 0.0, "y": 0.0, "z": 0.0, "speed": 5.0, "frame_id": "balloon" }),
    );
    // Moved after the goal was accepted: now 110 m up and climbing 0.2 m/s, to 500 m and
    // beyond; the vehicle catches up with it below the ceiling.
    frame_at(&mut h, "balloon", 110.0, 0.2).unwrap();
    h.run_for(200.0);
    let ceiling = 120.0;
    let top = h.samples[0]
        .iter()
        .map(|s| s.position_m.z)
        .fold(0.0, f64::max);
    assert!(
        top <= ceiling,
        "flew to {top} m against a {ceiling} m ceiling"
    );
    assert!(top > ceiling - 5.0, "held near the ceiling, at {top} m");
    assert!(h.samples[0]
        .iter()
        .all(|s| s.position_m.iter().all(|v| v.is_finite())));
    let records = h.log_records();
    let safety: Vec<_> = records.iter().filter(|r| r["type"] == "safety").collect();
    assert!(!safety.is_empty(), "the override is logged");
    assert!(safety[0]["reason"].as_str().unwrap().contains("ceiling"));
}

#[test]
fn frames_at_absurd_places_are_refused_and_change_nothing() {
    let mut h = Harness::one_drone();
    frame_at(&mut h, "site", 0.0, 0.0).unwrap();
    h.take_off(0, 2.0);
    for (z, climb) in [(1e308, 0.0), (f64::INFINITY, 0.0), (0.0, 1e6), (5e5, 0.0)] {
        let err = frame_at(&mut h, "site", z, climb).unwrap_err();
        assert!(matches!(err, HostError::Frame(_)), "{err}");
    }
    for builtin in ["earth", "map", "odom", "base_link"] {
        assert!(frame_at(&mut h, builtin, 0.0, 0.0).is_err(), "{builtin}");
    }
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 1.0, "y": 0.0, "z": 2.0, "speed": 1.0, "frame_id": "site" }),
    );
    assert_eq!(h.wait_for(0, id, 20.0), BehaviorResult::Succeeded);
    assert!((h.position(0) - Vec3::new(1.0, 0.0, 2.0)).norm() < 0.2);
}

#[test]
fn frame_errors_name_the_field_and_unit_and_the_count_is_bounded() {
    use kestrel::host::engine::MAX_FRAMES;
    let mut h = Harness::one_drone();
    let err = frame_at(&mut h, "site", f64::INFINITY, 0.0).unwrap_err();
    let message = err.to_string();
    assert!(
        message.contains("site") && message.contains("translation_m[2]") && message.contains("(m)"),
        "{message}"
    );
    let err = frame_at(&mut h, "site", 0.0, f64::NAN)
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("velocity_mps[2]") && err.contains("(m/s)"),
        "{err}"
    );
    for k in 0..MAX_FRAMES {
        frame_at(&mut h, &format!("f{k}"), 0.0, 0.0).unwrap();
    }
    let err = frame_at(&mut h, "one_more", 0.0, 0.0)
        .unwrap_err()
        .to_string();
    assert!(err.contains(&MAX_FRAMES.to_string()), "{err}");
    // Replacing a registered frame stays possible at the limit.
    frame_at(&mut h, "f3", 1.0, 0.0).unwrap();
}

#[test]
fn two_drones_whose_goals_cross_are_kept_apart() {
    let mut h = Harness::new(World::empty(), 2);
    h.take_off(0, 2.0);
    h.take_off(1, 2.0);
    // Head on, a little off centre: each goal is where the other drone starts, past it.
    h.start(
        0,
        "go_to",
        json!({ "x": 4.0, "y": 0.2, "z": 2.0, "speed": 1.0 }),
    );
    h.start(
        1,
        "go_to",
        json!({ "x": -2.0, "y": -0.2, "z": 2.0, "speed": 1.0 }),
    );
    h.run_for(25.0);
    let closest = h.samples[0]
        .iter()
        .zip(&h.samples[1])
        .map(|(a, b)| (a.position_m - b.position_m).norm())
        .fold(f64::INFINITY, f64::min);
    assert!(
        closest >= 0.9,
        "came {closest:.2} m close (minimum separation 1.0 m)"
    );
    let records = h.log_records();
    assert!(records.iter().all(|r| r["type"] != "collision"));
    assert!(records.iter().any(
        |r| r["type"] == "safety" && r["reason"].as_str().unwrap().contains("keeping at least")
    ));
}

#[test]
fn moving_a_frame_is_refused_when_it_would_invalidate_a_loaded_mission() {
    let mut h = Harness::one_drone();
    frame_at(&mut h, "site", 0.0, 0.0).unwrap();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 0.0, "y": 0.0, "z": 5.0, "speed": 1.0, "frame_id": "site"}}]});
    h.host
        .load_mission(&mission, LoadOptions::default())
        .unwrap();
    let err = frame_at(&mut h, "site", 500.0, 0.0).unwrap_err();
    assert!(
        err.to_string()
            .contains("loaded mission 1 would no longer be valid")
            && err.to_string().contains("ceiling"),
        "{err}"
    );
    frame_at(&mut h, "site", 20.0, 0.0).unwrap();
    frame_at(&mut h, "elsewhere", 500.0, 0.0).unwrap();
}

/// A drone whose estimate drifts, sent straight at a pole: the safety stage keeps it off what
/// its range beams hit, short of the pole, and says so in the flight log and to the operator.
#[test]
fn a_drifting_drone_sent_at_a_pole_stops_short_of_what_its_beams_hit_and_says_so() {
    use kestrel::host::status::{EventBody, HostEvent};
    let mut settings = kestrel::config::Config::default();
    settings.sim.position_drift_mps = 0.02;
    let mut h = Harness::with_config(
        world_with_pole(5.0, 0.0, 0.25),
        SimConfig {
            settings,
            ..SimConfig::default()
        },
    );
    h.take_off(0, 1.0);
    h.start(
        0,
        "go_to",
        json!({ "x": 10.0, "y": 0.0, "z": 1.0, "speed": 0.75 }),
    );
    h.run_for(20.0);
    let closest_m = h.samples[0]
        .iter()
        .map(|s| (s.position_m.xy() - Vec3::new(5.0, 0.0, 0.0).xy()).norm())
        .fold(f64::INFINITY, f64::min);
    // The pole's 0.25 m and the guard's 0.3 m from its face, less the vehicle's lag in
    // braking: clear of a contact (the vehicle's 0.15 m radius) by more than 5 cm.
    assert!(
        closest_m > 0.45,
        "came {closest_m:.2} m from the pole's centre"
    );
    assert!(
        closest_m < 1.5,
        "stopped {closest_m:.2} m off: not by the guard"
    );
    let records = h.log_records();
    assert!(records.iter().all(|r| r["type"] != "collision"));
    let said = |r: &str| r.contains("from what the range sensor hit");
    assert!(
        records
            .iter()
            .any(|r| r["type"] == "safety" && r["reason"].as_str().is_some_and(said)),
        "no safety record of the guard"
    );
    assert!(
        h.host_events.iter().any(|e| matches!(e,
            HostEvent::Event { event: EventBody::Alert { message }, .. }
                if message.starts_with("safety: ") && said(message))),
        "no alert of the guard"
    );
}
