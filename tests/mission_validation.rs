#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Malformed and unsafe missions: each is rejected whole, with every error as a JSON pointer
//! and a message, and nothing is loaded or moves.

mod mission_rig;

use kestrel::config::Config;
use kestrel::host::engine::{HostError, LoadOptions};
use kestrel::mission::validate::{validate_text, ValidationContext};
use kestrel::mission::{Limits, ValidationError};
use mission_rig::Rig;
use serde_json::{json, Value};

fn go_to(x: f64, y: f64, z: f64) -> Value {
    json!({"behavior": "go_to", "args": {"x": x, "y": y, "z": z, "speed": 1.0}})
}

fn plan(items: Vec<Value>) -> Value {
    json!({"target": "drone_0", "plan": items})
}

fn takeoff() -> Value {
    json!({"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}})
}

/// (case, mission, pointer of the first error, words its message must contain)
fn cases() -> Vec<(&'static str, Value, &'static str, &'static str)> {
    let many: Vec<Value> = (0..1001).map(|_| takeoff()).collect();
    let long_path: Vec<Value> = (0..10_001)
        .map(|i| json!([f64::from(i) * 0.01, 0.0, 2.0]))
        .collect();
    vec![
        ("not an object", json!([1, 2]), "", "JSON object"),
        (
            "missing target",
            json!({"plan": [takeoff()]}),
            "/target",
            "missing target",
        ),
        (
            "target not a string",
            json!({"target": 3, "plan": [takeoff()]}),
            "/target",
            "drone id string",
        ),
        (
            "target of another drone",
            json!({"target": "drone_7", "plan": [takeoff()]}),
            "/target",
            "drone_7",
        ),
        (
            "missing plan",
            json!({"target": "drone_0"}),
            "/plan",
            "missing plan",
        ),
        (
            "plan not an array",
            json!({"target": "drone_0", "plan": {"a": 1}}),
            "/plan",
            "array",
        ),
        ("empty plan", plan(vec![]), "/plan", "empty"),
        ("too many items", plan(many), "/plan", "limit of 1000"),
        (
            "item not an object",
            plan(vec![json!("takeoff")]),
            "/plan/0",
            "an item is an object",
        ),
        (
            "missing behavior",
            plan(vec![json!({"args": {}})]),
            "/plan/0/behavior",
            "missing behavior",
        ),
        (
            "behavior not a string",
            plan(vec![json!({"behavior": 5})]),
            "/plan/0/behavior",
            "must be a string",
        ),
        (
            "unknown behavior",
            plan(vec![json!({"behavior": "fly_to_moon"})]),
            "/plan/0/behavior",
            "unknown behavior `fly_to_moon`",
        ),
        (
            "unknown method",
            plan(vec![json!({"behavior": "land", "method": "crash"})]),
            "/plan/0/method",
            "unknown method `crash`",
        ),
        (
            "method not a string",
            plan(vec![json!({"behavior": "land", "method": 2})]),
            "/plan/0/method",
            "must be a string",
        ),
        (
            "args not an object",
            plan(vec![json!({"behavior": "land", "args": [0.5]})]),
            "/plan/0/args",
            "object of named arguments",
        ),
        (
            "missing argument",
            plan(vec![
                json!({"behavior": "go_to", "args": {"x": 1, "y": 2, "speed": 1}}),
            ]),
            "/plan/0/args/z",
            "missing argument `z`",
        ),
        (
            "mistyped argument",
            plan(vec![
                json!({"behavior": "go_to", "args": {"x": 1, "y": 2, "z": "high", "speed": 1}}),
            ]),
            "/plan/0/args/z",
            "not of type",
        ),
        (
            "unknown argument",
            plan(vec![
                json!({"behavior": "land", "args": {"speed": 1, "sped": 2}}),
            ]),
            "/plan/0/args/sped",
            "unknown argument `sped`",
        ),
        (
            "negative speed",
            plan(vec![json!({"behavior": "land", "args": {"speed": -1}})]),
            "/plan/0/args/speed",
            "positive",
        ),
        (
            "speed above the vehicle limit",
            plan(vec![
                takeoff(),
                json!({"behavior": "go_to", "args": {"x": 1, "y": 2, "z": 3, "speed": 30}}),
            ]),
            "/plan/1/args/speed",
            "limit of 8",
        ),
        (
            "takeoff above the ceiling",
            plan(vec![
                json!({"behavior": "takeoff", "args": {"height": 150, "speed": 1}}),
            ]),
            "/plan/0/args/height",
            "ceiling",
        ),
        (
            "go_to above the ceiling",
            plan(vec![takeoff(), go_to(0.0, 0.0, 121.0)]),
            "/plan/1/args/z",
            "ceiling",
        ),
        (
            "go_to below the floor",
            plan(vec![takeoff(), go_to(0.0, 0.0, -3.0)]),
            "/plan/1/args/z",
            "floor",
        ),
        (
            "go_to outside the radius",
            plan(vec![takeoff(), go_to(900.0, 600.0, 10.0)]),
            "/plan/1/args/x",
            "outside the 1000 m geofence",
        ),
        (
            "go_to_point outside the radius",
            plan(vec![
                takeoff(),
                json!({"behavior": "go_to", "method": "go_to_point", "args": {"point": [0, 2000, 5], "speed": 1}}),
            ]),
            "/plan/1/args/point/0",
            "geofence",
        ),
        (
            "waypoint outside the radius",
            plan(vec![
                takeoff(),
                json!({"behavior": "follow_path", "args": {"path": [[0, 0, 2], [5, 5, 2], [3000, 0, 2]], "speed": 1}}),
            ]),
            "/plan/1/args/path/2",
            "geofence",
        ),
        (
            "gps goal far away",
            plan(vec![
                takeoff(),
                json!({"behavior": "go_to_gps", "args": {"lat": 41.0, "lon": -3.0, "alt": 700.0, "speed": 2}}),
            ]),
            "/plan/1/args/lat",
            "geofence",
        ),
        (
            "too many waypoints",
            plan(vec![
                json!({"behavior": "follow_path", "args": {"path": long_path, "speed": 1}}),
            ]),
            "/plan/0/args/path",
            "limit of 10000",
        ),
        (
            "empty path",
            plan(vec![
                json!({"behavior": "follow_path", "args": {"path": [], "speed": 1}}),
            ]),
            "/plan/0/args/path",
            "at least one waypoint",
        ),
        (
            "unknown frame",
            plan(vec![
                takeoff(),
                json!({"behavior": "go_to", "args": {"x": 1, "y": 0, "z": 3, "speed": 1, "frame_id": "wind_turbine/nacelle"}}),
            ]),
            "/plan/1/args/frame_id",
            "unknown frame `wind_turbine/nacelle`",
        ),
        (
            "gimbal at an unknown frame",
            plan(vec![
                json!({"behavior": "point_gimbal", "args": {"x": 0, "y": 0, "z": 0, "frame_id": "panel_x"}}),
            ]),
            "/plan/0/args/frame_id",
            "unknown frame `panel_x`",
        ),
        (
            "wait as a string",
            plan(vec![json!({"behavior": "land", "args": {"wait": "False"}})]),
            "/plan/0/args/wait",
            "JSON boolean",
        ),
        (
            "bad on_failure",
            plan(vec![
                json!({"behavior": "land", "args": {"on_failure": "ignore"}}),
            ]),
            "/plan/0/args/on_failure",
            "abort",
        ),
        (
            "negative run_for_s",
            plan(vec![
                json!({"behavior": "hover", "args": {"run_for_s": -2}}),
            ]),
            "/plan/0/args/run_for_s",
            "positive",
        ),
        (
            "run_for_s without waiting",
            plan(vec![
                json!({"behavior": "follow_reference", "args": {"x": 0, "y": 0, "z": 2, "frame_id": "earth", "run_for_s": 2}}),
            ]),
            "/plan/0/args/run_for_s",
            "wait: true",
        ),
        (
            "point of two numbers",
            plan(vec![
                json!({"behavior": "go_to", "method": "go_to_point", "args": {"point": [1, 2], "speed": 1}}),
            ]),
            "/plan/0/args/point",
            "[x, y, z]",
        ),
        (
            "with_yaw without angle",
            plan(vec![
                json!({"behavior": "go_to", "method": "go_to_with_yaw", "args": {"x": 1, "y": 2, "z": 3, "speed": 1}}),
            ]),
            "/plan/0/args",
            "needs angle",
        ),
        (
            "fixed yaw without angle",
            plan(vec![
                json!({"behavior": "go_to", "args": {"x": 1, "y": 2, "z": 3, "speed": 1, "yaw_mode": 2}}),
            ]),
            "/plan/0/args/yaw_mode",
            "yaw_angle",
        ),
        (
            "unknown yaw mode",
            plan(vec![
                json!({"behavior": "go_to", "args": {"x": 1, "y": 2, "z": 3, "speed": 1, "yaw_mode": 7}}),
            ]),
            "/plan/0/args/yaw_mode",
            "",
        ),
        (
            "helper given a yaw mode",
            plan(vec![
                json!({"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 1, "y": 2, "z": 3, "speed": 1, "yaw_mode": 0}}),
            ]),
            "/plan/0/args/yaw_mode",
            "sets yaw_mode itself",
        ),
        (
            "rtl too fast",
            plan(vec![
                json!({"behavior": "rtl", "args": {"height": 5, "speed": 50}}),
            ]),
            "/plan/0/args/speed",
            "limit",
        ),
        (
            "zero photos",
            plan(vec![json!({"behavior": "take_photo", "args": {"n": 0}})]),
            "/plan/0/args/n",
            "1..=10000",
        ),
    ]
}

#[test]
fn every_bad_mission_is_rejected_with_a_precise_pointer_and_nothing_is_loaded() {
    let mut rig = Rig::new();
    let cases = cases();
    assert!(cases.len() >= 40);
    for (name, mission, pointer, words) in cases {
        let errors = match rig.host.load_mission(&mission, LoadOptions::default()) {
            Err(HostError::Invalid(errors)) => errors,
            other => panic!("{name}: expected invalid, got {other:?}"),
        };
        assert!(
            errors
                .iter()
                .any(|e| e.pointer == pointer && e.message.contains(words)),
            "{name}: wanted {pointer} with `{words}`, got {errors:?}"
        );
        for e in &errors {
            assert!(
                e.pointer.is_empty() || e.pointer.starts_with('/'),
                "{name}: {e:?}"
            );
        }
    }
    assert!(rig.host.executors()[0].missions().is_empty());
    rig.run_for(1.0);
    assert!(rig.active().is_empty());
    assert!(rig.position()[2] < 0.05);
}

fn context_check(text: &str) -> Result<(), Vec<ValidationError>> {
    let rig = Rig::new();
    let core = &rig.host.cores()[0];
    let limits = Limits::default();
    let ctx = ValidationContext {
        drone_id: "drone_0",
        registry: core.server().registry(),
        limits: &limits,
        frames: core.frames(),
        now: std::time::Duration::ZERO,
        home_enu_m: kestrel::types::Vec3::zeros(),
        geo_origin: core.geo_origin(),
        lowest_height: None,
    };
    validate_text(text, &ctx).map(|_| ())
}

#[test]
fn bad_json_is_rejected_with_line_and_column() {
    for text in [
        "",
        "{",
        "{\"target\": \"drone_0\", \"plan\": [}",
        "nul",
        "{\"target\": 'x'}",
    ] {
        let errors = context_check(text).unwrap_err();
        assert_eq!(errors.len(), 1);
        assert!(
            errors[0].message.contains("not valid JSON"),
            "{text}: {errors:?}"
        );
        assert!(errors[0].message.contains("line"), "{errors:?}");
    }
}

#[test]
fn every_error_of_a_mission_is_listed_at_once() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": -1}},
        {"behavior": "nope"},
        {"behavior": "go_to", "args": {"x": 0, "y": 0, "z": 500, "speed": 99}},
        {"behavior": "land", "args": {"speed": "slow"}}]});
    let Err(HostError::Invalid(errors)) = rig.host.load_mission(&mission, LoadOptions::default())
    else {
        panic!("accepted");
    };
    let pointers: Vec<&str> = errors.iter().map(|e| e.pointer.as_str()).collect();
    for p in [
        "/plan/0/args/height",
        "/plan/1/behavior",
        "/plan/2/args/speed",
        "/plan/2/args/z",
        "/plan/3/args/speed",
    ] {
        assert!(pointers.contains(&p), "{p} missing from {errors:?}");
    }
}

