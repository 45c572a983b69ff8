//! Issue 29, item 3, over MAVLink: a land sent while the fleet is held for a lost peer sets the
//! drone down on the fake ArduPilot (its LAND mode) and on the fake PX4 flown down on Kestrel's
//! own setpoints (`land = "setpoints"`, the safety stage's hold in the way). Two Kestrels, two
//! fake vehicles in one world; node_1 is killed with its drone in the air. (The fake PX4 with
//! its AUTO.LAND is tests/fleet_bus_e2e.rs.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::bus::{start_ardupilot_fleet, Fleet, BAYS};
use mavlink_support::{alongside, repo, Fake};
use serde_json::json;
use std::time::{Duration, Instant};

/// Both drones up and on their way across their bays; node_1 killed; once node_0 hears drone_1
/// silent, a land sent to node_0 must set drone_0 down.
fn lands_through_the_hold(fake: &Fake, mut fleet: Fleet) {
    fleet.wait_joined(&[0, 1]);
    for (i, [x, y]) in [(0, [-4.5, 1.0]), (1, [1.5, 2.0])] {
        let drone = format!("drone_{i}");
        let plan = json!([
            {"behavior": "takeoff", "args": {"height": 2.0, "speed": 0.5}},
            {"behavior": "go_to", "args": {"x": x, "y": y, "z": 2.0, "speed": 0.1}}
        ]);
        let update = json!({"drone_id": drone, "action": 0,
            "mission": {"target": drone, "plan": plan}});
        let (code, answer) = fleet.apis[i].post("/api/mission_update", &update);
        assert_eq!(code, 200, "node_{i}: {answer}");
    }
    let on_the_way = |i: usize| {
        let d = fleet.apis[i].get("/api/status")["drones"][0].clone();
        d["flight"] == "flying" && d["mission"]["current_item"]["behavior"] == "go_to"
    };
    let deadline = Instant::now() + Duration::from_secs(90);
    while !(on_the_way(0) && on_the_way(1)) {
        assert!(Instant::now() < deadline, "not both up\n{}", fleet.output());
        std::thread::sleep(Duration::from_millis(250));
    }
    drop(fleet.nodes[1].take());
    let silent = || {
        fleet.apis[0].get("/api/status")["remote"]
            .as_array()
            .is_some_and(|r| {
                r.iter()
                    .any(|d| d["id"] == "drone_1" && d["silent"] == true)
            })
    };
    let deadline = Instant::now() + Duration::from_secs(20);
    while !silent() {
        assert!(
            Instant::now() < deadline,
            "drone_1 never silent\n{}",
            fleet.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    // Held a moment (the safety stage's hold is on), then landed.
    std::thread::sleep(Duration::from_secs(2));
    let held = fake.state_of(0);
    assert_eq!(held["on_ground"], false, "still held in the air: {held}");
    let land = json!({
        "drone_id": "drone_0", "action": 0,
        "mission": {"target": "drone_0", "plan": [{"behavior": "land", "args": {"speed": 0.5}}]}
    });
    let (code, answer) = fleet.apis[0].post("/api/mission_update", &land);
    assert_eq!(code, 200, "{answer}");
    let started = Instant::now();
    while fake.state_of(0)["on_ground"] != true {
        assert!(
            started.elapsed() < Duration::from_secs(60),
            "not landed through the hold: {}\n{}",
            fake.state_of(0),
            fleet.output()
        );
        std::thread::sleep(Duration::from_millis(250));
    }
    println!(
        "landed in {:.1} s while held",
        started.elapsed().as_secs_f64()
    );
}

#[test]
fn land_gets_through_the_hold_on_the_fake_ardupilot() {
    let _beside = alongside();
    let world = repo().join(BAYS.world);
    let (fake, connections) = start_ardupilot_fleet(2, &["--world", world.to_str().unwrap()]);
    let fleet = Fleet::start_on(&BAYS, &connections, "platforms/ardupilot-copter.toml");
    lands_through_the_hold(&fake, fleet);
}

#[test]
fn land_on_setpoints_gets_through_the_hold_on_the_fake_px4() {
    let _beside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let profile = std::fs::read_to_string(repo().join("platforms/px4.toml")).unwrap();
    let on_setpoints = profile.replace("\nland = \"mode\"", "\nland = \"setpoints\"");
    assert_ne!(
        on_setpoints, profile,
        "platforms/px4.toml no longer says land = \"mode\""
    );
    let platform = dir.path().join("px4-land-on-setpoints.toml");
    std::fs::write(&platform, on_setpoints).unwrap();
    let world = repo().join(BAYS.world);
    let (fake, connections) = Fake::start_px4_fleet(2, &["--world", world.to_str().unwrap()]);
    let fleet = Fleet::start_on(&BAYS, &connections, platform.to_str().unwrap());
    lands_through_the_hold(&fake, fleet);
}
