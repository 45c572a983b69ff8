#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: the real `kestrel sim` process, driven through its HTTP and WebSocket API.

mod support;

use futures::{SinkExt, StreamExt};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};
use support::Kestrel;
use tokio_tungstenite::tungstenite::Message;

const TOKEN: &str = "e2e-secret";

fn client() -> reqwest::Client {
    reqwest::Client::new()
}

async fn start(dir: &Path, extra: &[&str]) -> Kestrel {
    Kestrel::sim(dir, TOKEN, extra).await
}

async fn update(k: &Kestrel, body: Value) -> Value {
    let (code, v) = k.post("/api/mission_update", &body).await;
    assert_eq!(code, 200, "{body} -> {v}");
    assert_eq!(v["accepted"], true, "{v}");
    v
}

fn takeoff_go_land() -> Value {
    let text = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/missions/takeoff_go_land.json"
    ))
    .unwrap();
    serde_json::from_str(&text).unwrap()
}

/// Polls the status until `done` holds for drone `i`.
async fn wait_status(k: &Kestrel, i: usize, max_s: f64, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs_f64(max_s);
    loop {
        let (_, s) = k.get("/api/status").await;
        let d = s["drones"][i].clone();
        if done(&d) {
            return d;
        }
        assert!(Instant::now() < deadline, "timed out; last status {d}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

type Ws =
    tokio_tungstenite::WebSocketStream<tokio_tungstenite::MaybeTlsStream<tokio::net::TcpStream>>;

async fn ws(k: &Kestrel) -> Ws {
    let (socket, _) =
        tokio_tungstenite::connect_async(format!("ws://127.0.0.1:{}/api/ws?token={TOKEN}", k.port))
            .await
            .unwrap();
    socket
}

async fn next_json(socket: &mut Ws) -> Value {
    loop {
        match tokio::time::timeout(Duration::from_secs(10), socket.next()).await {
            Ok(Some(Ok(Message::Text(t)))) => return serde_json::from_str(t.as_str()).unwrap(),
            Ok(Some(Ok(_))) => continue,
            other => panic!("websocket ended: {other:?}"),
        }
    }
}

#[tokio::test]
async fn a_client_uploads_takeoff_go_land_and_follows_it_over_websocket() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let mut socket = ws(&k).await;
    socket
        .send(Message::Text(
            json!({"type": "subscribe", "telemetry_rate_hz": 20, "request_id": 1})
                .to_string()
                .into(),
        ))
        .await
        .unwrap();
    let (code, up) = k.post("/api/missions", &takeoff_go_land()).await;
    assert_eq!(code, 201, "{up}");
    let id = up["mission_id"].as_u64().unwrap();
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": id, "item_id": 0, "action": 2, "mission": ""}),
    )
    .await;
    let mut states: Vec<(u64, Option<u64>)> = Vec::new();
    let mut started = Vec::new();
    let mut telemetry = 0;
    let mut replied = false;
    let deadline = Instant::now() + Duration::from_secs(60);
    loop {
        assert!(Instant::now() < deadline, "mission did not end: {states:?}");
        let m = next_json(&mut socket).await;
        match m["type"].as_str().unwrap() {
            "telemetry" => {
                telemetry += 1;
                assert_eq!(m["drones"][0]["drone"], "drone_0");
                assert!(m["drones"][0].get("mission").is_none());
            }
            "reply" => replied = m["accepted"] == true,
            "event" => {
                if m["event"]["kind"] == "behavior" && m["event"]["event"] == "started" {
                    started.push(m["event"]["behavior"].as_str().unwrap().to_string());
                }
            }
            "mission_status" => {
                let s = &m["status"];
                if s["mission_id"] == json!(id) {
                    let entry = (s["state"].as_u64().unwrap(), s["item_index"].as_u64());
                    if states.last() != Some(&entry) {
                        states.push(entry);
                    }
                    if s["state"] == 0 && s["done_items"] == 3 {
                        assert_eq!(s["last_error"], Value::Null);
                        break;
                    }
                }
            }
            "map_update" => {}
            other => panic!("unexpected message {other}"),
        }
    }
    assert!(replied, "subscribe was not answered");
    // 20 Hz of wall-clock time over a 16 s flight at 20x is about 16 frames.
    assert!(telemetry >= 10, "only {telemetry} telemetry frames");
    assert_eq!(started, ["takeoff", "go_to", "land"]);
    // The periodic status may show the mission loaded and idle before START.
    if states.first() == Some(&(0, None)) {
        states.remove(0);
    }
    assert_eq!(
        states,
        [(1, Some(0)), (1, Some(1)), (1, Some(2)), (0, None)]
    );
    let log = client()
        .get(format!("{}/api/log?drone=drone_0", k.base))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap()
        .text()
        .await
        .unwrap();
    let behaviors = log
        .lines()
        .filter(|l| l.contains("\"type\":\"behavior\""))
        .count();
    assert!(behaviors >= 6, "{behaviors} behavior records in the log");
}

#[tokio::test]
async fn requests_without_the_token_are_refused() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let c = client();
    let routes = [
        ("GET", "/api/status"),
        ("GET", "/api/missions"),
        ("POST", "/api/missions"),
        ("GET", "/api/missions/1"),
        ("DELETE", "/api/missions/1"),
        ("POST", "/api/mission_update"),
        ("GET", "/api/behaviors"),
        ("POST", "/api/frames"),
        ("GET", "/api/frames"),
        ("GET", "/api/log"),
        ("GET", "/api/logs"),
        ("POST", "/api/sim/fault"),
        ("GET", "/api/ws"),
    ];
    for (method, path) in routes {
        for token in [None, Some("wrong")] {
            let mut r = c.request(method.parse().unwrap(), format!("{}{path}", k.base));
            if let Some(t) = token {
                r = r.bearer_auth(t);
            }
            let r = r.json(&takeoff_go_land()).send().await.unwrap();
            assert_eq!(r.status().as_u16(), 401, "{method} {path} with {token:?}");
            let body: Value = r.json().await.unwrap();
            assert_eq!(body["error"]["code"], "unauthorized");
        }
    }
    let bad =
        tokio_tungstenite::connect_async(format!("ws://127.0.0.1:{}/api/ws?token=nope", k.port))
            .await;
    assert!(bad.is_err());
    assert_eq!(
        c.get(format!("{}/api/health", k.base))
            .send()
            .await
            .unwrap()
            .status(),
        200
    );
    let (_, missions) = k.get("/api/missions").await;
    assert_eq!(missions, json!([]), "nothing was loaded");
}

