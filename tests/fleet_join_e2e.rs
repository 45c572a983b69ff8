//! Issue 26, item 1: a Kestrel its fleet refuses says so in words, and does not take off.
//! Two `kestrel run` processes on loopback, no autopilot: node_0 listens with the fleet's
//! credentials; node_1, whose credentials file has the wrong password, connects to it and is
//! refused at every retry (every 2 s). Both sides say it once in Kestrel's words (rate-limited,
//! no Zenoh ERROR), node_1's `fleet_bus` counts the refused joins and says it has not joined,
//! and its missions and explorations are refused with `409 fleet_not_joined` naming the peer
//! (never a stop).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::bus::{bus_only_node, credentials, start_bus_only, Identities};
use mavlink_support::{alongside, free_tcp_port, Kestrel};
use serde_json::{json, Value};
use std::time::{Duration, Instant};

fn lines_with(node: &Kestrel, needle: &str) -> usize {
    node.output().lines().filter(|l| l.contains(needle)).count()
}

#[test]
fn a_refused_node_says_why_on_both_sides_and_does_not_take_off() {
    let _beside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let right = credentials(dir.path(), "right", "farm:the-fleet-secret");
    let wrong = credentials(dir.path(), "wrong", "farm:an-old-secret");
    let fleet = format!("join-{}", std::process::id());
    let ids = Identities::new(2);
    let bus_0 = free_tcp_port();
    let (node_0, _api_0) = start_bus_only(&bus_only_node(0, &fleet, bus_0, &[], &right, &ids));
    let (node_1, api_1) = start_bus_only(&bus_only_node(
        1,
        &fleet,
        free_tcp_port(),
        &[bus_0],
        &wrong,
        &ids,
    ));
    let said_1 = format!("fleet bus: peer at 127.0.0.1:{bus_0} refused: credentials do not match");
    let said_0 = "fleet bus: refused a peer from 127.0.0.1:";

    let deadline = Instant::now() + Duration::from_secs(10);
    let first = loop {
        if lines_with(&node_1, &said_1) > 0 && lines_with(&node_0, said_0) > 0 {
            break Instant::now();
        }
        assert!(
            Instant::now() < deadline,
            "no refusal in words:\n--- node_0 ---\n{}\n--- node_1 ---\n{}",
            node_0.output(),
            node_1.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    };
    // Zenoh retries every 2 s: after two more refusals, each side has still said it once.
    std::thread::sleep(Duration::from_secs(5).saturating_sub(first.elapsed()));
    let out = format!("{}\n{}", node_0.output(), node_1.output());
    assert_eq!(lines_with(&node_1, &said_1), 1, "{out}");
    assert_eq!(lines_with(&node_0, said_0), 1, "{out}");
    assert!(out.contains(": wrong credentials"), "{out}");
    for raw in ["ERROR", "OpenSyn", "reason GENERIC", ".cargo/registry"] {
        assert!(!out.contains(raw), "`{raw}` in the output:\n{out}");
    }

    let bus = api_1.get("/api/status")["fleet_bus"].clone();
    assert_eq!(bus["joined"], false, "{bus}");
    assert_eq!(bus["join_required"], true, "{bus}");
    assert!(bus["refused_joins"].as_u64().unwrap() >= 2, "{bus}");
    let waiting = format!("127.0.0.1:{bus_0} (refused this node: credentials do not match)");
    assert_eq!(bus["waiting_for"], json!([waiting]), "{bus}");

    let mission =
        json!({"target": "drone_1", "plan": [{"behavior": "takeoff", "args": {"height": 2.0}}]});
    let execute = json!({"drone_id": "drone_1", "mission_id": 1, "item_id": null, "action": 0, "mission": mission});
    let (status, answer) = api_1.post("/api/mission_update", &execute);
    assert_eq!(
        (status, &answer["code"]),
        (409, &json!("fleet_not_joined")),
        "{answer}"
    );
    assert!(
        answer["reason"].as_str().unwrap().contains(&waiting),
        "{answer}"
    );
    let (status, answer) = api_1.post("/api/exploration/start", &json!({"drones": ["drone_1"]}));
    let code: &Value = &answer["error"]["code"];
    assert_eq!(
        (status, code),
        (409, &json!("fleet_not_joined")),
        "{answer}"
    );
    // Stopping is never held back: it answers as it would in a whole fleet (nothing to stop).
    let (status, answer) = api_1.post("/api/exploration/stop", &json!({"drones": ["drone_1"]}));
    assert_ne!(
        answer["error"]["code"],
        json!("fleet_not_joined"),
        "{answer}"
    );
    assert!(status != 500, "{status} {answer}");
}
