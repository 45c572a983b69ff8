//! The README's two-node fleet example ("Two drones, step by step"), pasted into two configs,
//! forms a fleet on loopback: two real `kestrel run` processes, each with one fake PX4 of one
//! `sitl/` process, hear each other's drone and agree on where it is in the shared frame.
//!
//! Only what differs from machine to machine is replaced in the pasted text: the autopilot's
//! UDP port, the bus addresses (two drones' IPs become two loopback ports), the key files' paths
//! and the roster's two public keys (the test makes its keys with `kestrel fleet-key`). Everything else (`[map]`, `origin_enu_m`, node names, the fleet name, which side
//! connects) is the README's. Needs `sitl/.venv` (`bash sitl/setup.sh`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::{alongside, free_tcp_port, repo, Api, Fake, Kestrel};
use serde_json::Value;
use std::time::{Duration, Instant};

/// The README's indented blocks between "Two drones, step by step" and "Rotating a key": the
/// roster, drone A's config, drone B's config.
fn readme_example() -> [String; 3] {
    let readme = std::fs::read_to_string(repo().join("README.md")).unwrap();
    let from = readme
        .find("**Two drones, step by step.**")
        .expect("README has the two-node example");
    let to = from + readme[from..].find("**Rotating a key.**").unwrap();
    let mut blocks: Vec<String> = Vec::new();
    let mut current: Option<String> = None;
    for line in readme[from..to].lines() {
        if let Some(code) = line.strip_prefix("    ") {
            let block = current.get_or_insert_with(String::new);
            block.push_str(code);
            block.push('\n');
        } else if line.trim().is_empty() {
            if let Some(block) = current.as_mut() {
                block.push('\n');
            }
        } else if let Some(block) = current.take() {
            blocks.push(block);
        }
    }
    blocks.extend(current);
    blocks
        .try_into()
        .expect("three blocks: the roster, drone A, drone B")
}

/// Replaces `from` (which must be there) by `to`.
fn must_replace(text: &str, from: &str, to: &str) -> String {
    assert!(
        text.contains(from),
        "the README example lost `{from}`:\n{text}"
    );
    text.replace(from, to)
}

/// The other node's drone as `api`'s Kestrel hears it, once heard and not silent.
fn heard(api: &Api, drone: &str) -> Option<Value> {
    let status = api.get("/api/status");
    status["remote"]
        .as_array()?
        .iter()
        .find(|d| d["id"] == drone && d["silent"] == false)
        .cloned()
}

