//! Motion behaviors flown in the built-in simulator, in simulated time.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::{closest_approach, max_distance, Harness};
use kestrel::behavior::{BehaviorResult, FailureCode};
use kestrel::core::BehaviorCommand;
use kestrel::types::{FlightStatus, Vec3};
use serde_json::json;

#[test]
fn takeoff_reaches_the_height_and_stays_there() {
    let mut h = Harness::one_drone();
    let id = h.start(0, "takeoff", json!({ "height": 3.0, "speed": 1.0 }));
    h.wait_for(0, id, 20.0);
    assert_eq!(h.result(0, id), Some(BehaviorResult::Succeeded));
    let done_at = h.finished_at(0, id).unwrap();
    // 3 m at 1 m/s, plus arming and the final approach.
    assert!(done_at > 3.0 && done_at < 8.0, "took {done_at} s");
    assert!(
        (h.position(0).z - 3.0).abs() < 0.1,
        "z = {}",
        h.position(0).z
    );
    // The climb is vertical and never faster than asked.
    let climb = h.samples_between(0, 0.0, done_at);
    let max_vz = climb.iter().map(|s| s.velocity_mps.z).fold(0.0, f64::max);
    assert!(max_vz < 1.1, "climbed at {max_vz} m/s");
    assert!(climb.iter().all(|s| s.position_m.xy().norm() < 0.05));
    // Hovering afterwards keeps the height.
    let t = h.now_s();
    h.run_for(5.0);
    let hover = h.samples_between(0, t, h.now_s());
    assert!(hover.iter().all(|s| (s.position_m.z - 3.0).abs() < 0.1));
    h.assert_log(0, &["takeoff:started", "takeoff:finished:succeeded"]);
}

#[test]
fn go_to_ends_within_0_2_m_of_the_goal() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let goal = Vec3::new(6.0, -4.0, 3.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": goal.x, "y": goal.y, "z": goal.z, "speed": 2.0 }),
    );
    assert_eq!(h.wait_for(0, id, 30.0), BehaviorResult::Succeeded);
    assert!((h.position(0) - goal).norm() < 0.2);
    // 7.3 m at up to 2 m/s: a few seconds, not a crawl.
    let took = h.finished_at(0, id).unwrap() - h.finished_at(0, 1).unwrap();
    assert!(took < 8.0, "go_to took {took} s");
    // And it stays there, without overshooting on the way in.
    let t = h.now_s();
    h.run_for(5.0);
    assert!(max_distance(&h.samples_between(0, t, h.now_s()), &goal) < 0.2);
    let start = Vec3::new(0.0, 0.0, 2.0);
    let along = (goal - start).normalize();
    let overshoot = h.samples[0]
        .iter()
        .map(|s| (s.position_m - goal).dot(&along))
        .fold(f64::NEG_INFINITY, f64::max);
    assert!(overshoot < 0.1, "overshot the goal by {overshoot} m");
    let fastest = h.samples[0]
        .iter()
        .map(|s| s.velocity_mps.norm())
        .fold(0.0, f64::max);
    assert!(fastest < 2.0 * 1.05, "flew at {fastest} m/s, asked 2");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:succeeded",
        ],
    );
}

#[test]
fn go_to_yaw_modes_turn_the_vehicle() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    // path_facing: heads toward the goal (north-east = 45 deg).
    h.fly(
        0,
        "go_to",
        json!({ "x": 5.0, "y": 5.0, "z": 2.0, "speed": 1.0, "yaw_mode": "path_facing" }),
        30.0,
    );
    let during = &h.samples[0];
    let mid = during[during.len() - 300];
    assert!(
        (mid.yaw_rad - std::f64::consts::FRAC_PI_4).abs() < 0.05,
        "{}",
        mid.yaw_rad
    );
    // fixed: ends at the given heading.
    h.fly(
        0,
        "go_to",
        json!({ "x": 5.0, "y": 0.0, "z": 2.0, "speed": 1.0, "yaw_mode": "fixed", "yaw_angle": -1.0 }),
        30.0,
    );
    h.run_for(2.0);
    let yaw = h.world().vehicles[0].state.yaw_rad;
    assert!((yaw + 1.0).abs() < 0.05, "{yaw}");
    // face_point: looks at the point while moving.
    h.fly(
        0,
        "go_to",
        json!({ "x": 0.0, "y": 0.0, "z": 2.0, "speed": 1.0, "yaw_mode": "face_point", "face_point": [0.0, 10.0, 0.0] }),
        30.0,
    );
    h.run_for(2.0);
    let yaw = h.world().vehicles[0].state.yaw_rad;
    assert!((yaw - std::f64::consts::FRAC_PI_2).abs() < 0.05, "{yaw}");
    assert_eq!(h.log_sequence(0).len(), 8, "takeoff and three go_to");
}

