//! Issue 26, item 2: a healthy fleet logs no ERROR. Three `kestrel run` processes on loopback
//! (no autopilot), each `connect`ing to both others as operators write it: the two sides of a
//! pair race to open their session and the loser's retries are refused every 2 s (Zenoh logged
//! each as an ERROR with a cargo registry path). They join, say nothing alarming, and once
//! joined, a peer that dies is the lost-peer rules' business: the others stay joined and their
//! missions are not refused for joining.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::bus::{bus_only_node, credentials, start_bus_only, Identities};
use mavlink_support::{alongside, free_tcp_port};
use serde_json::json;
use std::time::{Duration, Instant};

#[test]
fn three_nodes_connecting_to_each_other_join_without_an_error() {
    let _beside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let creds = credentials(dir.path(), "creds", "farm:the-fleet-secret");
    let fleet = format!("quiet-{}", std::process::id());
    let ports: Vec<u16> = (0..3).map(|_| free_tcp_port()).collect();
    let ids = Identities::new(3);
    let mut nodes: Vec<_> = (0..3)
        .map(|i| {
            let others: Vec<u16> = (0..3).filter(|&j| j != i).map(|j| ports[j]).collect();
            start_bus_only(&bus_only_node(i, &fleet, ports[i], &others, &creds, &ids))
        })
        .collect();
    let output = |nodes: &[(mavlink_support::Kestrel, mavlink_support::Api)]| {
        nodes
            .iter()
            .enumerate()
            .map(|(i, (k, _))| format!("--- node_{i} ---\n{}", k.output()))
            .collect::<Vec<_>>()
            .join("\n")
    };

    let deadline = Instant::now() + Duration::from_secs(12);
    loop {
        let joined = nodes.iter().all(|(_, api)| {
            let status = api.get("/api/status");
            let heard = status["remote"]
                .as_array()
                .map_or(0, |r| r.iter().filter(|d| d["silent"] == false).count());
            status["fleet_bus"]["joined"] == true && heard == 2
        });
        if joined {
            break;
        }
        assert!(Instant::now() < deadline, "not joined:\n{}", output(&nodes));
        std::thread::sleep(Duration::from_millis(250));
    }
    // The racing retries go on every 2 s: watch two of them.
    std::thread::sleep(Duration::from_secs(5));
    let out = output(&nodes);
    for raw in ["ERROR", "WARN", "zenoh", "OpenSyn", ".cargo/registry"] {
        assert!(
            !out.contains(raw),
            "`{raw}` in a healthy fleet's output:\n{out}"
        );
    }
    for (_, api) in &nodes {
        assert_eq!(api.get("/api/status")["fleet_bus"]["refused_joins"], 0);
    }

    // node_2 dies: the others are still joined, and a mission is not refused for joining.
    drop(nodes.pop());
    std::thread::sleep(Duration::from_secs(2));
    let (_, api_0) = &nodes[0];
    assert_eq!(api_0.get("/api/status")["fleet_bus"]["joined"], true);
    let mission =
        json!({"target": "drone_0", "plan": [{"behavior": "takeoff", "args": {"height": 2.0}}]});
    let execute = json!({"drone_id": "drone_0", "mission_id": 1, "item_id": null, "action": 0, "mission": mission});
    let (_, answer) = api_0.post("/api/mission_update", &execute);
    assert_ne!(answer["code"], "fleet_not_joined", "{answer}");
}