/// The README's token recipe (`head -c 16 /dev/urandom | base64`) gives `+ / =`: the page puts
/// it in the WebSocket URL form-encoded, and any case of `Bearer` works; REST routes do not take
/// the token from the query.
#[tokio::test]
async fn a_base64_token_works_in_the_websocket_url_and_bearer_in_any_case() {
    let dir = tempfile::tempdir().unwrap();
    let token = "q+v/Zz3k9Q1w==";
    let k = Kestrel::sim(dir.path(), token, &[]).await;
    let encoded = "q%2Bv%2FZz3k9Q1w%3D%3D";
    let url = format!("ws://127.0.0.1:{}/api/ws?token={encoded}", k.port);
    let (mut socket, _) = tokio_tungstenite::connect_async(url).await.unwrap();
    assert!(next_json(&mut socket).await.is_object());
    let c = client();
    for scheme in ["Bearer", "bearer", "BEARER"] {
        let r = c
            .get(format!("{}/api/status", k.base))
            .header("Authorization", format!("{scheme} {token}"))
            .send()
            .await
            .unwrap();
        assert_eq!(r.status().as_u16(), 200, "{scheme}");
    }
    let r = c
        .get(format!("{}/api/status?token={encoded}", k.base))
        .send()
        .await
        .unwrap();
    assert_eq!(
        r.status().as_u16(),
        401,
        "the query token is for the WebSocket only"
    );
    let (code, body) = k.get("/api/log?drone=drone_9").await;
    assert_eq!(
        (code, body["error"]["code"].clone()),
        (404, json!("unknown_drone"))
    );
}

