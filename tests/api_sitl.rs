#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end against the fake PX4 autopilot (sitl/): the host and API that `kestrel run`
//! serves, flying a MAVLink platform in real time; a client uploads takeoff-go-land over REST
//! and follows it over the WebSocket to the end.
//!
//! Needs `sitl/.venv` (`bash sitl/setup.sh`, done by `.ci/run`).

mod support;

use futures::StreamExt;
use kestrel::api::{self, ApiState};
use kestrel::config::Config;
use kestrel::core::{CoreConfig, DroneCore};
use kestrel::estimator::EstimatorPlugin;
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::host::HostBuilder;
use kestrel::platform::mavlink::{LinkConfig, MavlinkPlatform, Profile};
use kestrel::platform::Platform;
use serde_json::{json, Value};
use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use support::{free_tcp_port, free_udp_port, wait_healthy, Process};
use tokio_tungstenite::tungstenite::Message;

const TOKEN: &str = "sitl-secret";

/// Starts the fake PX4 and waits for its ready line; Kestrel listens on `kestrel_port`.
fn fake_px4(kestrel_port: u16) -> Process {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let python = root.join("sitl/.venv/bin/python");
    assert!(
        python.exists(),
        "sitl/.venv is missing: run bash sitl/setup.sh"
    );
    let mut child = Command::new(python)
        .arg(root.join("sitl/fake_autopilot.py"))
        .args([
            "--personality",
            "px4",
            "--vehicles",
            "1",
            "--control-port",
            "0",
        ])
        .args(["--px4-listen-base", &free_udp_port().to_string()])
        .args(["--px4-remote-base", &kestrel_port.to_string()])
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap())
        .read_line(&mut line)
        .unwrap();
    assert!(
        line.contains("\"ready\": true") || line.contains("\"ready\":true"),
        "{line}"
    );
    Process(child)
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn takeoff_go_land_over_the_api_on_the_fake_px4() {
    let kestrel_port = free_udp_port();
    let _fake = fake_px4(kestrel_port);
    let mut config = Config::default();
    config.mavlink.platform = "px4".into();
    config.mavlink.connection = format!("udpin:127.0.0.1:{kestrel_port}");
    let profile = Profile::builtin("px4").unwrap().unwrap();
    let platform = MavlinkPlatform::start(
        profile,
        config.mavlink.session_config(),
        LinkConfig {
            connection: config.mavlink.connection.clone(),
            forward: Vec::new(),
            peers: config.mavlink.peer_policy(),
        },
    )
    .unwrap();
    let mut core_config = CoreConfig::new("drone_0");
    core_config.estimator = EstimatorPlugin::AutopilotOdometry;
    let core = DroneCore::new(
        core_config,
        platform.capabilities(),
        kestrel::behavior::payload::registry(),
    );
    let host = HostBuilder::vehicles(vec![(core, Box::new(platform))], &config).build();
    let (_stop, stop_rx) = tokio::sync::watch::channel(false);
    let spawned = runtime::spawn(host, RuntimeOptions::new(Pace::RealTime), stop_rx).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let app = api::router(
        ApiState::new(spawned.handle, Some(TOKEN.into()), &config.api, None),
        &config.api,
    );
    tokio::spawn(async move { axum::serve(listener, app).await });
    let base = format!("http://127.0.0.1:{port}");
    let http = reqwest::Client::new();

    // Wait until the autopilot is connected, ready and the position is estimated.
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let s = status(&http, &base).await;
        let d = &s["drones"][0];
        if d["link"] == "ok" && d["ready_to_fly"] == true {
            // The `udpin` address pinned from the autopilot's HEARTBEAT, shown to operators.
            let address = d["autopilot_address"].as_str().unwrap_or_default();
            assert!(address.starts_with("127.0.0.1:"), "{d}");
            assert_eq!(d["autopilot_address_changes"], 0, "{d}");
            break;
        }
        assert!(Instant::now() < deadline, "autopilot not ready: {d}");
        tokio::time::sleep(Duration::from_millis(200)).await;
    }
    let (mut socket, _) =
        tokio_tungstenite::connect_async(format!("ws://127.0.0.1:{port}/api/ws?token={TOKEN}"))
            .await
            .unwrap();
    let id = upload_and_start(&http, &base).await;
    let mut started = Vec::new();
    let mut states: Vec<(u64, Option<u64>)> = Vec::new();
    let deadline = Instant::now() + Duration::from_secs(90);
    loop {
        assert!(
            Instant::now() < deadline,
            "mission did not end: {states:?} {started:?}"
        );
        let Ok(Some(Ok(Message::Text(t)))) =
            tokio::time::timeout(Duration::from_secs(10), socket.next()).await
        else {
            panic!("websocket ended");
        };
        let m: Value = serde_json::from_str(t.as_str()).unwrap();
        if m["type"] == "event"
            && m["event"]["kind"] == "behavior"
            && m["event"]["event"] == "started"
        {
            started.push(m["event"]["behavior"].as_str().unwrap().to_string());
        }
        if m["type"] == "mission_status" && m["status"]["mission_id"] == id {
            let s = &m["status"];
            let entry = (s["state"].as_u64().unwrap(), s["item_index"].as_u64());
            if states.last() != Some(&entry) {
                states.push(entry);
            }
            if s["state"] == 0 && s["done_items"] == 3 {
                assert_eq!(s["last_error"], Value::Null, "{s}");
                break;
            }
            assert!(s["last_error"].is_null(), "{s}");
        }
    }
    if states.first() == Some(&(0, None)) {
        states.remove(0);
    }
    assert_eq!(
        states,
        [(1, Some(0)), (1, Some(1)), (1, Some(2)), (0, None)]
    );
    assert_eq!(started, ["takeoff", "go_to", "land"]);
    let s = status(&http, &base).await;
    let p = &s["drones"][0]["position_enu_m"];
    assert!((p[1].as_f64().unwrap() - 5.0).abs() < 0.5, "landed at {p}");
}