#[test]
fn a_short_go_to_still_ends_at_its_fixed_heading() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    // 0.3 m takes far less time than turning by 3 rad at the yaw-rate limit.
    h.fly(
        0,
        "go_to",
        json!({ "x": 0.3, "y": 0.0, "z": 2.0, "speed": 1.0, "yaw_mode": "fixed", "yaw_angle": 3.0 }),
        20.0,
    );
    h.run_for(3.0);
    let yaw = h.world().vehicles[0].state.yaw_rad;
    assert!((yaw - 3.0).abs() < 0.05, "stopped turning at {yaw} rad");
    assert!((h.position(0) - Vec3::new(0.3, 0.0, 2.0)).norm() < 0.2);
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:succeeded",
        ],
    );
}

#[test]
fn follow_path_passes_every_waypoint_without_stopping() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let path = [
        Vec3::new(4.0, 0.0, 2.0),
        Vec3::new(4.0, 4.0, 2.5),
        Vec3::new(0.0, 4.0, 3.0),
        Vec3::new(0.0, 8.0, 3.0),
    ];
    let goal_path: Vec<[f64; 3]> = path.iter().map(|p| [p.x, p.y, p.z]).collect();
    let start = h.now_s();
    let id = h.start(
        0,
        "follow_path",
        json!({ "path": goal_path, "speed": 1.5, "yaw_mode": "path_facing" }),
    );
    assert_eq!(h.wait_for(0, id, 60.0), BehaviorResult::Succeeded);
    let flight = h.samples_between(0, start, h.now_s());
    let mut passed_at = Vec::new();
    for w in &path {
        let (d, t) = closest_approach(&flight, w);
        assert!(d < 0.3, "waypoint {w} missed by {d} m");
        passed_at.push(t);
    }
    assert!(
        passed_at.windows(2).all(|p| p[0] < p[1]),
        "in order: {passed_at:?}"
    );
    // No stop between the first and the last waypoint.
    let between = h.samples_between(0, passed_at[0], passed_at[3] - 0.5);
    let slowest = between
        .iter()
        .map(|s| s.velocity_mps.norm())
        .fold(f64::INFINITY, f64::min);
    assert!(slowest > 0.2, "slowed to {slowest} m/s between waypoints");
    let fastest = flight
        .iter()
        .map(|s| s.velocity_mps.norm())
        .fold(0.0, f64::max);
    assert!(fastest < 1.5 * 1.1, "flew at {fastest} m/s, asked 1.5");
    assert!((h.position(0) - path[3]).norm() < 0.2);
    // 14 m of path at 1.5 m/s with slow corners: well under a stop-and-go time.
    let took = h.now_s() - start;
    assert!(took < 20.0, "took {took} s");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "follow_path:started",
            "follow_path:finished:succeeded",
        ],
    );
}

#[test]
fn pause_holds_position_and_resume_finishes_the_goal() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let goal = Vec3::new(10.0, 0.0, 2.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 10.0, "y": 0.0, "z": 2.0, "speed": 1.5 }),
    );
    h.run_for(3.0);
    let paused_at = h.position(0);
    assert!(paused_at.x > 1.5 && paused_at.x < 8.0, "{paused_at}");
    h.command(0, BehaviorCommand::Pause(id));
    // Braking from 1.5 m/s, then a still hover.
    h.run_for(2.0);
    assert!((h.position(0) - paused_at).norm() < 0.6);
    let hold = h.position(0);
    let t = h.now_s();
    h.run_for(10.0);
    let drift = max_distance(&h.samples_between(0, t, h.now_s()), &hold);
    assert!(drift < 0.1, "drifted {drift} m while paused");
    assert!(h.result(0, id).is_none(), "still paused, not finished");
    h.command(0, BehaviorCommand::Resume(id));
    assert_eq!(h.wait_for(0, id, 30.0), BehaviorResult::Succeeded);
    assert!((h.position(0) - goal).norm() < 0.2);
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:paused",
            "go_to:resumed",
            "go_to:finished:succeeded",
        ],
    );
}