/// A web page on another site cannot drive a tokenless Kestrel: its "simple" text/plain POST is
/// refused for its content type, anything it sends carries a foreign Origin, and a page whose
/// name was rebound to 127.0.0.1 sends a foreign Host.
#[tokio::test]
async fn a_foreign_web_page_cannot_upload_or_start_a_mission_without_a_token() {
    let dir = tempfile::tempdir().unwrap();
    let k = Kestrel::sim(dir.path(), "", &[]).await;
    let c = client();
    let plain = c
        .post(format!("{}/api/missions", k.base))
        .header("Content-Type", "text/plain")
        .body(takeoff_go_land().to_string())
        .send()
        .await
        .unwrap();
    assert_eq!(plain.status().as_u16(), 415);
    let body: Value = plain.json().await.unwrap();
    assert_eq!(body["error"]["code"], "unsupported_media_type");
    let foreign = c
        .post(format!("{}/api/missions", k.base))
        .header("Origin", "http://evil.example")
        .json(&takeoff_go_land())
        .send()
        .await
        .unwrap();
    assert_eq!(foreign.status().as_u16(), 403);
    let start = c
        .post(format!("{}/api/mission_update", k.base))
        .header("Origin", "http://evil.example")
        .json(&json!({"drone_id": "drone_0", "action": 0, "mission": takeoff_go_land()}))
        .send()
        .await
        .unwrap();
    assert_eq!(start.status().as_u16(), 403);
    let ws = tokio_tungstenite::tungstenite::client::IntoClientRequest::into_client_request(
        format!("ws://127.0.0.1:{}/api/ws", k.port),
    )
    .map(|mut r| {
        r.headers_mut()
            .insert("Origin", "http://evil.example".parse().unwrap());
        r
    })
    .unwrap();
    assert!(tokio_tungstenite::connect_async(ws).await.is_err());
    // DNS rebinding (issue 29, item 9): the attacker's page, its name now resolving to
    // 127.0.0.1, sends that name as both Host and Origin, which then agree.
    let rebound = format!("rebind.attacker.example:{}", k.port);
    let page = format!("http://{rebound}");
    let upload = c
        .post(format!("{}/api/missions", k.base))
        .header("Host", rebound.as_str())
        .header("Origin", page.as_str())
        .json(&takeoff_go_land())
        .send()
        .await
        .unwrap();
    assert_eq!(upload.status().as_u16(), 403);
    let body: Value = upload.json().await.unwrap();
    assert_eq!(body["error"]["code"], "foreign_host", "{body}");
    assert!(
        body["error"]["message"]
            .as_str()
            .unwrap()
            .contains("rebind.attacker.example"),
        "{body}"
    );
    let start = c
        .post(format!("{}/api/mission_update", k.base))
        .header("Host", rebound.as_str())
        .header("Origin", page.as_str())
        .json(&json!({"drone_id": "drone_0", "action": 0, "mission": takeoff_go_land()}))
        .send()
        .await
        .unwrap();
    assert_eq!(start.status().as_u16(), 403);
    // A same-origin GET carries no Origin at all: the Host alone decides.
    let read = c
        .get(format!("{}/api/status", k.base))
        .header("Host", rebound.as_str())
        .send()
        .await
        .unwrap();
    assert_eq!(read.status().as_u16(), 403);
    let ws = tokio_tungstenite::tungstenite::client::IntoClientRequest::into_client_request(
        format!("ws://127.0.0.1:{}/api/ws", k.port),
    )
    .map(|mut r| {
        r.headers_mut().insert("Host", rebound.parse().unwrap());
        r.headers_mut().insert("Origin", page.parse().unwrap());
        r
    })
    .unwrap();
    assert!(tokio_tungstenite::connect_async(ws).await.is_err());
    let localhost = c
        .get(format!("http://localhost:{}/api/status", k.port))
        .send()
        .await
        .unwrap();
    assert_eq!(
        localhost.status().as_u16(),
        200,
        "localhost is this machine"
    );
    let (_, missions) = k.get("/api/missions").await;
    assert_eq!(missions, json!([]), "nothing was loaded");
    let (_, status) = k.get("/api/status").await;
    assert_eq!(status["drones"][0]["armed"], false);
    let own = c
        .post(format!("{}/api/missions", k.base))
        .header("Origin", k.base.as_str())
        .json(&takeoff_go_land())
        .send()
        .await
        .unwrap();
    assert_eq!(own.status().as_u16(), 201, "the server's own page may");
}

