//! Issue 29: who may speak on the fleet bus, and how much, against a real `kestrel run` (bus only,
//! no autopilot). The test process is the attacker: a Zenoh peer holding the fleet's
//! `user:password` (a stolen credentials file, or a member gone rogue), but not node_1's key.
//! - item 1: a state written on node_1's key, signed with another key, and one of a made-up node,
//!   are refused and counted; nothing of them reaches the fleet view;
//! - item 5: a 96 MB put is dropped by Zenoh's transport as its fragments arrive (the node never
//!   reassembles more than `fleet_bus::node::MAX_REASSEMBLED_BYTES`): the node's peak memory
//!   does not grow by the put's size;
//! - item 10: a map a member signs that decodes but does not apply (another grid) is counted in
//!   `refused`, as docs/API.md says;
//! - item 6: 300 idle TCP connections held open to a node's bus port (each re-opened as soon as
//!   the node closes it) do not keep a second node from joining.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use kestrel::fleet_bus::identity::Signer;
use kestrel::fleet_bus::wire::{DroneState, MapHeader, MapMsg, StateMsg, WIRE_VERSION};
use kestrel::mapping::grid::GridSpec;
use mavlink_support::bus::{bus_only_node, credentials, start_bus_only, Identities};
use mavlink_support::{alongside, free_tcp_port, Api, Kestrel};
use std::time::{Duration, Instant};

/// A kB figure of /proc/PID/status (`VmHWM`: peak resident memory).
fn status_kb(pid: u32, field: &str) -> u64 {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap();
    status
        .lines()
        .find_map(|l| l.strip_prefix(field))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse().ok())
        .unwrap()
}

struct Target {
    _dir: tempfile::TempDir,
    ids: Identities,
    node: Kestrel,
    api: Api,
    fleet: String,
    zenoh: tokio::runtime::Runtime,
    session: zenoh::Session,
}

/// node_0 of a roster of two, listening; the attacker's Zenoh session joined to it.
fn target() -> Target {
    target_after("")
}

