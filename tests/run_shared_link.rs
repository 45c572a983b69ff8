//! Several vehicles behind one connection: one `kestrel run` flies two fake PX4 autopilots
//! (`sitl/`, system ids 1 and 2) that it reaches through one UDP endpoint, as behind
//! mavlink-router or a telemetry radio (a router in this test copies datagrams between the
//! vehicles and Kestrel's one `udpin` port). The config lists both vehicles on that connection,
//! each with its autopilot's `target_system`. Each flies its own mission (take off, go to a
//! point, land) at the same time; judged on the fakes' true states: each reached its own
//! targets, and neither moved for the other's commands.
//! Needs `sitl/.venv` (`bash sitl/setup.sh`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::router::UdpRouter;
use mavlink_support::{serial, vehicle_section, wait_fleet_ready, Api, Fake, Kestrel, LISTEN_ANY};
use serde_json::{json, Value};
use std::time::{Duration, Instant};
use support::free_udp_port;

const DRONES: [&str; 2] = ["drone_0", "drone_1"];
/// Where the fake starts its vehicles without a world: a row 3 m apart (ENU, m).
const STARTS_ENU_M: [[f64; 3]; 2] = [[0.0, 0.0, 0.0], [3.0, 0.0, 0.0]];
/// Each vehicle's go_to target in the shared frame (m): they cross the x axis apart.
const TARGETS_ENU_M: [[f64; 3]; 2] = [[-1.0, 4.0, 2.0], [5.0, -3.0, 2.5]];

fn config(connection: &str) -> String {
    let mut text = "[mavlink]\nplatform = \"platforms/px4.toml\"\n".to_string();
    for (i, origin) in STARTS_ENU_M.iter().enumerate() {
        text.push_str(&vehicle_section(DRONES[i], connection, i + 1, *origin));
    }
    text
}

fn mission(drone: &str, target: [f64; 3]) -> Value {
    json!({
        "target": drone,
        "plan": [
            {"behavior": "takeoff", "args": {"height": target[2], "speed": 1.0}},
            {"behavior": "go_to", "args": {"x": target[0], "y": target[1], "z": target[2], "speed": 1.0}},
            {"behavior": "land", "args": {"speed": 0.5}}
        ]
    })
}

/// The mission state of `drone` in `GET /api/status`.
fn mission_of(api: &Api, drone: &str) -> Value {
    let status = api.get("/api/status");
    status["drones"]
        .as_array()
        .and_then(|d| d.iter().find(|d| d["drone"] == drone))
        .map(|d| d["mission"].clone())
        .unwrap_or(Value::Null)
}

#[test]
fn two_px4_behind_one_connection_each_fly_their_own_mission() {
    let _alone = serial();
    let (fake, vehicle_connections) = Fake::start_px4_fleet(DRONES.len() as u16, &[]);
    let kestrel_port = free_udp_port();
    let router = UdpRouter::start(&vehicle_connections, kestrel_port);
    let kestrel = Kestrel::run_config(
        &config(&format!("udpin:127.0.0.1:{kestrel_port}")),
        &["--listen", LISTEN_ANY],
    );
    let api = kestrel.api();
    // Each drone shows its own autopilot: where that one stands.
    let status = wait_fleet_ready(&api, &kestrel, DRONES.len());
    for (drone, start) in DRONES.iter().zip(STARTS_ENU_M) {
        let d = status["drones"]
            .as_array()
            .and_then(|d| d.iter().find(|d| d["drone"] == *drone))
            .unwrap_or_else(|| panic!("{drone} not listed: {status}"));
        let p = &d["position_enu_m"];
        let at = [p[0].as_f64().unwrap(), p[1].as_f64().unwrap()];
        assert!(
            (at[0] - start[0]).abs() < 0.2 && (at[1] - start[1]).abs() < 0.2,
            "{drone} at {at:?}, expected {start:?}: {d}"
        );
    }
    let poller = fake.poll_fleet_states(DRONES.len());

    for (drone, target) in DRONES.iter().zip(TARGETS_ENU_M) {
        let (code, up) = api.post("/api/missions", &mission(drone, target));
        assert_eq!(code, 201, "{up}");
        let start = json!({"drone_id": drone, "mission_id": up["mission_id"], "action": "START"});
        let (code, started) = api.post("/api/mission_update", &start);
        assert_eq!(code, 200, "{started}");
    }
    let deadline = Instant::now() + Duration::from_secs(90);
    loop {
        let ended = DRONES.iter().all(|d| {
            mission_of(&api, d)["state"] == 0 && mission_of(&api, d)["mission_id"].is_u64()
        });
        let landed = (0..DRONES.len()).all(|i| fake.state_of(i)["on_ground"] == true);
        if ended && landed {
            break;
        }
        assert!(
            Instant::now() < deadline,
            "missions not over: {} {}\n{}\n{}",
            mission_of(&api, DRONES[0]),
            mission_of(&api, DRONES[1]),
            fake.diagnostics(),
            kestrel.output()
        );
        std::thread::sleep(Duration::from_millis(250));
    }
    let samples = poller.finish();

    for (i, target) in TARGETS_ENU_M.iter().enumerate() {
        let track: Vec<[f64; 3]> = samples
            .iter()
            .filter_map(|s| s[i]["position_enu_m"].as_array().cloned())
            .map(|p| std::array::from_fn(|k| p[k].as_f64().unwrap()))
            .collect();
        let closest = track
            .iter()
            .map(|p| {
                ((p[0] - target[0]).powi(2)
                    + (p[1] - target[1]).powi(2)
                    + (p[2] - target[2]).powi(2))
                .sqrt()
            })
            .fold(f64::INFINITY, f64::min);
        assert!(
            closest < 0.3,
            "{} came only within {closest:.2} m of {target:?}\n{}",
            DRONES[i],
            kestrel.output()
        );
        // Landed near its target, not where the other was sent.
        let last = track.last().unwrap();
        let off = ((last[0] - target[0]).powi(2) + (last[1] - target[1]).powi(2)).sqrt();
        assert!(off < 0.5, "{} landed {off:.2} m from its target", DRONES[i]);
        let outcome = mission_of(&api, DRONES[i]);
        assert!(outcome["last_error"].is_null(), "{}: {outcome}", DRONES[i]);
        assert_eq!(outcome["pending_items"], 0, "{}: {outcome}", DRONES[i]);
    }
    let (from_vehicles, from_kestrel) = *router.counts.lock().unwrap();
    assert!(from_vehicles > 0 && from_kestrel > 0);
}