/// `kestrel sim --speedup max` without `--exit-when-done`: the demo flies as fast as the CPU
/// allows, then simulated time follows the wall clock (it used to run on at thousands of seconds
/// a second, filling the disk with flight log).
#[tokio::test]
async fn speedup_max_falls_back_to_real_time_once_the_flights_are_over() {
    let dir = tempfile::tempdir().unwrap();
    let port = support::free_tcp_port();
    let base = format!("http://127.0.0.1:{port}");
    let _kestrel = support::Process(
        Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .args(["sim", "--speedup", "max", "--listen"])
            .arg(format!("127.0.0.1:{port}"))
            .arg("--log")
            .arg(dir.path().join("flight.jsonl"))
            .env("KESTREL_API_TOKEN", TOKEN)
            .stdout(std::process::Stdio::null())
            .stderr(std::process::Stdio::null())
            .spawn()
            .unwrap(),
    );
    support::wait_healthy(&base).await;
    let status = || async {
        client()
            .get(format!("{base}/api/status"))
            .bearer_auth(TOKEN)
            .send()
            .await
            .unwrap()
            .json::<Value>()
            .await
            .unwrap()
    };
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let s = status().await;
        let d = &s["drones"][0];
        if d["armed"] == false && d["mission"]["state"] == 0 && d["mission"]["done_items"] == 4 {
            break;
        }
        assert!(Instant::now() < deadline, "the demo did not end: {d}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
    let t0 = status().await["t"].as_f64().unwrap();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let t1 = status().await["t"].as_f64().unwrap();
    assert!(
        (1.0..4.0).contains(&(t1 - t0)),
        "{:.1} simulated s in 2 wall-clock s after the flight",
        t1 - t0
    );
}

#[tokio::test]
async fn mid_flight_insert_modify_and_an_on_demand_plan_switch() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let patrol = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 0.0, "y": 10.0, "z": 3.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 10.0, "y": 10.0, "z": 3.0, "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]});
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 1, "action": 0, "mission": patrol.to_string()}),
    )
    .await;
    wait_status(&k, 0, 30.0, |d| d["mission"]["item_index"] == 1).await;
    // MODIFY the running go_to: climb to 5 m on the way.
    let new_goal = json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": 0.0, "y": 10.0, "z": 5.0, "speed": 2.0}}]});
    update(&k, json!({"drone_id": "drone_0", "mission_id": 1, "item_id": 1, "action": 9, "mission": new_goal})).await;
    // INSERT a detour after the running item, MODIFY the pending leg.
    let detour = json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": -4.0, "y": 10.0, "z": 5.0, "speed": 2.0}}]});
    update(&k, json!({"drone_id": "drone_0", "mission_id": 1, "item_id": 1, "action": 8, "mission": detour})).await;
    let leg = json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": 6.0, "y": 10.0, "z": 5.0, "speed": 2.0}}]});
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 1, "item_id": 3, "action": 9, "mission": leg}),
    )
    .await;
    let d = wait_status(&k, 0, 30.0, |d| d["mission"]["item_index"] == 3).await;
    // The modified item 1 and the inserted detour (item 2) were flown and reached.
    let done = &d["mission"]["done_results"];
    assert_eq!(
        (done[1]["item"].clone(), done[1]["result"].clone()),
        (json!(1), json!("succeeded")),
        "{d}"
    );
    assert_eq!(
        (done[2]["item"].clone(), done[2]["result"].clone()),
        (json!(2), json!("succeeded")),
        "{d}"
    );
    assert!(
        (d["position_enu_m"][2].as_f64().unwrap() - 5.0).abs() < 0.5,
        "{d}"
    );
    let (_, view) = k.get("/api/missions/1").await;
    let plan = &view["plan"]["plan"];
    assert_eq!(plan[1]["args"]["z"], 5.0);
    assert_eq!(plan[2]["args"]["x"], -4.0);
    assert_eq!(plan[3]["args"]["x"], 6.0);
    // On-demand inspection takes over: LOAD it, START it while patrol runs.
    let inspect = json!({"target": "drone_0", "plan": [
        {"behavior": "go_to", "args": {"x": 2.0, "y": 2.0, "z": 4.0, "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]});
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 2, "action": 1, "mission": inspect}),
    )
    .await;
    let v = update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 2, "action": 2}),
    )
    .await;
    assert_eq!(v["status"]["mission_id"], 2);
    let d = wait_status(&k, 0, 60.0, |d| {
        d["mission"]["state"] == 0 && d["mission"]["mission_id"] == 2
    })
    .await;
    assert_eq!(d["mission"]["last_error"], Value::Null, "{d}");
    let p = &d["position_enu_m"];
    assert!(
        (p[0].as_f64().unwrap() - 2.0).abs() < 0.5 && p[2].as_f64().unwrap() < 0.2,
        "{p}"
    );
    let (_, missions) = k.get("/api/missions").await;
    let patrol_view = missions
        .as_array()
        .unwrap()
        .iter()
        .find(|m| m["mission_id"] == 1)
        .unwrap();
    assert_eq!(patrol_view["items"], 5);
    assert_eq!(patrol_view["state"], 0);
}

#[tokio::test]
async fn mission_updates_over_the_websocket_are_answered() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let mut socket = ws(&k).await;
    let msg = json!({"type": "mission_update", "request_id": 7, "drone_id": "drone_0", "mission_id": 3, "action": 1, "mission": takeoff_go_land()});
    socket
        .send(Message::Text(msg.to_string().into()))
        .await
        .unwrap();
    let refuse = json!({"type": "mission_update", "request_id": 8, "drone_id": "drone_0", "mission_id": 3, "action": 3});
    socket
        .send(Message::Text(refuse.to_string().into()))
        .await
        .unwrap();
    let mut answers = Vec::new();
    while answers.len() < 2 {
        let m = next_json(&mut socket).await;
        if m["type"] == "reply" {
            answers.push(m);
        }
    }
    assert_eq!(
        (
            answers[0]["request_id"].clone(),
            answers[0]["accepted"].clone()
        ),
        (json!(7), json!(true))
    );
    assert_eq!(
        (
            answers[1]["request_id"].clone(),
            answers[1]["accepted"].clone()
        ),
        (json!(8), json!(false))
    );
    assert!(answers[1]["reason"]
        .as_str()
        .unwrap()
        .contains("no mission is running"));
    let took = oversized_frame_dropped_after(k.port).await;
    assert!(took < Duration::from_secs(2), "dropped after {took:?}");
}

