//! A fleet on `kestrel run`: one real process flies three fake PX4 autopilots (`sitl/`, one
//! process, one world, each vehicle on its own UDP ports with its own system id) from a
//! `[[vehicle]]` config, through a three-drone exploration of a walled 10 x 10 m room with five
//! poles, mapping with each autopilot's four range beams, started over the API like an operator
//! would (`POST /api/exploration/start`), until no frontier is left and all three have landed.
//!
//! Each fake's local frame starts where it was switched on (PX4 counts from its EKF origin), so
//! the config says where each origin lies in the room: a frame error there puts one drone's walls
//! where there are none, which the map check catches. Judged on the merged map from the API
//! (known share of the floor, obstacle cells on true obstacles) and on the fakes' true states
//! (clearance to obstacles, no collision logged, the drones never closer than 0.5 m).
//! Needs `sitl/.venv` (`bash sitl/setup.sh`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use kestrel::sim::world::World;
use mavlink_support::room::{
    assert_no_collision, judge_map, judge_tracks, wait_explored, MIN_SEPARATION_M,
};
use mavlink_support::{repo, serial, vehicle_section, wait_fleet_ready, Fake, Kestrel, LISTEN_ANY};
use serde_json::json;
use std::time::{Duration, Instant};

const WORLD: &str = "sitl/worlds/room10_fleet.json";
const DRONES: [&str; 3] = ["drone_0", "drone_1", "drone_2"];
/// Where the fake starts each vehicle (the world's `starts_xy_yaw` for three, m, ENU).
const STARTS_ENU_M: [[f64; 3]; 3] = [[-3.0, 0.0, 0.0], [0.0, 0.0, 0.0], [3.0, 1.0, 0.0]];

/// The fleet's config: the room's map and the three autopilots, each with its connection, system id and frame origin.
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
fn three_px4_explore_a_room_together_from_one_kestrel_run() {
    let _alone = serial();
    let w = World::load(&repo().join(WORLD)).unwrap();
    let world_path = repo().join(WORLD);
    let (fake, connections) = Fake::start_px4_fleet(
        DRONES.len() as u16,
        &["--world", world_path.to_str().unwrap(), "--rangers", "cf4"],
    );
    // The config's origins are where the fake switched each vehicle on.
    for (i, start) in STARTS_ENU_M.iter().enumerate() {
        let s = fake.state_of(i);
        assert_eq!(s["sysid"], i + 1, "{s}");
        let o = &s["local_origin_enu_m"];
        let o = [0, 1].map(|k| o[k].as_f64().unwrap());
        assert!(
            (o[0] - start[0]).abs() < 1e-6 && (o[1] - start[1]).abs() < 1e-6,
            "{s}"
        );
    }
    let poller = fake.poll_fleet_states(DRONES.len());
    let kestrel = Kestrel::run_config(&config(&connections), &["--listen", LISTEN_ANY]);
    let api = kestrel.api();

    // The API shows the whole fleet, each drone where its autopilot stands in the room.
    let status = wait_fleet_ready(&api, &kestrel, DRONES.len());
    let drones = status["drones"].as_array().unwrap();
    let ids: Vec<&str> = drones
        .iter()
        .map(|d| d["drone"].as_str().unwrap())
        .collect();
    assert_eq!(ids, DRONES, "{status}");
    for (d, start) in drones.iter().zip(STARTS_ENU_M) {
        let p = &d["position_enu_m"];
        let at = [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()];
        assert!(
            (at[0] - start[0]).abs() < 0.2 && (at[1] - start[1]).abs() < 0.2,
            "{} at {at:?}, expected {start:?}: {d}",
            d["drone"]
        );
    }

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
    let samples = poller.finish();
    let out = kestrel.output();
    println!("explored in {took:?}: {view}");

    // Every drone's part succeeded; every vehicle has landed and disarmed.
    let parts = view["progress"]["drones"].as_array().unwrap();
    assert_eq!(parts.len(), DRONES.len(), "{view}");
    for part in parts {
        assert_eq!(part["phase"], "succeeded", "{view}\n{out}");
    }
    for i in 0..DRONES.len() {
        let end = fake.state_of(i);
        assert_eq!(
            (end["armed"].clone(), end["on_ground"].clone()),
            (json!(false), json!(true)),
            "vehicle {i}: {end}"
        );
    }

    // The merged map of the three: most of the floor known, every obstacle cell on a true
    // obstacle (a wrong frame origin puts one drone's walls inside the room).
    let map = api.get("/api/map");
    let (known_pct, stray) = judge_map(&map, &w, 0.3);
    assert!(known_pct >= 95.0, "{known_pct:.1} % of the floor known");
    assert!(
        stray.len() <= 10,
        "{} obstacle cells off every true obstacle: {:?}",
        stray.len(),
        stray.iter().take(10).collect::<Vec<_>>()
    );

    // The true flights: every vehicle flew, none closer than 0.2 m to an obstacle, no
    // collision logged, and no two ever closer than MIN_SEPARATION_M.
    let tracks = judge_tracks(&samples, &w);
    assert!(
        tracks.airborne.iter().all(|&n| n > 100),
        "airborne samples per vehicle: {:?}",
        tracks.airborne
    );
    tracks.assert_safe(&samples, 0.2, MIN_SEPARATION_M);
    assert_no_collision(&fake, DRONES.len());
    println!(
        "floor known {known_pct:.1} %, {} stray obstacle cells, closest to an obstacle {:.2} m, \
         closest two drones {:.2} m, airborne samples {:?}",
        stray.len(),
        tracks.clearance.m,
        tracks.closest_pair.0,
        tracks.airborne
    );
}
