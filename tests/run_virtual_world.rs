//! Exploration on autopilots without simulated sensors: three fake PX4 (`sitl/`, one process,
//! each vehicle on its own UDP ports with its own system id) that send no range readings at all
//! (`--rangers none`), flown by one `kestrel run --virtual-world` through a three-drone
//! exploration of the walled 10 x 10 m room with five poles: every beam the drones map comes
//! from the virtual world, cast from the pose each autopilot reports, in the shared frame
//! (each autopilot's local frame starts where it was switched on: the config's `origin_enu_m`).
//! Started over the API (`POST /api/exploration/start`) until no frontier is left and all three
//! have landed; what PX4 SITL without Gazebo flies.
//!
//! The fakes fly in the same room (it places them and logs their true collisions, their beams
//! are off), so the run is judged on both sides: the exploration report (known area, and the
//! evaluator's metrics against the virtual world, which `kestrel run` keeps as the truth), no
//! `virtual_collision` in any mission, no collision in the fakes' logs, the drones landed and
//! disarmed. Needs `sitl/.venv` (`bash sitl/setup.sh`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use kestrel::sim::world::World;
use mavlink_support::room::{assert_no_collision, judge_map, wait_explored};
use mavlink_support::{repo, serial, vehicle_section, wait_fleet_ready, Fake, Kestrel, LISTEN_ANY};
use serde_json::json;
use std::time::{Duration, Instant};

const WORLD: &str = "sitl/worlds/room10_fleet.json";
const DRONES: [&str; 3] = ["drone_0", "drone_1", "drone_2"];
/// Where the fake starts each vehicle (the world's `starts_xy_yaw` for three, m, ENU).
const STARTS_ENU_M: [[f64; 3]; 3] = [[-3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 1.0, 0.0]];

/// The fleet's config as tests/run_fleet.rs: a 12 m map (framed on the virtual world's centre),
/// the three autopilots with their connections, system ids and frame
/// origins.
fn config(connections: &[String]) -> String {
    let mut text = "[map]\nsize_m = [12.0, 12.0]\n\n\
                    [mavlink]\nplatform = \"platforms/px4.toml\"\n"
        .to_string();
    for (i, (connection, origin)) in connections.iter().zip(STARTS_ENU_M).enumerate() {
        text.push_str(&vehicle_section(DRONES[i], connection, i + 1, origin));
    }
    text
}

#[test]
fn three_px4_without_range_sensors_explore_a_virtual_room() {
    let _alone = serial();
    let world_path = repo().join(WORLD);
    let w = World::load(&world_path).unwrap();
    let (fake, connections) = Fake::start_px4_fleet(
        DRONES.len() as u16,
        &["--world", world_path.to_str().unwrap(), "--rangers", "none"],
    );
    let kestrel = Kestrel::run_config(
        &config(&connections),
        &["--listen", LISTEN_ANY, "--virtual-world", WORLD],
    );
    let api = kestrel.api();
    wait_fleet_ready(&api, &kestrel, DRONES.len());
    assert!(
        kestrel.line_at("virtual world").is_some(),
        "{}",
        kestrel.output()
    );

    let started_at = Instant::now();
    let (code, started) = api.post(
        "/api/exploration/start",
        &json!({"drones": DRONES, "args": {"height": 2.0, "spin_rate": 0.4, "safety_distance": 0.5}}),
    );
    assert_eq!(code, 200, "{started}");
    let view = wait_explored(&api, &kestrel, &fake);
    let took = started_at.elapsed();
    // Let the last touchdown's disarm reach the fake.
    std::thread::sleep(Duration::from_secs(1));
    let out = kestrel.output();
    println!("explored in {took:?}: {view}");

    // Every drone's part succeeded, none hit a virtual obstacle; all landed and disarmed.
    let parts = view["progress"]["drones"].as_array().unwrap();
    assert_eq!(parts.len(), DRONES.len(), "{view}");
    for part in parts {
        assert_eq!(part["phase"], "succeeded", "{view}\n{out}");
    }
    let status = api.get("/api/status");
    for d in status["drones"].as_array().unwrap() {
        let m = &d["mission"];
        assert!(m["last_error"].is_null(), "{}: {m}", d["drone"]);
    }
    assert!(!out.contains("virtual_collision"), "{out}");
    for i in 0..DRONES.len() {
        let end = fake.state_of(i);
        assert_eq!(
            (end["armed"].clone(), end["on_ground"].clone()),
            (json!(false), json!(true)),
            "vehicle {i}: {end}"
        );
    }
    assert_no_collision(&fake, DRONES.len());

    // The report: the map known but for what lies beyond the walls (the room is 10.4 m of the
    // 12 m map, its walls 0.2 m thick), and the evaluator's metrics against the virtual world
    // (the observable floor seen, no collision).
    let report = api.get("/api/exploration/report");
    let known = report["known_pct"].as_f64().unwrap();
    assert!(known >= 60.0, "{known:.1} % of the map known: {report}");
    let eval = &report["evaluation"];
    assert!(report["evaluation_error"].is_null(), "{report}");
    let observable = eval["observable_pct"].as_f64().unwrap();
    assert!(observable >= 90.0, "{observable:.1} % observable: {eval}");
    assert_eq!(eval["collisions"], 0, "{eval}");

    // The merged map has the room where it is: the walls and poles in the shared frame.
    let map = api.get("/api/map");
    let (floor_pct, stray) = judge_map(&map, &w, 0.3);
    println!(
        "{floor_pct:.1} % of the floor known, {} stray cells",
        stray.len()
    );
    assert!(floor_pct >= 95.0, "{floor_pct:.1} % of the floor known");
    assert!(
        stray.len() <= 10,
        "{} obstacle cells off every true obstacle: {:?}",
        stray.len(),
        stray.iter().take(10).collect::<Vec<_>>()
    );
    println!(
        "known {known:.1} % of the map, {floor_pct:.1} % of the floor, observable {observable:.1} %, \
         {} stray obstacle cells",
        stray.len()
    );
}