#[test]
fn modify_redirects_a_running_go_to() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let first = Vec3::new(10.0, 0.0, 2.0);
    let second = Vec3::new(0.0, 6.0, 3.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": first.x, "y": first.y, "z": first.z, "speed": 1.5 }),
    );
    h.run_for(2.0);
    // A goal that cannot be resolved is refused and the flight goes on unchanged.
    let refused = h.try_command(
        0,
        BehaviorCommand::Modify {
            id,
            goal: json!({ "x": 1.0, "y": 1.0, "z": 2.0, "speed": 1.0, "frame_id": "nowhere" }),
        },
    );
    assert!(
        refused
            .as_ref()
            .is_err_and(|e| e.to_string().contains("nowhere")),
        "{refused:?}"
    );
    let modified_at = h.now_s();
    h.command(
        0,
        BehaviorCommand::Modify {
            id,
            goal: json!({ "x": second.x, "y": second.y, "z": second.z, "speed": 1.5 }),
        },
    );
    assert_eq!(h.wait_for(0, id, 40.0), BehaviorResult::Succeeded);
    assert!((h.position(0) - second).norm() < 0.2);
    let after = h.samples_between(0, modified_at, h.now_s());
    let (closest_to_first, _) = closest_approach(&after, &first);
    assert!(closest_to_first > 5.0, "still went toward the first goal");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:modified",
            "go_to:finished:succeeded",
        ],
    );
}

#[test]
fn stop_leaves_the_drone_hovering() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 10.0, "y": 0.0, "z": 2.0, "speed": 2.0 }),
    );
    h.run_for(3.0);
    h.command(0, BehaviorCommand::Stop(id));
    h.step();
    assert_eq!(
        h.result(0, id),
        Some(BehaviorResult::Aborted {
            code: FailureCode::Stopped,
            reason: "stopped".into()
        })
    );
    h.run_for(2.0);
    let hold = h.position(0);
    assert!(hold.x < 9.0, "it stopped short of the goal: {hold}");
    let t = h.now_s();
    h.run_for(10.0);
    let samples = h.samples_between(0, t, h.now_s());
    assert!(max_distance(&samples, &hold) < 0.1);
    assert!(samples
        .iter()
        .all(|s| s.armed && s.flight == FlightStatus::Flying));
    assert!(h.host.cores()[0].server().active().is_empty());
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:aborted",
        ],
    );
}

#[test]
fn land_touches_down_and_disarms() {
    let mut h = Harness::one_drone();
    h.take_off(0, 3.0);
    h.fly(
        0,
        "go_to",
        json!({ "x": 2.0, "y": 1.0, "z": 3.0, "speed": 1.0 }),
        20.0,
    );
    let start = h.now_s();
    let id = h.fly(0, "land", json!({ "speed": 0.5 }), 30.0);
    let took = h.finished_at(0, id).unwrap() - start;
    // 3 m at 0.5 m/s is 6 s; disarming confirms right after touchdown.
    assert!(took > 5.5 && took < 10.0, "landing took {took} s");
    let s = &h.world().vehicles[0];
    assert!(!s.is_armed());
    assert_eq!(s.state.position_m.z, 0.0);
    assert!((s.state.position_m.xy() - Vec3::new(2.0, 1.0, 0.0).xy()).norm() < 0.2);
    let descent = h.samples_between(0, start, h.now_s());
    let fastest = descent
        .iter()
        .map(|s| -s.velocity_mps.z)
        .fold(0.0, f64::max);
    assert!(fastest < 0.6, "descended at {fastest} m/s");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to:started",
            "go_to:finished:succeeded",
            "land:started",
            "land:finished:succeeded",
        ],
    );
}

#[test]
fn rotate_turns_in_place() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let here = h.position(0);
    h.fly(
        0,
        "rotate",
        json!({ "by_angle": 2.0, "yaw_speed": 1.0 }),
        10.0,
    );
    let yaw = h.world().vehicles[0].state.yaw_rad;
    assert!((yaw - 2.0).abs() < 0.05, "{yaw}");
    assert!((h.position(0) - here).norm() < 0.1);
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "rotate:started",
            "rotate:finished:succeeded",
        ],
    );
}

