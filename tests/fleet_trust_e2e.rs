//! Issue 29: who may speak on the fleet bus, and how much, against a real `kestrel run` (bus only,
//! no autopilot). The test process is the attacker: a Zenoh peer holding the fleet's
//! `user:password` (a stolen credentials file, or a member gone rogue), but not node_1's key.
//! - item 1: a state written on node_1's key, signed with another key, and one of a made-up node,
//!   are refused and counted; nothing of them reaches the fleet view.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use kestrel::fleet_bus::identity::Signer;
use kestrel::fleet_bus::wire::{DroneState, StateMsg, WIRE_VERSION};
use kestrel::types::LinkHealth;
use mavlink_support::bus::{bus_only_node, credentials, start_bus_only, Identities};
use mavlink_support::{alongside, free_tcp_port, Api, Kestrel};
use std::time::{Duration, Instant};

struct Target {
    _dir: tempfile::TempDir,
    _ids: Identities,
    node: Kestrel,
    api: Api,
    fleet: String,
    zenoh: tokio::runtime::Runtime,
    session: zenoh::Session,
}

/// node_0 of a roster of two, listening; the attacker's Zenoh session joined to it.
fn target() -> Target {
    let dir = tempfile::tempdir().unwrap();
    let creds = credentials(dir.path(), "creds", "farm:the-fleet-secret");
    let fleet = format!("trust-{}", std::process::id());
    let ids = Identities::new(2);
    let port = free_tcp_port();
    let (node, api) = start_bus_only(&bus_only_node(0, &fleet, port, &[], &creds, &ids));
    let zenoh = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    let config = serde_json::json!({
        "mode": "peer",
        "connect": { "endpoints": [format!("tcp/127.0.0.1:{port}")] },
        "scouting": { "multicast": { "enabled": false }, "gossip": { "enabled": false } },
        "transport": { "auth": { "usrpwd": { "user": "farm", "password": "the-fleet-secret" } } },
    });
    let session = zenoh.block_on(async {
        let config = zenoh::Config::from_json5(&config.to_string()).unwrap();
        let deadline = Instant::now() + Duration::from_secs(10);
        loop {
            let s = zenoh::open(config.clone()).await.unwrap();
            if s.info().peers_zid().await.count() > 0 {
                break s;
            }
            assert!(Instant::now() < deadline, "never joined node_0");
            let _ = s.close().await;
            tokio::time::sleep(Duration::from_millis(200)).await;
        }
    });
    Target {
        _dir: dir,
        _ids: ids,
        node,
        api,
        fleet,
        zenoh,
        session,
    }
}

impl Target {
    /// Puts `bytes`, waiting for room in Zenoh's queue rather than dropping (a put's default):
    /// every fragment goes out.
    fn put(&self, key: &str, bytes: Vec<u8>) {
        self.zenoh
            .block_on(async {
                self.session
                    .put(key, bytes)
                    .congestion_control(zenoh::qos::CongestionControl::Block)
                    .await
            })
            .unwrap();
    }

    fn bus(&self) -> serde_json::Value {
        self.api.get("/api/status")["fleet_bus"].clone()
    }
}

fn state(node: &str, drone: &str) -> Vec<u8> {
    StateMsg {
        v: WIRE_VERSION,
        node: node.into(),
        seq: 1,
        sent_unix_us: 0,
        drones: vec![DroneState {
            id: drone.into(),
            position_enu_m: [1.0, 0.0, 1.0],
            velocity_enu_mps: [0.0; 3],
            yaw_rad: 0.0,
            flying: true,
            link: LinkHealth::Ok,
            battery_pct: None,
            behavior: None,
            goal_enu_m: None,
            mission: None,
            claim_enu_m: None,
        }],
    }
    .encode()
}

#[test]
fn a_peer_speaking_for_another_node_or_a_made_up_one_is_refused_and_counted() {
    let _beside = alongside();
    let t = target();
    let mut stranger = Signer::from_seed(&[42; 32]).unwrap();
    let on = |node: &str| format!("kestrel/{}/{node}/state", t.fleet);
    // Several of each: every one refused, counted, and said at most once per 5 s.
    for _ in 0..5 {
        let forged = stranger.seal(&t.fleet, "node_1", "state", &state("node_1", "drone_1"));
        t.put(&on("node_1"), forged);
        let made_up = stranger.seal(&t.fleet, "ghost", "state", &state("ghost", "drone_9"));
        t.put(&on("ghost"), made_up);
        t.put(&on("node_1"), state("node_1", "drone_1"));
    }
    let deadline = Instant::now() + Duration::from_secs(10);
    while t.bus()["refused"].as_u64().unwrap_or(0) < 15 {
        assert!(
            Instant::now() < deadline,
            "not refused: {}\n{}",
            t.bus(),
            t.node.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let status = t.api.get("/api/status");
    assert!(
        status["remote"].as_array().is_none_or(|r| r.is_empty()),
        "{status}"
    );
    let out = t.node.output();
    let lines = out
        .lines()
        .filter(|l| l.contains("fleet bus: refused a `state` message"))
        .count();
    assert_eq!(lines, 1, "{out}");
}