/// Issue 29, item 10b: a client announces one 15 MB frame and sends its first kilobyte. The
/// server must drop it from the frame's header, not wait for (and buffer) the 15 MB before the
/// 256 KiB message limit applies. How long until the server closed the connection.
async fn oversized_frame_dropped_after(port: u16) -> Duration {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", port))
        .await
        .unwrap();
    let head = format!(
        "GET /api/ws?token={TOKEN} HTTP/1.1\r\nHost: 127.0.0.1:{port}\r\nUpgrade: websocket\r\n\
         Connection: Upgrade\r\nSec-WebSocket-Key: dGhlIHNhbXBsZSBub25jZQ==\r\n\
         Sec-WebSocket-Version: 13\r\n\r\n"
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    let mut buf = vec![0u8; 4096];
    let n = tcp.read(&mut buf).await.unwrap();
    let answer = String::from_utf8_lossy(&buf[..n]).to_string();
    assert!(answer.starts_with("HTTP/1.1 101"), "{answer}");
    // FIN + text, masked, 64-bit length 15 000 000, a zero mask, then 1 KiB of the payload.
    let mut frame = vec![0x81, 0xff];
    frame.extend(15_000_000u64.to_be_bytes());
    frame.extend([0u8; 4]);
    frame.extend(vec![b' '; 1024]);
    tcp.write_all(&frame).await.unwrap();
    let sent = Instant::now();
    // Telemetry may still arrive; the connection must end (EOF or reset) without the rest.
    let ended = tokio::time::timeout(Duration::from_secs(5), async {
        while matches!(tcp.read(&mut buf).await, Ok(n) if n > 0) {}
    })
    .await;
    assert!(
        ended.is_ok(),
        "still open 5 s after the oversized frame's header"
    );
    sent.elapsed()
}

async fn huge_upload_status(port: u16) -> String {
    use tokio::io::{AsyncReadExt, AsyncWriteExt};
    let mut tcp = tokio::net::TcpStream::connect(("127.0.0.1", port))
        .await
        .unwrap();
    let head = format!(
        "POST /api/missions HTTP/1.1\r\nHost: x\r\nAuthorization: Bearer {TOKEN}\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n",
        50 << 20
    );
    tcp.write_all(head.as_bytes()).await.unwrap();
    let mut buf = vec![0u8; 512];
    let n = tokio::time::timeout(Duration::from_secs(5), tcp.read(&mut buf))
        .await
        .unwrap()
        .unwrap();
    String::from_utf8_lossy(&buf[..n]).to_string()
}

#[tokio::test]
async fn bad_requests_are_rejected_precisely_and_nothing_moves() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let c = client();
    // A huge body is refused from its Content-Length, before it is sent.
    let answer = huge_upload_status(k.port).await;
    assert!(answer.starts_with("HTTP/1.1 413"), "{answer}");
    let r = c
        .post(format!("{}/api/missions", k.base))
        .bearer_auth(TOKEN)
        .header("Content-Type", "application/json")
        .body("{\"target\": ")
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 400);
    let (code, v) = k.post("/api/missions", &json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": 0, "y": 0, "z": 300, "speed": 1}}]})).await;
    assert_eq!(code, 422);
    assert_eq!(v["error"]["details"][0]["pointer"], "/plan/0/args/z");
    // No target: every problem of the plan is listed, the missing target too.
    let (code, v) = k.post("/api/missions", &json!({"plan": [{"behavior": "go_to", "args": {"x": 0, "y": 0, "z": 300, "speed": 1}}]})).await;
    assert_eq!(code, 422, "{v}");
    let pointers: Vec<&str> = v["error"]["details"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["pointer"].as_str().unwrap())
        .collect();
    assert!(
        pointers.contains(&"/target") && pointers.contains(&"/plan/0/args/z"),
        "{v}"
    );
    let (code, v) = k
        .post("/api/missions", &json!({"target": "drone_9", "plan": []}))
        .await;
    assert_eq!(code, 422, "{v}");
    assert_eq!(v["error"]["details"][0]["pointer"], "/target", "{v}");
    let (code, v) = k.get("/api/missions").await;
    assert_eq!(code, 200);
    assert_eq!(v.as_array().map(Vec::len), Some(0), "nothing stored: {v}");
    let (code, v) = k
        .post(
            "/api/mission_update",
            &json!({"drone_id": "drone_0", "action": 42}),
        )
        .await;
    assert_eq!((code, v["accepted"].clone()), (422, json!(false)), "{v}");
    let (code, _) = k
        .post(
            "/api/mission_update",
            &json!({"drone_id": "drone_9", "action": 2}),
        )
        .await;
    assert_eq!(code, 404);
    // Misspelt keys are refused, named by their pointer, and act on nothing: `droneid` must not
    // start a mission on the only drone, `mision_id` must not pick the current one.
    for (body, pointer) in [
        (
            json!({"droneid": "drone_0", "action": "execute", "mission": takeoff_go_land()}),
            "/droneid",
        ),
        (
            json!({"drone_id": "drone_0", "mision_id": 1, "action": 2}),
            "/mision_id",
        ),
    ] {
        let (code, v) = k.post("/api/mission_update", &body).await;
        assert_eq!((code, v["accepted"].clone()), (422, json!(false)), "{v}");
        assert_eq!(v["code"], "invalid_request", "{v}");
        assert_eq!(v["details"][0]["pointer"], pointer, "{v}");
    }
    let (code, v) = k
        .post("/api/frames", &json!({"frame_id": "f", "parnt": "earth"}))
        .await;
    assert_eq!(
        (code, v["error"]["details"][0]["pointer"].clone()),
        (422, json!("/parnt")),
        "{v}"
    );
    let (code, v) = k
        .post(
            "/api/frames",
            &json!({"frame_id": "a b", "parent": "earth"}),
        )
        .await;
    assert_eq!(
        (code, v["error"]["code"].clone()),
        (422, json!("invalid_frame"))
    );
    let (code, _) = k
        .post(
            "/api/frames",
            &json!({"frame_id": "x", "parent": "nowhere"}),
        )
        .await;
    assert_eq!(code, 422);
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (code, s) = k.get("/api/status").await;
    assert_eq!(code, 200, "process alive");
    assert_eq!(s["drones"][0]["armed"], false);
    assert!(s["drones"][0]["position_enu_m"][2].as_f64().unwrap() < 0.05);
}