#[test]
fn a_polygon_geofence_rejects_points_outside_it() {
    let mut config = Config::default();
    config.geofence.polygon_enu_m = Some(vec![
        [-10.0, -10.0],
        [20.0, -10.0],
        [20.0, 20.0],
        [-10.0, 20.0],
    ]);
    let mut rig = Rig::with_config(config, 1);
    assert!(rig
        .host
        .load_mission(
            &plan(vec![takeoff(), go_to(15.0, 15.0, 5.0)]),
            LoadOptions::default()
        )
        .is_ok());
    let Err(HostError::Invalid(errors)) = rig.host.load_mission(
        &plan(vec![takeoff(), go_to(25.0, 0.0, 5.0)]),
        LoadOptions::default(),
    ) else {
        panic!("accepted");
    };
    assert_eq!(errors[0].pointer, "/plan/1/args/x");
    assert!(errors[0].message.contains("polygon"));
}

/// A vehicle whose height estimate may be off by 1.5 m (a barometer's, as PX4's and
/// ArduPilot's profiles say) is never sent below 2.0 m: not by a height given, a default, or a
/// point; landing is still allowed. Where the height is exact (the simulator) nothing changes.
#[test]
fn nothing_flies_below_the_height_the_vehicles_height_error_leaves() {
    let mut config = Config::default();
    config.safety.height_error_m = Some(1.5);
    let mut rig = Rig::with_config(config, 1);
    let low = plan(vec![
        json!({"behavior": "takeoff", "args": {"speed": 1.0}}),
        json!({"behavior": "explore", "args": {"height": 1.5}}),
        go_to(3.0, 0.0, 1.0),
        json!({"behavior": "land", "args": {}}),
    ]);
    let Err(HostError::Invalid(errors)) = rig.host.load_mission(&low, LoadOptions::default())
    else {
        panic!("accepted");
    };
    let found = |pointer: &str, words: &str| {
        errors
            .iter()
            .any(|e| e.pointer == pointer && e.message.contains(words))
    };
    assert_eq!(errors.len(), 3, "{errors:?}");
    assert!(
        found("/plan/0/args", "height 1 m (the default)"),
        "{errors:?}"
    );
    assert!(found("/plan/1/args/height", "height = 1.5 m"), "{errors:?}");
    assert!(found("/plan/2/args/z", "1.0 m above home"), "{errors:?}");
    for e in &errors {
        assert!(
            e.message.contains("lowest flight height of 2.0 m")
                && e.message.contains("off by 1.5 m")
                && e.message.contains("height_error_m"),
            "{e:?}"
        );
    }
    assert!(rig.host.executors()[0].missions().is_empty());
    let high = plan(vec![
        json!({"behavior": "takeoff", "args": {"height": 2.0}}),
        json!({"behavior": "explore", "args": {"height": 2.5}}),
        go_to(3.0, 0.0, 2.0),
        json!({"behavior": "rtl", "args": {"height": 3.0, "speed": 1.0}}),
    ]);
    rig.host
        .load_mission(&high, LoadOptions::default())
        .expect("at and above the lowest flight height");

    let mut exact = Rig::new();
    exact
        .host
        .load_mission(&low, LoadOptions::default())
        .expect("the simulator's height is exact");
}