#[test]
fn the_readme_two_node_example_forms_a_fleet_on_loopback() {
    let _beside = alongside();
    let [roster, a, b] = readme_example();
    let dir = tempfile::tempdir().unwrap();
    // Each drone's key, made as the README says; its public key replaces the README's.
    let mut roster = roster;
    let mut keys = Vec::new();
    for (node, readme_key) in [
        ("a", "DnS4T4W9PWKg5AXhs1OAlsANUZgGwdrgjLyo6GLS+9k="),
        ("b", "x60jo213YLRB1bDZr8pzyXt9hJJ0i9sIphTjLKQO34k="),
    ] {
        let path = dir.path().join(format!("fleet-{node}.key"));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .args(["fleet-key", path.to_str().unwrap()])
            .output()
            .unwrap();
        let printed = String::from_utf8_lossy(&out.stdout).to_string();
        let public = printed
            .lines()
            .find_map(|l| l.strip_prefix("public key: "))
            .unwrap_or_else(|| panic!("no public key printed: {printed}"));
        roster = must_replace(&roster, readme_key, public);
        keys.push(path.to_str().unwrap().to_string());
    }

    let (fake, connections) = Fake::start_px4_fleet(2, &[]);
    let (bus_a, bus_b) = (free_tcp_port(), free_tcp_port());
    let paste = |text: &str, autopilot: &str, bus: u16, key: &str| {
        let text = must_replace(text, "udpin:0.0.0.0:14540", autopilot);
        let text = must_replace(&text, "tcp/0.0.0.0:7447", &format!("tcp/127.0.0.1:{bus}"));
        must_replace(&text, "/etc/kestrel/fleet.key", key) + "\n" + &roster
    };
    let a = paste(&a, &connections[0], bus_a, &keys[0]);
    let b = must_replace(
        &paste(&b, &connections[1], bus_b, &keys[1]),
        "tcp/192.168.1.11:7447",
        &format!("tcp/127.0.0.1:{bus_a}"),
    );
    let (api_a, api_b) = (free_tcp_port(), free_tcp_port());
    let node_a = Kestrel::run_config(&a, &["--listen", &format!("127.0.0.1:{api_a}")]);
    let node_b = Kestrel::run_config(&b, &["--listen", &format!("127.0.0.1:{api_b}")]);
    let (api_a, api_b) = (Api::connect(api_a), Api::connect(api_b));

    // Each hears the other's drone, from the other's node, with a position from its autopilot.
    let deadline = Instant::now() + Duration::from_secs(60);
    let (b_on_a, a_on_b) = loop {
        let own_b = &api_b.get("/api/status")["drones"][0];
        // Until B's autopilot gives a position, B announces its drone with a null position
        // (nothing made up): wait for a state sent after the first position.
        if let (Some(x), Some(y)) = (heard(&api_a, "drone_b"), heard(&api_b, "drone_a")) {
            if x["position_enu_m"].is_null() {
                assert!(
                    x["velocity_enu_mps"].is_null() && x["yaw_rad"].is_null(),
                    "a drone without a position has no velocity or heading either: {x}"
                );
            } else if own_b["has_position"] == true {
                let agree = (0..2).all(|k| {
                    (x["position_enu_m"][k].as_f64().unwrap()
                        - own_b["position_enu_m"][k].as_f64().unwrap())
                    .abs()
                        < 0.3
                });
                if agree {
                    break (x, y);
                }
            }
        }
        assert!(
            Instant::now() < deadline,
            "the README's two nodes did not form a fleet:\n{}\n{}\n--- A ---\n{}\n--- B ---\n{}",
            api_a.get("/api/status"),
            api_b.get("/api/status"),
            node_a.output(),
            node_b.output()
        );
        std::thread::sleep(Duration::from_millis(250));
    };
    assert_eq!(b_on_a["node"], "kestrel-b", "{b_on_a}");
    assert_eq!(a_on_b["node"], "kestrel-a", "{a_on_b}");
    let a_status = api_a.get("/api/status");
    assert_eq!(a_status["fleet_bus"]["fleet"], "farm-7", "{a_status}");
    assert_eq!(a_status["fleet_bus"]["node"], "kestrel-a", "{a_status}");
    // B's Kestrel puts its autopilot's local frame at the README's `origin_enu_m = [4.0, 0.0,
    // 0.0]`: its position is the fake's local one (east, north) shifted 4 m east.
    let own_b = api_b.get("/api/status")["drones"][0]["position_enu_m"].clone();
    let local_ned = fake.state_of(1)["local_ned_m"].clone();
    let local_en = [
        local_ned[1].as_f64().unwrap(),
        local_ned[0].as_f64().unwrap(),
    ];
    let shared = [own_b[0].as_f64().unwrap(), own_b[1].as_f64().unwrap()];
    assert!(
        (shared[0] - local_en[0] - 4.0).abs() < 0.3 && (shared[1] - local_en[1]).abs() < 0.3,
        "drone_b at {own_b} in the shared frame, its autopilot's local NED {local_ned}"
    );
    // Both agree where drone_b is: its own Kestrel's position (its autopilot's, shifted by its
    // origin_enu_m) is what A hears, within the drift of one state period on the ground.
    for k in 0..2 {
        let (mine, theirs) = (
            own_b[k].as_f64().unwrap(),
            b_on_a["position_enu_m"][k].as_f64().unwrap(),
        );
        assert!(
            (mine - theirs).abs() < 0.3,
            "drone_b: {own_b} on B, {b_on_a} on A"
        );
    }
}
