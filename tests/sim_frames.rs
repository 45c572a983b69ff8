//! Goals in other frames, flown in the simulator: moving user frames and WGS84 coordinates.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;

use common::Harness;
use kestrel::behavior::BehaviorResult;
use kestrel::core::BehaviorCommand;
use kestrel::estimator::frames::{FrameMotion, EARTH};
use kestrel::estimator::geodetic::GeoPoint;
use kestrel::host::FrameRegistration;
use kestrel::sim::world::World;
use kestrel::types::{Pose, Vec3};
use serde_json::json;
use std::time::Duration;

/// Registers a frame in `earth` for every drone, as the API does.
fn register(h: &mut Harness, frame_id: &str, motion: &FrameMotion) {
    let p = motion.pose_in_parent.position_m;
    let v = motion.velocity_mps;
    h.host
        .set_frame(FrameRegistration {
            frame_id: frame_id.into(),
            parent: EARTH.into(),
            translation_m: [p.x, p.y, p.z],
            yaw_rad: motion.pose_in_parent.yaw_rad(),
            velocity_mps: [v.x, v.y, v.z],
            yaw_rate_radps: motion.yaw_rate_radps,
            drone_id: None,
        })
        .unwrap();
}

#[test]
fn go_to_in_a_moving_frame_tracks_it() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    // A target drifting east at 0.5 m/s, starting 6 m north of the drone.
    let motion = FrameMotion {
        pose_in_parent: Pose::from_position_yaw(Vec3::new(0.0, 6.0, 0.0), 0.0),
        stamp: h.host.now(),
        velocity_mps: Vec3::new(0.5, 0.0, 0.0),
        yaw_rate_radps: 0.0,
    };
    register(&mut h, "target", &motion);
    let target_at = |t: Duration| h_frame_point(&motion, t, &Vec3::new(0.0, 0.0, 3.0));
    let id = h.start(
        0,
        "go_to",
        json!({ "x": 0.0, "y": 0.0, "z": 3.0, "speed": 2.0, "frame_id": "target" }),
    );
    assert_eq!(h.wait_for(0, id, 30.0), BehaviorResult::Succeeded);
    let now = h.host.now();
    let goal_now = target_at(now);
    assert!(
        (h.position(0) - goal_now).norm() < 0.2,
        "at {} but the target is at {goal_now}",
        h.position(0)
    );
    assert!(goal_now.x > 1.5, "the target moved meanwhile: {goal_now}");
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

/// Where a point fixed in a frame with `motion` (parent `earth`) is at `t`.
fn h_frame_point(motion: &FrameMotion, t: Duration, point: &Vec3) -> Vec3 {
    let mut tree = kestrel::estimator::frames::FrameTree::new();
    tree.set("f", EARTH, *motion).unwrap();
    tree.point_to_earth(point, "f", t).unwrap()
}

#[test]
fn follow_reference_stays_on_a_turning_frame() {
    let mut h = Harness::one_drone();
    h.take_off(0, 2.0);
    // A nacelle 4 m east turning at 0.1 rad/s; the reference is 5 m in front of it.
    let motion = FrameMotion {
        pose_in_parent: Pose::from_position_yaw(Vec3::new(4.0, 0.0, 0.0), 0.0),
        stamp: h.host.now(),
        velocity_mps: Vec3::zeros(),
        yaw_rate_radps: 0.1,
    };
    register(&mut h, "nacelle", &motion);
    let point = Vec3::new(-5.0, 0.0, 3.0);
    let id = h.start(
        0,
        "follow_reference",
        json!({ "x": point.x, "y": point.y, "z": point.z, "frame_id": "nacelle", "speed_x": 3.0, "speed_y": 3.0, "speed_z": 1.0 }),
    );
    h.run_for(15.0);
    // Caught up: from here on the drone stays on the moving point.
    let mut worst: f64 = 0.0;
    for _ in 0..1500 {
        h.step();
        let target = h_frame_point(&motion, h.host.now(), &point);
        worst = worst.max((h.position(0) - target).norm());
    }
    assert!(worst < 0.3, "fell {worst} m behind the turning frame");
    assert!(
        h.result(0, id).is_none(),
        "follow_reference never ends by itself"
    );
    h.command(0, BehaviorCommand::Stop(id));
    h.step();
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "follow_reference:started",
            "follow_reference:finished:aborted",
        ],
    );
}

/// East and north offsets (m) of `p` from `origin` on the WGS84 ellipsoid, from the
/// meridian and prime-vertical radii of curvature (good to millimetres over tens of metres).
fn local_offset_m(origin: &GeoPoint, p: &GeoPoint) -> (f64, f64) {
    let a = 6_378_137.0;
    let e2 = 6.694_379_990_14e-3;
    let phi = origin.lat_deg.to_radians();
    let w = (1.0 - e2 * phi.sin().powi(2)).sqrt();
    let meridian = a * (1.0 - e2) / w.powi(3);
    let prime_vertical = a / w;
    let north = (p.lat_deg - origin.lat_deg).to_radians() * meridian;
    let east = (p.lon_deg - origin.lon_deg).to_radians() * prime_vertical * phi.cos();
    (east, north)
}

#[test]
fn a_goal_in_lat_lon_lands_where_it_should() {
    let origin = GeoPoint {
        lat_deg: 47.397_742,
        lon_deg: 8.545_594,
        alt_m: 488.0,
    };
    let mut world = World::empty();
    world.geodetic_origin = Some(origin);
    let mut h = Harness::new(world, 1);
    h.take_off(0, 3.0);
    let goal = GeoPoint {
        lat_deg: origin.lat_deg + 0.000_1,
        lon_deg: origin.lon_deg - 0.000_15,
        alt_m: origin.alt_m + 4.0,
    };
    let (east, north) = local_offset_m(&origin, &goal);
    assert!(north > 11.0 && east < -11.0, "({east}, {north})");
    h.fly(
        0,
        "go_to_gps",
        json!({ "lat": goal.lat_deg, "lon": goal.lon_deg, "alt": goal.alt_m, "speed": 3.0 }),
        40.0,
    );
    assert!((h.position(0).z - 4.0).abs() < 0.2, "{}", h.position(0));
    h.fly(0, "land", json!({ "speed": 1.0 }), 30.0);
    let p = h.position(0);
    assert_eq!(p.z, 0.0);
    let miss = ((p.x - east).powi(2) + (p.y - north).powi(2)).sqrt();
    assert!(
        miss < 0.2,
        "landed at ({}, {}), expected ({east}, {north})",
        p.x,
        p.y
    );
    h.assert_log(
        0,
        &[
            "takeoff:started",
            "takeoff:finished:succeeded",
            "go_to_gps:started",
            "go_to_gps:finished:succeeded",
            "land:started",
            "land:finished:succeeded",
        ],
    );
}