#[test]
fn an_aerostack2_mission_loads_unchanged_with_warnings_for_unknown_fields() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "verbose": true, "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0, "wait": true}},
        {"behavior": "go_to", "method": "go_to_point_path_facing", "args": {"point": [2.0, 2.0, 2.0], "speed": 1.0}},
        {"behavior": "follow_path", "args": {"path": [[0, 0, 2], [2, 0, 2]], "speed": 1.0, "yaw_mode": 1, "frame_id": "earth"}},
        {"behavior": "land", "method": "__call__", "args": {"speed": 0.5}, "note": "x"}]});
    let up = rig
        .host
        .load_mission(&mission, LoadOptions::default())
        .unwrap();
    assert_eq!(up.warnings.len(), 2, "{:?}", up.warnings);
    assert!(up.warnings[0].contains("verbose"));
}

#[test]
fn frames_registered_over_the_api_make_a_mission_valid() {
    let mut rig = Rig::new();
    let m = plan(vec![
        takeoff(),
        json!({"behavior": "go_to", "args": {"x": -10, "y": 0, "z": 0, "speed": 1, "frame_id": "wind_turbine/nacelle"}}),
    ]);
    assert!(rig.host.load_mission(&m, LoadOptions::default()).is_err());
    rig.host
        .set_frame(serde_json::from_value(json!({"frame_id": "wind_turbine/nacelle", "translation_m": [40, 0, 30], "yaw_rate_radps": 0.01})).unwrap())
        .unwrap();
    assert!(rig.host.load_mission(&m, LoadOptions::default()).is_ok());
}