#[tokio::test]
async fn a_restart_keeps_loaded_missions_and_does_not_resume_them() {
    let dir = tempfile::tempdir().unwrap();
    {
        let k = start(dir.path(), &[]).await;
        k.post("/api/missions", &takeoff_go_land()).await;
        update(&k, json!({"drone_id": "drone_0", "mission_id": 5, "action": 0, "mission": takeoff_go_land()})).await;
        wait_status(&k, 0, 30.0, |d| d["mission"]["item_index"] == 1).await;
        let (code, _) = k
            .post(
                "/api/frames",
                &json!({"frame_id": "panel_x", "translation_m": [5, 5, 0]}),
            )
            .await;
        assert_eq!(code, 200);
        tokio::time::sleep(Duration::from_millis(300)).await;
    } // killed here (SIGKILL): only what was already saved survives
    let k = start(dir.path(), &[]).await;
    let (_, missions) = k.get("/api/missions").await;
    let ids: Vec<u64> = missions
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["mission_id"].as_u64().unwrap())
        .collect();
    assert_eq!(ids, [1, 5]);
    let (_, status) = k.get("/api/status").await;
    let m = &status["drones"][0]["mission"];
    assert_eq!(m["state"], 0);
    assert!(
        m["last_error"].as_str().unwrap().contains("not resumed"),
        "{m}"
    );
    let (_, frames) = k.get("/api/frames").await;
    assert_eq!(frames[0]["frame_id"], "panel_x");
    tokio::time::sleep(Duration::from_millis(500)).await;
    let (_, status) = k.get("/api/status").await;
    assert_eq!(status["drones"][0]["armed"], false);
}

#[tokio::test]
async fn several_drones_share_one_api_and_a_lost_link_shows() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &["--drones", "2"]).await;
    let mut mission = takeoff_go_land();
    mission["target"] = json!("drone_1");
    let (code, up) = k.post("/api/missions", &mission).await;
    assert_eq!((code, up["drone"].clone()), (201, json!("drone_1")));
    let (code, v) = k
        .post(
            "/api/mission_update",
            &json!({"mission_id": 1, "action": 2}),
        )
        .await;
    assert_eq!((code, v["code"].clone()), (400, json!("drone_id_required")));
    update(
        &k,
        json!({"drone_id": "drone_1", "mission_id": 1, "action": 2}),
    )
    .await;
    let d = wait_status(&k, 1, 30.0, |d| d["flight"] == "flying").await;
    assert_eq!(d["drone"], "drone_1");
    let (_, s) = k.get("/api/status").await;
    assert_eq!(
        s["drones"][0]["armed"], false,
        "drone_0 stays on the ground"
    );
    let (code, _) = k
        .post(
            "/api/sim/fault",
            &json!({"drone_id": "drone_1", "fault": "link_lost"}),
        )
        .await;
    assert_eq!(code, 200);
    // The mission waits for the link (README: "When the link to the autopilot drops").
    let d = wait_status(&k, 1, 10.0, |d| {
        d["link"] == "lost"
            && d["mission"]["done_results"]
                .as_array()
                .is_some_and(|r| r.iter().any(|x| x["code"] == "link_lost"))
    })
    .await;
    assert_eq!(d["mission"]["state"], 1, "still running, waiting: {d}");
    k.post(
        "/api/sim/fault",
        &json!({"drone_id": "drone_1", "fault": "link_restored"}),
    )
    .await;
    // Default `[mission] on_link_regained = "land"`: the mission ends and the drone lands.
    let d = wait_status(&k, 1, 10.0, |d| {
        d["link"] == "ok" && d["mission"]["last_error_code"] == "link_lost"
    })
    .await;
    assert_eq!(d["mission"]["state"], 0, "{d}");
    wait_status(&k, 1, 30.0, |d| d["armed"] == false).await;
}