/// As [`target`], node_0's config starting with `head` (sections before `[[vehicle]]`).
fn target_after(head: &str) -> Target {
    let dir = tempfile::tempdir().unwrap();
    let creds = credentials(dir.path(), "creds", "farm:the-fleet-secret");
    let fleet = format!("trust-{}", std::process::id());
    let ids = Identities::new(2);
    let port = free_tcp_port();
    let config = format!(
        "{head}{}",
        bus_only_node(0, &fleet, port, &[], &creds, &ids)
    );
    let (node, api) = start_bus_only(&config);
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
        ids,
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
        drones: vec![DroneState::at_rest(drone, [1.0, 0.0, 1.0], true)],
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

#[test]
fn a_members_map_that_decodes_but_does_not_apply_is_counted_refused() {
    let _beside = alongside();
    let t = target_after("[map]\nsize_m = [10.0, 10.0]\n\n");
    let mut member = t.ids.signer(1);
    // A grid of its own: 4 x 4 cells of 0.5 m far off node_0's.
    let grid = GridSpec {
        resolution_m: 0.5,
        width_cells: 4,
        height_cells: 4,
        origin_enu_m: [500.0, 500.0].into(),
    };
    let map = MapMsg {
        header: MapHeader {
            v: WIRE_VERSION,
            node: "node_1".into(),
            drone: "drone_1".into(),
            seq: 0,
            keyframe: true,
            grid,
            region: grid.full_box(),
        },
        cells: vec![100; 16],
    }
    .encode();
    let key = format!("kestrel/{}/node_1/map", t.fleet);
    t.put(&key, member.seal(&t.fleet, "node_1", "map", &map));
    let deadline = Instant::now() + Duration::from_secs(10);
    while t.bus()["refused"] != 1 {
        assert!(
            Instant::now() < deadline,
            "not refused: {}\n{}",
            t.bus(),
            t.node.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    assert_eq!(t.bus()["received"], 1, "{}", t.bus());
    assert!(
        t.node
            .output()
            .contains("give every node the same [map] section"),
        "{}",
        t.node.output()
    );
}

#[test]
fn a_huge_put_is_dropped_by_the_transport_without_the_node_growing() {
    let _beside = alongside();
    let t = target();
    std::thread::sleep(Duration::from_secs(1));
    let pid = t.node.pid();
    let before_kb = status_kb(pid, "VmHWM:");
    let huge = vec![7u8; 96 << 20];
    let started = Instant::now();
    t.put(&format!("kestrel/{}/node_1/map", t.fleet), huge);
    // Sent (every fragment queued); what arrives, arrives within this.
    std::thread::sleep(Duration::from_secs(3));
    let grew_mb = status_kb(pid, "VmHWM:").saturating_sub(before_kb) / 1024;
    println!(
        "96 MB put in {:?}; node_0's peak memory grew {grew_mb} MB",
        started.elapsed()
    );
    assert!(grew_mb < 32, "node_0's peak memory grew {grew_mb} MB");
    // Dropped before Kestrel saw it: not even received.
    assert_eq!(t.bus()["received"], 0, "{}", t.bus());
    assert_eq!(t.node.pid(), pid);
}

/// Holds `n` idle TCP connections to `port` (no byte ever sent), opening a new one for each the
/// far end closes, until dropped. Returns how many were re-opened.
struct IdleConnections {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    worker: Option<std::thread::JoinHandle<usize>>,
}

impl IdleConnections {
    fn hold(port: u16, n: usize) -> Self {
        use std::net::TcpStream;
        use std::sync::atomic::Ordering;
        let connect = move || {
            let s = TcpStream::connect(("127.0.0.1", port)).ok()?;
            s.set_nonblocking(true).ok()?;
            Some(s)
        };
        let mut held: Vec<TcpStream> = (0..n).filter_map(|_| connect()).collect();
        assert_eq!(held.len(), n, "could not open {n} connections");
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let until = stop.clone();
        let worker = std::thread::spawn(move || {
            let mut reopened = 0;
            while !until.load(Ordering::SeqCst) {
                for s in &mut held {
                    let mut byte = [0u8; 1];
                    let closed = match s.peek(&mut byte) {
                        Ok(0) => true,
                        Ok(_) => false,
                        Err(e) => e.kind() != std::io::ErrorKind::WouldBlock,
                    };
                    if let Some(again) = closed.then(connect).flatten() {
                        *s = again;
                        reopened += 1;
                    }
                }
                std::thread::sleep(Duration::from_millis(20));
            }
            reopened
        });
        IdleConnections {
            stop,
            worker: Some(worker),
        }
    }

    fn release(mut self) -> usize {
        self.stop.store(true, std::sync::atomic::Ordering::SeqCst);
        self.worker.take().unwrap().join().unwrap()
    }
}

#[test]
fn idle_connections_held_to_the_bus_port_do_not_stop_a_join() {
    let _beside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let creds = credentials(dir.path(), "creds", "farm:the-fleet-secret");
    let fleet = format!("idle-{}", std::process::id());
    let ids = Identities::new(2);
    let port = free_tcp_port();
    let (node_0, api_0) = start_bus_only(&bus_only_node(0, &fleet, port, &[], &creds, &ids));
    // The node is listening once its API answers.
    api_0.get("/api/status");
    let idle = IdleConnections::hold(port, 300);
    let started = Instant::now();
    let (node_1, api_1) = start_bus_only(&bus_only_node(
        1,
        &fleet,
        free_tcp_port(),
        &[port],
        &creds,
        &ids,
    ));
    let heard = |api: &Api, drone: &str| {
        api.get("/api/status")["remote"]
            .as_array()
            .is_some_and(|r| r.iter().any(|d| d["id"] == drone))
    };
    let deadline = started + Duration::from_secs(20);
    while !(heard(&api_0, "drone_1") && heard(&api_1, "drone_0")) {
        assert!(
            Instant::now() < deadline,
            "no join with 300 idle connections held\n--- node_0 ---\n{}\n--- node_1 ---\n{}",
            node_0.output(),
            node_1.output()
        );
        std::thread::sleep(Duration::from_millis(200));
    }
    let joined_s = started.elapsed().as_secs_f64();
    let reopened = idle.release();
    println!("joined in {joined_s:.1} s with 300 idle connections held ({reopened} re-opened)");
}
