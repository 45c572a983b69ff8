//! Control-tick interval of the real-time host while 60 maximum-size missions (1000 items, the
//! `[limits] max_items`) are uploaded over HTTP during a flight, against the same flight without
//! uploads in the same run. One simulated drone flies one-second `go_to` items at 100 Hz; the
//! real axum server (bearer token, state directory written durably) takes the uploads for the
//! flying drone, back to back from one client, each answered 201 once saved.
//!
//! Run: `cargo bench --bench tick_uploads` (about 45 s). Prints p50, p99 and max per phase, the
//! loop's own late/missed counts and the uploads' round trips; the results are in BENCHMARKS.md
//! ("Control tick while missions are uploaded").

use kestrel::api::{self, ApiState};
use kestrel::config::Config;
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::host::store;
use kestrel::mission::{Action, MissionUpdate};
use kestrel::scenario::sim_host::simulated_host;
use kestrel::sim::world::World;
use serde_json::{json, Value};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const TOKEN: &str = "bench-token";
const HEIGHT_M: f64 = 1.5;
/// Seconds of flight before the uploads start (the quiet phase).
const QUIET_S: u64 = 15;
const UPLOADS: usize = 60;
/// PX4's offboard timeout (COM_OF_LOSS_T default): no interval may reach it.
const OFFBOARD_TIMEOUT_MS: f64 = 500.0;

/// The flight: takeoff, `items` one-second go_to items back and forth, land.
fn flight(items: usize) -> Value {
    let mut plan = vec![json!({"behavior": "takeoff", "args": {"height": HEIGHT_M, "speed": 1.0}})];
    for k in 0..items {
        let x = if k % 2 == 0 { 0.5 } else { -0.5 };
        plan.push(json!({"behavior": "go_to",
            "args": {"x": x, "y": 0.0, "z": HEIGHT_M, "speed": 0.5, "run_for_s": 1.0}}));
    }
    plan.push(json!({"behavior": "land", "args": {"speed": 1.0}}));
    json!({"target": "drone_0", "plan": plan})
}

/// A mission of the largest size the API accepts (`max_items` items).
fn largest(max_items: usize) -> Value {
    let plan: Vec<Value> = (0..max_items)
        .map(|k| {
            json!({"behavior": "go_to", "args": {"x": (k % 40) as f64 * 0.25, "y": -(k as f64 % 7.0),
            "z": 2.0 + (k % 5) as f64, "speed": 1.5, "run_for_s": 2.0}})
        })
        .collect();
    json!({"target": "drone_0", "plan": plan})
}

/// The last tick's time and every (phase, interval ms) recorded while the drone flies go_to.
type Intervals = (Option<Instant>, Vec<(usize, f64)>);

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let k = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(k).copied().unwrap_or(f64::NAN)
}