#[test]
fn listening_beyond_loopback_without_a_token_is_refused_at_start() {
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(["sim", "--no-demo", "--listen", "0.0.0.0:0"])
        .env_remove("KESTREL_API_TOKEN")
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("without an API token"), "{err}");
}

#[tokio::test]
async fn missions_are_listed_fetched_and_deleted_and_behaviors_listed() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let (code, up) = k
        .post("/api/missions?mission_id=42", &takeoff_go_land())
        .await;
    assert_eq!((code, up["mission_id"].clone()), (201, json!(42)));
    let (code, m) = k.get("/api/missions/42").await;
    assert_eq!(code, 200);
    assert_eq!(
        m["plan"]["plan"],
        takeoff_go_land()["plan"]
            .clone()
            .as_array()
            .map(|p| {
                let mut p = p.clone();
                p[0]["method"] = json!("__call__");
                p[2]["method"] = json!("__call__");
                Value::Array(p)
            })
            .unwrap()
    );
    assert_eq!(m["progress"]["cursor"], 0);
    let (code, _) = k.get("/api/missions/7").await;
    assert_eq!(code, 404);
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 42, "action": 2}),
    )
    .await;
    let r = client()
        .delete(format!("{}/api/missions/42", k.base))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 409, "running missions stay");
    update(
        &k,
        json!({"drone_id": "drone_0", "mission_id": 42, "action": 5}),
    )
    .await;
    let r = client()
        .delete(format!("{}/api/missions/42", k.base))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 204);
    let (_, list) = k.get("/api/missions").await;
    assert_eq!(list, json!([]));
    let (_, behaviors) = k.get("/api/behaviors").await;
    let go_to = behaviors
        .as_array()
        .unwrap()
        .iter()
        .find(|b| b["name"] == "go_to")
        .unwrap();
    assert_eq!(go_to["resource"], "motion");
    assert!(go_to["methods"]
        .as_array()
        .unwrap()
        .contains(&json!("go_to_point_with_yaw")));
    assert_eq!(
        go_to["args_schema"]["required"],
        json!(["x", "y", "z", "speed"])
    );
    for name in [
        "takeoff",
        "land",
        "follow_path",
        "rtl",
        "point_gimbal",
        "take_photo",
    ] {
        assert!(
            behaviors
                .as_array()
                .unwrap()
                .iter()
                .any(|b| b["name"] == name),
            "{name}"
        );
    }
    let spec: Value = reqwest::get(format!("{}/api/openapi.json", k.base))
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    for route in [
        "/api/health",
        "/api/status",
        "/api/missions",
        "/api/missions/{id}",
        "/api/mission_update",
        "/api/behaviors",
        "/api/frames",
        "/api/log",
        "/api/logs",
        "/api/sim/fault",
    ] {
        assert!(
            spec["paths"].get(route).is_some(),
            "{route} missing from the OpenAPI spec"
        );
    }
}

#[tokio::test]
async fn mission_run_flies_a_file_on_a_running_kestrel_and_validate_reports_errors() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let bin = env!("CARGO_BIN_EXE_kestrel");
    let file = concat!(env!("CARGO_MANIFEST_DIR"), "/missions/takeoff_go_land.json");
    let out = tokio::process::Command::new(bin)
        .args(["mission", "run", file, "--api", &k.base])
        .env("KESTREL_API_TOKEN", TOKEN)
        .output()
        .await
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(stdout.contains("succeeded"), "{stdout}");
    let bad = dir.path().join("bad.json");
    std::fs::write(
        &bad,
        r#"{"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": 1}}]}"#,
    )
    .unwrap();
    let out = std::process::Command::new(bin)
        .args(["mission", "validate"])
        .arg(&bad)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("/plan/0/args/y: missing argument `y`"),
        "{stdout}"
    );
    let out = std::process::Command::new(bin)
        .args(["mission", "validate", file])
        .output()
        .unwrap();
    assert!(out.status.success());
}