async fn status(http: &reqwest::Client, base: &str) -> Value {
    http.get(format!("{base}/api/status"))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap()
}

/// The service path as systemd starts it: the real `kestrel run` process on the fake PX4,
/// serving the API; the mission is uploaded and started over REST before the autopilot even
/// runs (takeoff waits for readiness), and flies to the end.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn kestrel_run_process_serves_the_api_and_flies_the_mission() {
    let kestrel_port = free_udp_port();
    let api_port = free_tcp_port();
    let state = tempfile::tempdir().unwrap();
    let _kestrel = Process(
        Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .args(["run", "--platform", "px4"])
            .args(["--connection", &format!("udpin:127.0.0.1:{kestrel_port}")])
            .args(["--listen", &format!("127.0.0.1:{api_port}")])
            .arg("--state-dir")
            .arg(state.path())
            .arg("--log")
            .arg(state.path().join("flight.jsonl"))
            .env("KESTREL_API_TOKEN", TOKEN)
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    let base = format!("http://127.0.0.1:{api_port}");
    let http = reqwest::Client::new();
    wait_healthy(&base).await;
    // Nothing connected: no made-up vehicle, over REST and over the WebSocket.
    let before = status(&http, &base).await;
    let d = &before["drones"][0];
    assert_eq!(d["link"], "connecting", "{d}");
    assert_eq!(d["has_position"], false, "{d}");
    assert_no_position(d);
    assert_no_position(&first_telemetry(api_port).await["drones"][0]);
    let id = upload_and_start(&http, &base).await;
    // The autopilot starts only now: the takeoff has to wait for it to become ready.
    let fake = fake_px4(kestrel_port);
    let deadline = Instant::now() + Duration::from_secs(90);
    let last = loop {
        let s = status(&http, &base).await;
        let m = &s["drones"][0]["mission"];
        assert!(m["last_error"].is_null(), "{m}");
        assert_eq!(m["mission_id"], id, "{m}");
        if m["state"] == 0 && m["done_items"] == 3 {
            break s;
        }
        assert!(Instant::now() < deadline, "mission did not end: {m}");
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    let d = &last["drones"][0];
    let p = &d["position_enu_m"];
    assert!((p[1].as_f64().unwrap() - 5.0).abs() < 0.5, "landed at {p}");
    assert_eq!(d["armed"], false, "{d}");
    assert_eq!(d["has_position"], true, "{d}");
    assert_eq!(d["stale"], false, "{d}");
    for key in ["position_enu_m", "velocity_enu_mps"] {
        assert!(
            d[key].as_array().is_some_and(
                |a| a.len() == 3 && a.iter().all(|v| v.as_f64().is_some_and(f64::is_finite))
            ),
            "{key}: {d}"
        );
    }
    assert!(d["yaw_rad"].as_f64().is_some_and(f64::is_finite), "{d}");
    assert!(d["geo"]["lat_deg"].as_f64().is_some(), "{d}");
    assert!(first_telemetry(api_port).await["drones"][0]["position_enu_m"].is_array());
    // The autopilot falls silent: what is shown is the last known, and says so.
    drop(fake);
    let deadline = Instant::now() + Duration::from_secs(30);
    let lost = loop {
        let s = status(&http, &base).await;
        if s["drones"][0]["link"] == "lost" {
            break s["drones"][0].clone();
        }
        assert!(Instant::now() < deadline, "link never lost: {s}");
        tokio::time::sleep(Duration::from_millis(250)).await;
    };
    assert_eq!(lost["stale"], true, "{lost}");
    assert!(lost["age_s"].as_f64().unwrap() >= 1.0, "{lost}");
    let log = std::fs::read_to_string(state.path().join("flight.jsonl")).unwrap();
    let started: Vec<String> = log
        .lines()
        .filter_map(|l| serde_json::from_str::<Value>(l).ok())
        .filter(|r| r["type"] == "behavior" && r["event"] == "started")
        .map(|r| r["behavior"].as_str().unwrap_or_default().to_string())
        .collect();
    assert_eq!(started, ["takeoff", "go_to", "land"]);
}

/// Before the autopilot's first position, every positional field is `null`, not a placeholder.
fn assert_no_position(d: &Value) {
    for key in [
        "position_enu_m",
        "yaw_rad",
        "velocity_enu_mps",
        "geo",
        "age_s",
    ] {
        assert!(d[key].is_null(), "{key} is not null: {d}");
        assert!(
            d.get(key).is_some(),
            "{key} is missing instead of null: {d}"
        );
    }
}

/// The first `telemetry` frame of a new WebSocket client.
async fn first_telemetry(api_port: u16) -> Value {
    let url = format!("ws://127.0.0.1:{api_port}/api/ws?token={TOKEN}");
    let (mut socket, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    loop {
        let Ok(Some(Ok(Message::Text(t)))) =
            tokio::time::timeout(Duration::from_secs(10), socket.next()).await
        else {
            panic!("no telemetry on the websocket");
        };
        let m: Value = serde_json::from_str(t.as_str()).unwrap();
        if m["type"] == "telemetry" {
            return m;
        }
    }
}

/// Uploads the thesis's takeoff-go-land and STARTs it; returns its mission id.
async fn upload_and_start(http: &reqwest::Client, base: &str) -> Value {
    let mission: Value = serde_json::from_str(
        &std::fs::read_to_string(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/missions/takeoff_go_land.json"
        ))
        .unwrap(),
    )
    .unwrap();
    let up: Value = http
        .post(format!("{base}/api/missions"))
        .bearer_auth(TOKEN)
        .json(&mission)
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    let id = up["mission_id"].clone();
    assert!(id.is_u64(), "{up}");
    let start: Value = http
        .post(format!("{base}/api/mission_update"))
        .bearer_auth(TOKEN)
        .json(&json!({"drone_id": "drone_0", "mission_id": id, "action": 2}))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert_eq!(start["accepted"], true, "{start}");
    id
}