fn row(name: &str, mut v: Vec<f64>) -> (f64, f64) {
    v.sort_by(f64::total_cmp);
    let (p99, max) = (percentile(&v, 0.99), v.last().copied().unwrap_or(f64::NAN));
    println!(
        "| {name} | {} | {:.2} | {:.2} | {:.2} |",
        v.len(),
        percentile(&v, 0.5),
        p99,
        max
    );
    (p99, max)
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("tick_uploads: run it with `cargo bench --bench tick_uploads`");
        return;
    }
    let config = Config::default();
    let max_items = config.mission_limits().max_items;
    let state_dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mut host = simulated_host(World::empty(), 1, 1, &config);
    let (_, report) =
        store::load(state_dir.path(), &host.drone_ids()).unwrap_or_else(|e| panic!("{e}"));
    let sink = store::Sink::start(state_dir.path(), report).unwrap_or_else(|e| panic!("{e}"));
    host.set_store(sink.clone());
    host.step();
    host.update(&MissionUpdate {
        drone_id: Some("drone_0".into()),
        mission_id: None,
        item_id: None,
        action: Action::Execute,
        mission: Some(flight(2 * QUIET_S as usize + 30)),
    })
    .unwrap_or_else(|e| panic!("flight: {e}"));

    // Phase 0 = flying before the uploads, 1 = while uploading, 2 = after.
    let phase = Arc::new(AtomicUsize::new(0));
    let intervals: Arc<Mutex<Intervals>> = Arc::default();
    let (p, rec) = (phase.clone(), intervals.clone());
    let mut options = RuntimeOptions::new(Pace::RealTime);
    options.stop_when = Some(Box::new(move |host| {
        let now = Instant::now();
        let flying = host
            .cores()
            .first()
            .and_then(|c| c.server().motion())
            .is_some_and(|(name, _)| name == "go_to");
        let mut r = rec.lock().unwrap_or_else(|e| e.into_inner());
        if let (true, Some(last)) = (flying, r.0) {
            let ms = now.duration_since(last).as_secs_f64() * 1000.0;
            r.1.push((p.load(Ordering::Relaxed), ms));
        }
        r.0 = Some(now);
        host.executors().iter().all(|e| e.running_id().is_none())
    }));

    let rt = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    let (round_trips, stats) = rt.block_on(async {
        let (_stop, stop_rx) = tokio::sync::watch::channel(false);
        let spawned = runtime::spawn(host, options, stop_rx).unwrap_or_else(|e| panic!("{e}"));
        let handle = spawned.handle.clone();
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0")
            .await
            .unwrap_or_else(|e| panic!("{e}"));
        let base = format!(
            "http://{}",
            listener.local_addr().unwrap_or_else(|e| panic!("{e}"))
        );
        let state = ApiState::new(handle.clone(), Some(TOKEN.into()), &config.api, None)
            .with_store(Some(sink));
        let app = api::router(state, &config.api);
        tokio::spawn(async move { axum::serve(listener, app).await });
        let body = serde_json::to_vec(&largest(max_items)).unwrap_or_else(|e| panic!("{e}"));
        println!("each upload: {max_items} items, {} bytes", body.len());
        let http = reqwest::Client::new();
        tokio::time::sleep(Duration::from_secs(QUIET_S)).await;
        let before = handle.loop_stats();
        phase.store(1, Ordering::Relaxed);
        let mut round_trips = Vec::new();
        for k in 0..UPLOADS {
            let t = Instant::now();
            let r = http
                .post(format!("{base}/api/missions"))
                .bearer_auth(TOKEN)
                .header("Content-Type", "application/json")
                .body(body.clone())
                .send()
                .await
                .unwrap_or_else(|e| panic!("upload {k}: {e}"));
            let status = r.status().as_u16();
            let text = r.text().await.unwrap_or_default();
            assert_eq!(status, 201, "upload {k}: {text}");
            round_trips.push(t.elapsed().as_secs_f64() * 1000.0);
        }
        phase.store(2, Ordering::Relaxed);
        let after = handle.loop_stats();
        let joined = tokio::task::spawn_blocking(move || spawned.thread.join()).await;
        joined
            .unwrap_or_else(|e| panic!("{e}"))
            .unwrap_or_else(|_| panic!("control loop panicked"));
        (round_trips, (before, after))
    });
    let r = intervals.lock().unwrap_or_else(|e| e.into_inner());
    let of = |ph: usize| -> Vec<f64> {
        r.1.iter()
            .filter(|(p, _)| *p == ph)
            .map(|(_, ms)| *ms)
            .collect()
    };
    println!("| phase | ticks | p50 ms | p99 ms | max ms |");
    println!("|---|---|---|---|---|");
    let (quiet_p99, quiet_max) = row("flight, no uploads", of(0));
    let (up_p99, up_max) = row("flight, 60 maximum-size uploads", of(1));
    let mut rt_ms = round_trips.clone();
    rt_ms.sort_by(f64::total_cmp);
    println!(
        "upload round trip (201, saved): p50 {:.1} ms, max {:.1} ms, {} uploads in {:.1} s",
        percentile(&rt_ms, 0.5),
        rt_ms.last().copied().unwrap_or(f64::NAN),
        rt_ms.len(),
        round_trips.iter().sum::<f64>() / 1000.0
    );
    let (a, b) = stats;
    println!(
        "loop's own count during the uploads: {} ticks, {} late, {} missed, {} commands",
        b.wakes - a.wakes,
        b.late - a.late,
        b.missed - a.missed,
        b.commands - a.commands
    );
    println!(
        "p99 moved by {:.2} ms (target < 1 ms); longest gap {:.1} ms (offboard timeout {OFFBOARD_TIMEOUT_MS} ms)",
        up_p99 - quiet_p99,
        up_max.max(quiet_max)
    );
}
