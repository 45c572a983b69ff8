#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: what QGroundControl sees of Kestrel. The real `kestrel run` flies the demo
//! mission against the fake PX4, which forwards what the companion sends to its ground-station
//! port as PX4 does with MAVLink forwarding on (`--gcs-port-base`); a pymavlink ground station
//! (`sitl/gcs_listen.py`) listens there and reassembles STATUSTEXT chunks as QGC does.
//!
//! Needs `sitl/.venv` (`bash sitl/setup.sh`, done by `.ci/run`).

mod mavlink_support;
mod support;

use mavlink_support::{alongside, free_udp_port, repo, Fake, Kestrel, Personality, DEMO};
use serde_json::Value;
use std::io::{BufRead, BufReader};
use std::process::{Child, Command, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// The listening ground station and the JSON lines it printed so far.
struct GroundStation {
    child: Child,
    lines: Arc<Mutex<Vec<Value>>>,
}

impl GroundStation {
    fn listen(port: u16) -> Self {
        let mut child = Command::new(repo().join("sitl/.venv/bin/python"))
            .arg(repo().join("sitl/gcs_listen.py"))
            .args(["--port", &port.to_string()])
            .stdout(Stdio::piped())
            .spawn()
            .expect("starting sitl/gcs_listen.py (run bash sitl/setup.sh)");
        let mut reader = BufReader::new(child.stdout.take().unwrap());
        let mut first = String::new();
        reader.read_line(&mut first).unwrap();
        assert!(first.contains("listening"), "{first}");
        let lines = Arc::new(Mutex::new(Vec::new()));
        let out = lines.clone();
        std::thread::spawn(move || {
            for line in reader.lines().map_while(Result::ok) {
                if let Ok(v) = serde_json::from_str(&line) {
                    out.lock().unwrap().push(v);
                }
            }
        });
        Self { child, lines }
    }

    fn texts(&self) -> Vec<Value> {
        let lines = self.lines.lock().unwrap();
        lines.iter().map(|l| l["statustext"].clone()).collect()
    }
}

impl Drop for GroundStation {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

#[test]
fn qgc_sees_kestrels_heartbeat_and_its_mission_texts() {
    let _flight = alongside();
    let gcs_port = free_udp_port();
    let gcs = GroundStation::listen(gcs_port);
    let fake = Fake::start(
        Personality::Px4,
        &["--gcs-port-base", &gcs_port.to_string()],
    );
    let mut kestrel = Kestrel::run(Personality::Px4, &fake.connection, "", DEMO);
    let status = kestrel.wait(Duration::from_secs(120));
    assert!(status.success(), "demo failed:\n{}", kestrel.output());
    // The last texts leave at a few a second.
    let deadline = Instant::now() + Duration::from_secs(5);
    while Instant::now() < deadline
        && !gcs
            .texts()
            .iter()
            .any(|t| t["text"].as_str().is_some_and(|s| s.contains("finished")))
    {
        std::thread::sleep(Duration::from_millis(100));
    }
    let lines = gcs.lines.lock().unwrap().clone();
    let all = || {
        lines
            .iter()
            .map(Value::to_string)
            .collect::<Vec<_>>()
            .join("\n")
    };

    println!("the ground station saw:\n{}", all());
    // Kestrel's HEARTBEAT: an onboard controller (18), no autopilot (8), component 191, the
    // autopilot's system id.
    let ours = lines
        .iter()
        .find(|l| l["heartbeat"]["component"] == 191)
        .unwrap_or_else(|| panic!("no HEARTBEAT from component 191:\n{}", all()));
    assert_eq!(ours["heartbeat"]["system"], 1, "{ours}");
    assert_eq!(ours["heartbeat"]["type"], 18, "{ours}");
    assert_eq!(ours["heartbeat"]["autopilot"], 8, "{ours}");

    let texts: Vec<&Value> = lines
        .iter()
        .map(|l| &l["statustext"])
        .filter(|t| t["component"] == 191)
        .collect();
    let find = |needle: &str| {
        texts
            .iter()
            .find(|t| t["text"].as_str().is_some_and(|s| s.contains(needle)))
            .unwrap_or_else(|| panic!("no `{needle}` from Kestrel:\n{}", all()))
    };
    assert!(
        texts
            .iter()
            .all(|t| t["text"].as_str().unwrap().starts_with("Kestrel: ") && t["complete"] == true),
        "{}",
        all()
    );
    // MAV_SEVERITY: NOTICE 5, INFO 6.
    let go_to = find("go_to #2 started");
    assert_eq!(go_to["severity"], 6, "{go_to}");
    // Longer than one STATUSTEXT: sent in chunks and read back whole, as the console printed it.
    let text = go_to["text"].as_str().unwrap();
    assert!(
        text.len() > 50 && go_to["chunks"].as_u64() >= Some(2),
        "{go_to}"
    );
    let console = kestrel.output();
    let printed = console
        .lines()
        .find_map(|l| {
            l.split_once("drone_0: go_to #2 started")
                .map(|(_, rest)| rest)
        })
        .unwrap_or_else(|| panic!("no go_to line:\n{console}"));
    assert_eq!(text, format!("Kestrel: go_to #2 started{printed}"));
    for (needle, severity) in [
        ("takeoff #1 succeeded", 6),
        ("land #4 succeeded", 6),
        (" finished", 5),
    ] {
        assert_eq!(find(needle)["severity"], severity, "{needle}");
    }
    let mission = find("Kestrel: mission ");
    assert!(
        mission["text"].as_str().unwrap().ends_with(" started") && mission["severity"] == 5,
        "the mission's start comes first:\n{}",
        all()
    );
}
