#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The missions shipped in missions/: the schema is current, every mission matches it and
//! validates, and each thesis scenario flies to its end in the simulator.

mod mission_rig;

use kestrel::mission::schema::mission_schema;
use kestrel::mission::{Action, ItemResult};
use kestrel::scenario::file::Scenario;
use kestrel::scenario::SimulatedHost;
use kestrel::types::Vec3;
use mission_rig::Rig;
use serde_json::Value;
use std::path::{Path, PathBuf};

fn dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("missions")
}

fn read(path: &Path) -> Value {
    serde_json::from_str(&std::fs::read_to_string(path).unwrap()).unwrap()
}

fn missions() -> Vec<PathBuf> {
    let mut out: Vec<PathBuf> = std::fs::read_dir(dir())
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "json") && !p.ends_with("schema.json"))
        .collect();
    out.sort();
    out
}

/// `missions/demo.json` is the demo flight `kestrel sim` flies with one drone (from the origin,
/// facing east); the simulator places the same plan per drone from each start pose.
#[test]
fn the_demo_mission_file_is_the_demo_the_simulator_flies() {
    let config = kestrel::config::Config::default();
    let host =
        kestrel::scenario::simulated_host(kestrel::sim::world::World::empty(), 1, 0, &config);
    let flown = kestrel::scenario::demo::demo_missions(host.sim_world().unwrap());
    let on_disk = read(&dir().join("demo.json"));
    if std::env::var_os("KESTREL_WRITE_DEMO").is_some() {
        std::fs::write(
            dir().join("demo.json"),
            serde_json::to_string_pretty(&flown[0]).unwrap() + "\n",
        )
        .unwrap();
    }
    assert_eq!(
        flown[0], on_disk,
        "missions/demo.json is stale: rerun this test with KESTREL_WRITE_DEMO=1"
    );
}

#[test]
fn the_schema_file_is_generated_from_this_build() {
    let generated = mission_schema(&kestrel::behavior::payload::registry());
    let on_disk = read(&dir().join("schema.json"));
    assert!(
        generated == on_disk,
        "missions/schema.json is stale: run `kestrel mission schema > missions/schema.json`"
    );
}

#[test]
fn every_shipped_mission_matches_the_schema_and_a_broken_one_does_not() {
    let schema = read(&dir().join("schema.json"));
    let validator = jsonschema::validator_for(&schema).unwrap();
    assert_eq!(missions().len(), 6);
    for m in missions() {
        let errors: Vec<String> = validator
            .iter_errors(&read(&m))
            .map(|e| e.to_string())
            .collect();
        assert!(errors.is_empty(), "{}: {errors:?}", m.display());
    }
    let broken = serde_json::json!({"target": "drone_0", "plan": [
        {"behavior": "go_to", "args": {"x": 1, "y": 2, "z": "up", "speed": 1}}]});
    assert!(!validator.is_valid(&broken));
    let aerostack2 = serde_json::json!({"target": "drone_0", "verbose": true, "plan": [
        {"behavior": "follow_path", "args": {"path": [[0, 0, 1]], "speed": 1, "yaw_mode": 1, "wait": true}}]});
    assert!(validator.is_valid(&aerostack2));
}

/// Flies a scenario (or a bare mission) to its end; returns the rig.
fn fly(scenario: Option<&str>, mission: &str) -> Rig {
    let mut rig = Rig::new();
    if let Some(s) = scenario {
        for f in Scenario::load(&dir().join("scenarios").join(s))
            .unwrap()
            .frames
        {
            rig.host.set_frame(f).unwrap();
        }
    }
    rig.execute(1, read(&dir().join(mission)));
    assert!(
        rig.run_until(600.0, |r| r.is_idle()),
        "{mission} did not end"
    );
    let s = rig.status();
    assert_eq!(s.last_error, None, "{mission}: {s:?}");
    assert!(
        rig.position()[2] < 0.1,
        "{mission} did not land: {:?}",
        rig.position()
    );
    rig
}

#[test]
fn takeoff_go_land_flies() {
    let rig = fly(None, "takeoff_go_land.json");
    assert_eq!(rig.started(), ["takeoff", "go_to", "land"]);
    assert!(rig.near(0.0, 5.0, 0.0, 0.3));
}