#[test]
fn hover_lasts_its_duration() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let start = h.now_s();
    let id = h.fly(0, "hover", json!({ "duration": 4.0 }), 10.0);
    let took = h.finished_at(0, id).unwrap() - start;
    assert!((took - 4.0).abs() < 0.05, "{took}");
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "hover:started",
            "hover:finished:succeeded",
        ],
    );
}

#[test]
fn goals_that_cannot_be_flown_are_rejected_with_a_reason() {
    let mut h = Harness::one_drone();
    let err = h
        .try_command(
            0,
            BehaviorCommand::Start {
                behavior: "go_to".into(),
                goal: json!({ "x": 1.0, "y": 0.0, "z": 1.0, "speed": 1.0 }),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("not flying"), "{err}");
    let err = h
        .try_command(
            0,
            BehaviorCommand::Start {
                behavior: "takeoff".into(),
                goal: json!({ "height": -1.0 }),
            },
        )
        .unwrap_err();
    assert!(err.to_string().contains("height"), "{err}");
    assert!(h.log_sequence(0).is_empty(), "rejected goals never start");
}

#[test]
fn a_landed_drone_takes_off_again_and_rtl_goes_to_the_new_home() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    h.fly(
        0,
        "go_to",
        json!({ "x": 4.0, "y": 3.0, "z": 2.0, "speed": 2.0 }),
        20.0,
    );
    h.fly(0, "land", json!({ "speed": 1.0 }), 20.0);
    h.take_off(0, 2.5);
    assert!(
        (h.position(0) - Vec3::new(4.0, 3.0, 2.5)).norm() < 0.1,
        "{}",
        h.position(0)
    );
    h.fly(
        0,
        "go_to",
        json!({ "x": 0.0, "y": 0.0, "z": 2.5, "speed": 2.0 }),
        20.0,
    );
    h.fly(0, "rtl", json!({ "height": 2.0, "speed": 2.0 }), 40.0);
    let p = h.position(0);
    assert!((p.xy() - Vec3::new(4.0, 3.0, 0.0).xy()).norm() < 0.2, "{p}");
    assert_eq!(h.log_sequence(0).len(), 12);
}

#[test]
fn every_estimator_plugin_flies_the_simulator() {
    use common::SimConfig;
    use kestrel::estimator::EstimatorPlugin;
    use kestrel::sim::world::World;
    for plugin in [
        EstimatorPlugin::GroundTruth,
        EstimatorPlugin::AutopilotOdometry,
        EstimatorPlugin::ExternalPose,
    ] {
        let mut h = Harness::with_core_config(World::empty(), SimConfig::default(), |c| {
            c.estimator = plugin;
        });
        h.take_off(0, 2.0);
        let goal = Vec3::new(3.0, 2.0, 2.0);
        h.fly(
            0,
            "go_to",
            json!({ "x": 3.0, "y": 2.0, "z": 2.0, "speed": 1.0 }),
            30.0,
        );
        assert!((h.position(0) - goal).norm() < 0.2, "{plugin:?}");
    }
}

#[test]
fn a_paused_follow_path_resumes_through_the_waypoints_left() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    let path = [
        Vec3::new(5.0, 0.0, 2.0),
        Vec3::new(5.0, 5.0, 2.0),
        Vec3::new(0.0, 5.0, 2.0),
    ];
    let goal_path: Vec<[f64; 3]> = path.iter().map(|p| [p.x, p.y, p.z]).collect();
    let start = h.now_s();
    let id = h.start(0, "follow_path", json!({ "path": goal_path, "speed": 1.5 }));
    h.run_until(20.0, "the first corner", |h| {
        (h.position(0) - path[0]).norm() < 0.3
    });
    h.run_for(1.0);
    h.command(0, BehaviorCommand::Pause(id));
    h.run_for(5.0);
    let hold = h.position(0);
    h.run_for(3.0);
    assert!((h.position(0) - hold).norm() < 0.1, "holds while paused");
    h.command(0, BehaviorCommand::Resume(id));
    assert_eq!(h.wait_for(0, id, 40.0), BehaviorResult::Succeeded);
    let flight = h.samples_between(0, start, h.now_s());
    for w in &path {
        let (d, _) = closest_approach(&flight, w);
        assert!(d < 0.3, "waypoint {w} missed by {d} m");
    }
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "follow_path:started",
            "follow_path:paused",
            "follow_path:resumed",
            "follow_path:finished:succeeded",
        ],
    );
}