/// What the router refuses on its own (a path or query that does not parse, a wrong method, no
/// route, a body that is not JSON) answers the project's JSON error body, not axum's plain text.
#[tokio::test]
async fn router_rejections_answer_json_errors() {
    let dir = tempfile::tempdir().unwrap();
    let k = start(dir.path(), &[]).await;
    let c = client();
    let check = |status: u16, code: &'static str, r: reqwest::Response| async move {
        let got = r.status().as_u16();
        let allow = r.headers().get("allow").cloned();
        let text = r.text().await.unwrap();
        let body: Value =
            serde_json::from_str(&text).unwrap_or_else(|e| panic!("not JSON ({e}): {got} {text}"));
        assert_eq!(
            (got, body["error"]["code"].as_str()),
            (status, Some(code)),
            "{body}"
        );
        assert!(body["error"]["message"]
            .as_str()
            .is_some_and(|m| !m.is_empty()));
        allow
    };
    let get = |path: &str| c.get(format!("{}{path}", k.base)).bearer_auth(TOKEN).send();
    // `Invalid URL: Cannot parse ...` from the path extractor.
    check(400, "bad_request", get("/api/missions/abc").await.unwrap()).await;
    check(404, "not_found", get("/api/nothing_here").await.unwrap()).await;
    let allow = check(
        405,
        "method_not_allowed",
        c.put(format!("{}/api/missions", k.base))
            .bearer_auth(TOKEN)
            .send()
            .await
            .unwrap(),
    )
    .await;
    assert!(allow.is_some(), "405 keeps its Allow header");
    let post_to = |path: &str, body: &'static str, mime: &'static str| {
        c.post(format!("{}{path}", k.base))
            .bearer_auth(TOKEN)
            .header("Content-Type", mime)
            .body(body)
            .send()
    };
    let post = |body: &'static str, mime: &'static str| post_to("/api/missions", body, mime);
    check(
        400,
        "bad_request",
        post_to("/api/missions?mission_id=abc", "{}", "application/json")
            .await
            .unwrap(),
    )
    .await;
    check(
        400,
        "bad_json",
        post("{", "application/json").await.unwrap(),
    )
    .await;
    check(
        415,
        "unsupported_media_type",
        post("{}", "text/plain").await.unwrap(),
    )
    .await;
}

/// A coverage plan that outlives `[api] request_timeout_s` answers 408 with the JSON error body
/// and stops computing: the process goes back to idle at once, it does not plan on.
#[tokio::test]
async fn a_coverage_plan_past_the_request_timeout_answers_408_and_stops() {
    let dir = tempfile::tempdir().unwrap();
    let config = dir.path().join("kestrel.toml");
    std::fs::write(&config, "[api]\nrequest_timeout_s = 1.0\n").unwrap();
    let k = start(dir.path(), &["--config", config.to_str().unwrap()]).await;
    // 20 000 vertices and 100 000 streets: minutes of work for a debug build.
    let polygon: Vec<[f64; 2]> = (0..20_000)
        .map(|i| {
            let a = i as f64 / 20_000.0 * std::f64::consts::TAU;
            [400.0 * a.cos(), 400.0 * a.sin()]
        })
        .collect();
    let request = json!({"polygon_enu_m": polygon, "street_spacing_m": 0.008,
        "drones": ["drone_0"], "height_m": 3.0, "angle_deg": 0.0});
    let t = Instant::now();
    let (code, body) = k.post("/api/coverage", &request).await;
    assert_eq!(
        (code, body["error"]["code"].as_str()),
        (408, Some("request_timeout")),
        "{body}"
    );
    assert!(t.elapsed() < Duration::from_secs(5), "{:?}", t.elapsed());
    // CPU time of the process over the next second: a sim at 20x, not a planner running on.
    let cpu_ticks = || {
        let stat = std::fs::read_to_string(format!("/proc/{}/stat", k.process.0.id())).unwrap();
        let after_name = stat.rsplit_once(')').unwrap().1;
        let fields: Vec<u64> = after_name
            .split_whitespace()
            .skip(11)
            .take(2)
            .map(|f| f.parse().unwrap())
            .collect();
        fields.iter().sum::<u64>()
    };
    tokio::time::sleep(Duration::from_millis(300)).await;
    let before = cpu_ticks();
    tokio::time::sleep(Duration::from_secs(2)).await;
    let used = cpu_ticks() - before;
    // Clock ticks are 1/100 s: a planner still running would use about 200 in 2 s.
    assert!(used < 120, "{used} CPU ticks in 2 s after the 408");
}
