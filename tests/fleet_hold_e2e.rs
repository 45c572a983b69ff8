//! Issue 29, item 3: land (and an operator's stop) get through the hold for a lost peer on the
//! simulator platform, where Kestrel flies the descent on its own setpoints. Two
//! `kestrel run --platform sim` nodes on one bus: node_1 is killed with its drone in the air,
//! node_0's drone is held (one of two is no majority), and a land sent to node_0 sets it down.
//! (The fake PX4's land mode is tests/fleet_bus_e2e.rs; land on setpoints over MAVLink is
//! tests/fleet_hold_mavlink_e2e.rs.)
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::bus::{credentials, Identities};
use mavlink_support::{alongside, free_tcp_port, Api, Kestrel, LISTEN_ANY};
use serde_json::{json, Value};
use std::time::{Duration, Instant};

/// `kestrel run --platform sim` as node `id` of the fleet, its drone `drone_{id}`.
fn sim_node(id: usize, fleet: &str, bus: &[u16], creds: &str, ids: &Identities) -> (Kestrel, Api) {
    let connect: Vec<String> = bus[..id]
        .iter()
        .map(|p| format!("tcp/127.0.0.1:{p}"))
        .collect();
    let config = format!(
        "[drone]\nid = \"drone_{id}\"\n\n\
         [fleet]\nenabled = true\nname = \"{fleet}\"\nnode = \"node_{id}\"\n\
         listen = [\"tcp/127.0.0.1:{}\"]\nconnect = {}\ncredentials_file = \"{creds}\"\n{}",
        bus[id],
        serde_json::to_string(&connect).unwrap(),
        ids.section_end(id)
    );
    let node = Kestrel::run_config(&config, &["--platform", "sim", "--listen", LISTEN_ANY]);
    let api = node.api();
    (node, api)
}

fn drone(api: &Api) -> Value {
    api.get("/api/status")["drones"][0].clone()
}

fn execute(api: &Api, id: usize, plan: Value) {
    let drone = format!("drone_{id}");
    let update = json!({"drone_id": drone, "action": 0,
        "mission": {"target": drone, "plan": plan}});
    let (code, answer) = api.post("/api/mission_update", &update);
    assert_eq!(code, 200, "node_{id}: {answer}");
}

fn wait_for(
    what: &str,
    timeout: Duration,
    mut done: impl FnMut() -> bool,
    say: impl Fn() -> String,
) {
    let deadline = Instant::now() + timeout;
    while !done() {
        assert!(Instant::now() < deadline, "{what}\n{}", say());
        std::thread::sleep(Duration::from_millis(200));
    }
}

#[test]
fn land_and_stop_get_through_the_hold_for_a_lost_peer_on_the_simulator() {
    let _beside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let creds = credentials(dir.path(), "creds", "sim:held-fleet");
    let fleet = format!("held-{}", std::process::id());
    let ids = Identities::new(2);
    let bus = [free_tcp_port(), free_tcp_port()];
    let (node_0, api_0) = sim_node(0, &fleet, &bus, &creds, &ids);
    let (node_1, api_1) = sim_node(1, &fleet, &bus, &creds, &ids);
    let both = || format!("{}\n--- node_1 ---\n{}", node_0.output(), node_1.output());
    let heard = |api: &Api, other: &str| {
        let s = api.get("/api/status");
        s["drones"][0]["ready_to_fly"] == true
            && s["remote"]
                .as_array()
                .is_some_and(|r| r.iter().any(|d| d["id"] == other && d["silent"] == false))
    };
    wait_for(
        "the two did not join",
        Duration::from_secs(60),
        || heard(&api_0, "drone_1") && heard(&api_1, "drone_0"),
        both,
    );
    // Both simulated drones start at the origin: drone_1 climbs to 1 m and moves 3 m aside
    // first (two drones taking off from one spot at once would be held apart by the safety
    // stage), then drone_0 climbs to 3 m.
    let idle_in_air = |api: &Api| {
        let d = drone(api);
        d["flight"] == "flying" && d["mission"]["state"] == 0
    };
    execute(
        &api_1,
        1,
        json!([
            {"behavior": "takeoff", "args": {"height": 1.0, "speed": 0.5}},
            {"behavior": "go_to", "args": {"x": 3.0, "y": 0.0, "z": 1.0, "speed": 0.5}}
        ]),
    );
    wait_for(
        "drone_1 not up and aside",
        Duration::from_secs(60),
        || idle_in_air(&api_1),
        both,
    );
    execute(
        &api_0,
        0,
        json!([
            {"behavior": "takeoff", "args": {"height": 3.0, "speed": 0.5}}
        ]),
    );
    wait_for(
        "not both up",
        Duration::from_secs(60),
        || idle_in_air(&api_0) && idle_in_air(&api_1),
        both,
    );
    drop(node_1);
    let say = || node_0.output();
    // An operator's stop ends what flies while the fleet is held.
    execute(
        &api_0,
        0,
        json!([
            {"behavior": "go_to", "args": {"x": -3.0, "y": 0.0, "z": 3.0, "speed": 0.2}}
        ]),
    );
    wait_for(
        "drone_1 never silent",
        Duration::from_secs(20),
        || {
            api_0.get("/api/status")["remote"]
                .as_array()
                .is_some_and(|r| {
                    r.iter()
                        .any(|d| d["id"] == "drone_1" && d["silent"] == true)
                })
        },
        say,
    );
    std::thread::sleep(Duration::from_secs(1));
    let stop = json!({"drone_id": "drone_0", "action": 5});
    let (code, answer) = api_0.post("/api/mission_update", &stop);
    assert_eq!(code, 200, "{answer}");
    let d = drone(&api_0);
    assert_eq!(d["mission"]["state"], 0, "stopped: {d}");
    assert!(
        d["active_behaviors"]
            .as_array()
            .is_none_or(|b| b.is_empty()),
        "{d}"
    );
    let held_z = d["position_enu_m"][2].as_f64().unwrap();
    assert!(held_z > 2.5, "held in the air: {d}");
    // What the ground station's LAND button sends: it descends and disarms, held or not.
    execute(
        &api_0,
        0,
        json!([{"behavior": "land", "args": {"speed": 0.5}}]),
    );
    let started = Instant::now();
    wait_for(
        "not landed through the hold",
        Duration::from_secs(40),
        || {
            let d = drone(&api_0);
            d["armed"] == false && d["position_enu_m"][2].as_f64().unwrap() < 0.2
        },
        || format!("{}\n{}", drone(&api_0), node_0.output()),
    );
    println!(
        "landed from {held_z:.2} m in {:.1} s while held",
        started.elapsed().as_secs_f64()
    );
}
