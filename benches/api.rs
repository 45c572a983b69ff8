#![allow(clippy::unwrap_used, clippy::expect_used)]
//! API costs on the control loop, measured on the real server and host in one process:
//! 1. latency from an HTTP START (request sent) to the first changed setpoint the vehicle gets;
//! 2. the control loop's tick timing with 0 and with 100 WebSocket clients at 10 Hz.
//!
//! Run: `cargo bench --bench api` (add `-- --trials N --clients N --seconds S` to change the
//! defaults 200, 100, 10). Results are in BENCHMARKS.md (`## Missions and API`).

use futures::StreamExt;
use kestrel::api::{self, ApiState};
use kestrel::config::Config;
use kestrel::control::Setpoint;
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::host::Fleet;
use kestrel::host::HostBuilder;
use kestrel::platform::{Capabilities, PlatformFeedback, PlatformRequest};
use kestrel::scenario::sim_host::{sim_world, simulated_parts};
use kestrel::sim::fleet::SimFleet;
use kestrel::sim::world::World;
use kestrel::types::Vec3;
use serde_json::{json, Value};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const TOKEN: &str = "bench";

/// What the probe saw at the platform boundary.
#[derive(Default)]
struct Probe {
    /// Set by the bench just before a START; cleared at the first changed setpoint.
    armed: AtomicBool,
    changed_at: Mutex<Option<Instant>>,
    /// Wall-clock instants of drone_0's ticks, while `recording`.
    recording: AtomicBool,
    ticks: Mutex<Vec<Instant>>,
    last_velocity: Mutex<Option<Vec3>>,
    commands: AtomicU64,
}

/// The simulator fleet with a probe on drone_0's commands.
struct ProbeFleet {
    inner: SimFleet,
    probe: Arc<Probe>,
}

fn velocity_of(setpoint: &Option<Setpoint>) -> Option<Vec3> {
    match setpoint {
        Some(Setpoint::Velocity {
            velocity_enu_mps, ..
        }) => Some(*velocity_enu_mps),
        Some(Setpoint::Position { position_enu_m, .. }) => Some(*position_enu_m),
        _ => None,
    }
}

impl Fleet for ProbeFleet {
    fn len(&self) -> usize {
        self.inner.len()
    }
    fn capabilities(&self, i: usize) -> Option<Capabilities> {
        self.inner.capabilities(i)
    }
    fn poll(&mut self, i: usize, now: Duration) -> PlatformFeedback {
        self.inner.poll(i, now)
    }
    fn command(
        &mut self,
        i: usize,
        now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    ) {
        if i == 0 {
            let at = Instant::now();
            self.probe.commands.fetch_add(1, Ordering::Relaxed);
            if self.probe.recording.load(Ordering::Relaxed) {
                if let Ok(mut t) = self.probe.ticks.lock() {
                    t.push(at);
                }
            }
            let v = velocity_of(&setpoint);
            if let Ok(mut last) = self.probe.last_velocity.lock() {
                let changed = match (*last, v) {
                    (Some(a), Some(b)) => (a - b).norm() > 0.3,
                    (None, Some(_)) => true,
                    _ => false,
                };
                if changed && self.probe.armed.swap(false, Ordering::SeqCst) {
                    if let Ok(mut c) = self.probe.changed_at.lock() {
                        *c = Some(at);
                    }
                }
                *last = v;
            }
        }
        self.inner.command(i, now, setpoint, requests);
    }
    fn advance(&mut self, now: Duration, tick: Duration) {
        self.inner.advance(now, tick);
    }
    fn is_simulated(&self) -> bool {
        true
    }
}

struct Setup {
    base: String,
    port: u16,
    probe: Arc<Probe>,
    http: reqwest::Client,
    _shutdown: tokio::sync::watch::Sender<bool>,
}