#[test]
fn wind_turbine_inspection_follows_the_yawing_nacelle() {
    let mut rig = Rig::new();
    let scenario = Scenario::load(&dir().join("scenarios/wind_turbine.json")).unwrap();
    assert!(scenario.frames[0].yaw_rate_radps > 0.0);
    for f in scenario.frames {
        rig.host.set_frame(f).unwrap();
    }
    rig.execute(1, read(&dir().join("wind_turbine_frontal.json")));
    let nacelle = "wind_turbine/nacelle";
    let mut checked = Vec::new();
    // At the end of each follow_reference item (4, 6, .. 12), the drone is at the inspection
    // point of the nacelle as it is then, not as it was at takeoff. The take_photo items
    // between them do not wait, so the next current item is two further on.
    for item in [4usize, 6, 8, 10, 12] {
        let next = if item == 12 { 13 } else { item + 2 };
        assert!(rig.run_until(120.0, |r| r.at_item(next)), "item {item}");
        let core = &rig.host.cores()[0];
        let z = [0.0, 5.0, 10.0, 15.0, 20.0][(item - 4) / 2];
        let now = rig.host.now();
        let target = core
            .frames()
            .point_to_earth(&Vec3::new(15.0, 0.0, z), nacelle, now)
            .unwrap();
        let p = rig.position();
        let error = (Vec3::new(p[0], p[1], p[2]) - target).norm();
        assert!(
            error < 0.6,
            "item {item}: {error:.2} m from the moving inspection point"
        );
        checked.push(target);
    }
    let drift = (checked[4].xy() - checked[0].xy()).norm();
    assert!(drift > 1.0, "the nacelle should have yawed: {drift:.2} m");
    assert!(rig.run_until(300.0, |r| r.is_idle()));
    let s = rig.status();
    assert_eq!(s.last_error, None);
    let photos = s
        .done_results
        .iter()
        .filter(|d| d.behavior == "take_photo")
        .count();
    assert_eq!(photos, 5);
}

#[test]
fn solar_park_coverage_points_the_gimbal_while_following_the_path() {
    let rig = fly(Some("solar_park.json"), "solar_park_coverage.json");
    assert_eq!(
        rig.started(),
        [
            "takeoff",
            "go_to",
            "point_gimbal",
            "go_to",
            "follow_path",
            "rtl"
        ]
    );
    let s = rig.status();
    let gimbal = s
        .done_results
        .iter()
        .find(|d| d.behavior == "point_gimbal")
        .unwrap();
    assert_eq!(
        gimbal.result,
        ItemResult::Stopped,
        "ran in parallel until the end"
    );
    assert!(rig.near(0.0, 0.0, 0.0, 0.3), "{:?}", rig.position());
}

#[test]
fn panel_inspection_flies_relative_to_the_panel_frame() {
    let mut rig = Rig::new();
    for f in Scenario::load(&dir().join("scenarios/panel_inspection.json"))
        .unwrap()
        .frames
    {
        rig.host.set_frame(f).unwrap();
    }
    rig.execute(1, read(&dir().join("panel_inspection.json")));
    assert!(rig.run_until(120.0, |r| r.at_item(4)));
    // 2.5 m above the panel, which is 1 m up at (12, -8).
    assert!(rig.near(12.0, -8.0, 3.5, 0.3), "{:?}", rig.position());
    assert!(rig.run_until(200.0, |r| r.is_idle()));
    assert_eq!(rig.status().last_error, None);
}

#[test]
fn an_on_demand_inspection_takes_over_the_coverage() {
    let mut rig = Rig::new();
    for s in ["solar_park.json", "panel_inspection.json"] {
        for f in Scenario::load(&dir().join("scenarios").join(s))
            .unwrap()
            .frames
        {
            rig.host.set_frame(f).unwrap();
        }
    }
    rig.execute(1, read(&dir().join("solar_park_coverage.json")));
    assert!(rig.run_until(120.0, |r| r.at_item(4)));
    let mut inspection = read(&dir().join("panel_inspection.json"));
    // Already flying: the on-demand plan starts at its first go_to.
    inspection["plan"].as_array_mut().unwrap().remove(0);
    rig.send(Action::Load, Some(2), None, Some(inspection))
        .unwrap();
    rig.send(Action::Start, Some(2), None, None).unwrap();
    assert!(rig.run_until(200.0, |r| r.is_idle()));
    let s = rig.status();
    assert_eq!(
        (s.mission_id, s.last_error.clone()),
        (Some(2), None),
        "{s:?}"
    );
    assert!(rig.near(0.0, 0.0, 0.0, 0.3));
}