/// Issue 29, item 10c: `POST /api/missions` for a drone another Kestrel of the fleet flies
/// answered `422 invalid_mission` instead of the documented `409 remote_drone`.
#[test]
fn a_mission_for_a_remote_drone_is_refused_as_remote_not_invalid() {
    use kestrel::api::error::ApiError;
    use kestrel::fleet_bus::remote::SilencePolicy;
    use kestrel::fleet_bus::wire::{DroneState, StateMsg, WIRE_VERSION};
    use std::time::Duration;

    let mut rig = Rig::new();
    rig.host.enable_fleet_bus(
        SilencePolicy {
            peer_timeout: Duration::from_secs(3),
            lost_after: Duration::from_secs(10),
            keepout_m: 2.0,
        },
        [("kestrel-b".to_string(), vec!["drone_7".to_string()])].into(),
    );
    let drone = DroneState::at_rest("drone_7", [5.0, 0.0, 0.0], false);
    let refused = rig.host.apply_bus_state(StateMsg {
        v: WIRE_VERSION,
        node: "kestrel-b".into(),
        seq: 0,
        sent_unix_us: 0,
        drones: vec![drone],
    });
    assert!(refused.is_empty(), "{refused:?}");
    let mut mission = plan(vec![takeoff()]);
    mission["target"] = json!("drone_7");
    let answers = [
        rig.host.load_context(Some("drone_7")).map(|_| ()),
        rig.host
            .load_mission(&mission, LoadOptions::default())
            .map(|_| ()),
    ];
    for answer in answers {
        let e = answer.unwrap_err();
        assert!(
            matches!(&e, HostError::RemoteDrone { node, .. } if node == "kestrel-b"),
            "{e:?}"
        );
        let (status, code) = ApiError::from(e).status_and_code();
        assert_eq!((status.as_u16(), code), (409, "remote_drone"));
    }
    // A drone no Kestrel flies is still an error of the mission, at its target.
    let unknown = rig.host.load_context(Some("drone_9")).map(|_| ());
    assert!(
        matches!(&unknown, Err(HostError::Invalid(e)) if e[0].pointer == "/target"),
        "{unknown:?}"
    );
    assert!(
        rig.host.executors()[0].missions().is_empty(),
        "nothing was loaded"
    );
}