async fn setup() -> Setup {
    let config = Config::default();
    let sim = sim_world(World::empty(), 1, 0, &config);
    let world = sim.world.clone();
    let (cores, fleet) = simulated_parts(sim, &config);
    let probe = Arc::new(Probe::default());
    let fleet = ProbeFleet {
        inner: fleet,
        probe: probe.clone(),
    };
    let mut host = HostBuilder::new(cores, Box::new(fleet), &config)
        .world(world)
        .build();
    host.step();
    let (shutdown, rx) = tokio::sync::watch::channel(false);
    let spawned = runtime::spawn(host, RuntimeOptions::new(Pace::Factor(1.0)), rx).unwrap();
    let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
    let port = listener.local_addr().unwrap().port();
    let state = ApiState::new(spawned.handle, Some(TOKEN.into()), &config.api, None);
    let app = api::router(state, &config.api);
    tokio::spawn(async move { axum::serve(listener, app).await });
    Setup {
        base: format!("http://127.0.0.1:{port}"),
        port,
        probe,
        http: reqwest::Client::new(),
        _shutdown: shutdown,
    }
}

impl Setup {
    async fn update(&self, body: Value) -> Value {
        let r = self
            .http
            .post(format!("{}/api/mission_update", self.base))
            .bearer_auth(TOKEN)
            .json(&body)
            .send()
            .await
            .unwrap();
        r.json().await.unwrap()
    }

    async fn status(&self) -> Value {
        let r = self
            .http
            .get(format!("{}/api/status", self.base))
            .bearer_auth(TOKEN)
            .send()
            .await
            .unwrap();
        let v: Value = r.json().await.unwrap();
        v["drones"][0].clone()
    }

    /// Takes off and hovers (mission 1 ends after takeoff; the vehicle holds).
    async fn airborne(&self) {
        let takeoff = json!({"target": "drone_0", "plan": [{"behavior": "takeoff", "args": {"height": 3.0, "speed": 2.0}}]});
        self.update(
            json!({"drone_id": "drone_0", "mission_id": 1, "action": 0, "mission": takeoff}),
        )
        .await;
        loop {
            let d = self.status().await;
            if d["mission"]["state"] == 0 && d["mission"]["done_items"] == 1 {
                break;
            }
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
        tokio::time::sleep(Duration::from_secs(1)).await;
    }
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() - 1) as f64 * p).round() as usize;
    sorted[i.min(sorted.len() - 1)]
}

fn summary(name: &str, mut v: Vec<f64>) {
    v.sort_by(f64::total_cmp);
    println!(
        "{name}: n={} p50={:.2} ms p99={:.2} ms max={:.2} ms",
        v.len(),
        percentile(&v, 0.5),
        percentile(&v, 0.99),
        v.last().copied().unwrap_or(f64::NAN)
    );
}

async fn start_latency(s: &Setup, trials: usize) {
    for (id, x) in [(2, 4.0), (3, -4.0)] {
        let m = json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": x, "y": 0.0, "z": 3.0, "speed": 2.0}}]});
        s.update(json!({"drone_id": "drone_0", "mission_id": id, "action": 1, "mission": m}))
            .await;
    }
    let mut latencies = Vec::new();
    let mut round_trips = Vec::new();
    for k in 0..trials {
        let id = 2 + (k % 2);
        tokio::time::sleep(Duration::from_millis(300)).await;
        *s.probe.changed_at.lock().unwrap() = None;
        s.probe.armed.store(true, Ordering::SeqCst);
        let t0 = Instant::now();
        let answer = s
            .update(json!({"drone_id": "drone_0", "mission_id": id, "action": 2}))
            .await;
        let answered = t0.elapsed();
        assert_eq!(answer["accepted"], true, "{answer}");
        let deadline = Instant::now() + Duration::from_secs(1);
        let changed = loop {
            if let Some(t) = *s.probe.changed_at.lock().unwrap() {
                break Some(t);
            }
            if Instant::now() > deadline {
                break None;
            }
            tokio::time::sleep(Duration::from_millis(1)).await;
        };
        s.probe.armed.store(false, Ordering::SeqCst);
        if let Some(t) = changed {
            latencies.push(t.duration_since(t0).as_secs_f64() * 1e3);
        }
        round_trips.push(answered.as_secs_f64() * 1e3);
        s.update(json!({"drone_id": "drone_0", "mission_id": id, "action": 5}))
            .await;
    }
    println!(
        "== START -> first changed setpoint ({trials} trials, 100 Hz control loop, real time)"
    );
    summary("start_to_setpoint", latencies);
    summary("start_http_round_trip", round_trips);
}

async fn tick_timing(s: &Setup, clients: usize, seconds: f64) {
    let mut tasks = Vec::new();
    let received = Arc::new(AtomicU64::new(0));
    for _ in 0..clients {
        let url = format!("ws://127.0.0.1:{}/api/ws?token={TOKEN}", s.port);
        let received = received.clone();
        tasks.push(tokio::spawn(async move {
            let (mut socket, _) = tokio_tungstenite::connect_async(url).await.unwrap();
            use futures::SinkExt;
            let sub = json!({"type": "subscribe", "telemetry_rate_hz": 10}).to_string();
            socket
                .send(tokio_tungstenite::tungstenite::Message::Text(sub.into()))
                .await
                .unwrap();
            while let Some(Ok(_)) = socket.next().await {
                received.fetch_add(1, Ordering::Relaxed);
            }
        }));
    }
    // A mission flying the whole time, so behaviors publish feedback and events.
    let lap = json!({"target": "drone_0", "plan": [
        {"behavior": "follow_path", "args": {"path": [[5, 0, 3], [5, 5, 3], [0, 5, 3], [0, 0, 3]], "speed": 2.0}},
        {"behavior": "follow_path", "args": {"path": [[5, 0, 3], [5, 5, 3], [0, 5, 3], [0, 0, 3]], "speed": 2.0}},
        {"behavior": "follow_path", "args": {"path": [[5, 0, 3], [5, 5, 3], [0, 5, 3], [0, 0, 3]], "speed": 2.0}}]});
    let id = 10 + clients as i64;
    s.update(json!({"drone_id": "drone_0", "mission_id": id, "action": 0, "mission": lap}))
        .await;
    tokio::time::sleep(Duration::from_millis(500)).await;
    received.store(0, Ordering::Relaxed);
    s.probe.ticks.lock().unwrap().clear();
    s.probe.recording.store(true, Ordering::SeqCst);
    tokio::time::sleep(Duration::from_secs_f64(seconds)).await;
    s.probe.recording.store(false, Ordering::SeqCst);
    let got = received.load(Ordering::Relaxed);
    s.update(json!({"drone_id": "drone_0", "mission_id": id, "action": 5}))
        .await;
    for t in tasks {
        t.abort();
    }
    let ticks = s.probe.ticks.lock().unwrap().clone();
    let intervals: Vec<f64> = ticks
        .windows(2)
        .map(|w| w[1].duration_since(w[0]).as_secs_f64() * 1e3)
        .collect();
    let late = intervals.iter().filter(|i| **i > 15.0).count();
    println!(
        "== control loop with {clients} WebSocket clients at 10 Hz for {seconds} s: {} ticks ({:.1} Hz), {late} intervals > 15 ms, clients received {:.1} msg/s each",
        ticks.len(),
        ticks.len() as f64 / seconds,
        got as f64 / seconds / clients.max(1) as f64
    );
    summary(&format!("tick_interval_{clients}_clients"), intervals);
}

fn arg(name: &str, default: f64) -> f64 {
    let args: Vec<String> = std::env::args().collect();
    args.iter()
        .position(|a| a == name)
        .and_then(|i| args.get(i + 1))
        .and_then(|v| v.parse().ok())
        .unwrap_or(default)
}

fn main() {
    // `cargo bench` passes `--bench`; `cargo test --benches` runs this as a quick check.
    let quick = !std::env::args().any(|a| a == "--bench");
    let trials = if quick { 4.0 } else { arg("--trials", 200.0) } as usize;
    let clients = if quick { 5.0 } else { arg("--clients", 100.0) } as usize;
    let seconds = if quick { 1.0 } else { arg("--seconds", 10.0) };
    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .unwrap();
    rt.block_on(async {
        let s = setup().await;
        s.airborne().await;
        start_latency(&s, trials).await;
        tick_timing(&s, 0, seconds).await;
        tick_timing(&s, clients, seconds).await;
    });
}
