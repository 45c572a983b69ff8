//! Control-tick interval of the real-time host with 4 drones, in one run: first every drone
//! flies `go_to` items (no planning), then `navigate_to` items on a 500 x 500 map (0.1 m cells,
//! a 50 m x 50 m world of poles seen by each drone's lidar), one new item and so one new plan a
//! second per drone. Plans run on the host's planner worker, so the tick interval must not move.
//!
//! Run: `cargo bench --bench tick_interval` (about 50 s). Prints p50, p99 and max per phase;
//! the results are in BENCHMARKS.md ("Control tick while planning").

use kestrel::config::Config;
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::mission::{Action, MissionUpdate};
use kestrel::scenario::sim_host::simulated_host;
use kestrel::sim::world::{Cylinder, World};
use kestrel::types::SensorConfig;
use rand::{Rng, SeedableRng};
use serde_json::{json, Value};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

const DRONES: usize = 4;
/// Items (seconds) per phase.
const ITEMS: usize = 20;
const HEIGHT_M: f64 = 1.5;

/// Where drone `d` starts (m): a row along x, 2 m apart, facing north.
fn start_x(d: usize) -> f64 {
    2.0 * d as f64 - 3.0
}

/// 50 m x 50 m with 150 poles between the start row and the goals at y = +-20 m.
fn world() -> World {
    let mut w = World::empty();
    w.bounds_m.x = [-25.0, 25.0];
    w.bounds_m.y = [-25.0, 25.0];
    w.sensor = SensorConfig::lidar();
    let starts = (0..DRONES).map(|d| [start_x(d), 0.0, 0.0]).collect();
    w.starts_xy_yaw.insert(DRONES.to_string(), starts);
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    while w.cylinders.len() < 150 {
        let (x, y): (f64, f64) = (rng.gen_range(-24.0..24.0), rng.gen_range(-24.0..24.0));
        let clear_of_paths = y.abs() > 2.0 && !(y.abs() > 18.0 && x.abs() < 5.0);
        if clear_of_paths {
            w.cylinders.push(Cylinder {
                xy_m: [x, y],
                radius_m: 0.3,
                height_m: 5.0,
            });
        }
    }
    w
}

/// Takeoff, `ITEMS` one-second go_to items, `ITEMS` one-second navigate_to items (each a new
/// plan across the map), land.
fn mission(drone: usize) -> Value {
    let x0 = start_x(drone);
    let mut plan = vec![json!({"behavior": "takeoff", "args": {"height": HEIGHT_M, "speed": 1.0}})];
    for k in 0..ITEMS {
        let y = if k % 2 == 0 { 0.5 } else { -0.5 };
        plan.push(
            json!({"behavior": "go_to", "args": {"x": x0, "y": y, "z": HEIGHT_M,
            "speed": 0.5, "run_for_s": 1.0}}),
        );
    }
    for k in 0..ITEMS {
        let y = if k % 2 == 0 { 20.0 } else { -20.0 };
        plan.push(
            json!({"behavior": "navigate_to", "args": {"x": x0, "y": y, "z": HEIGHT_M,
            "speed": 0.5, "run_for_s": 1.0}}),
        );
    }
    plan.push(json!({"behavior": "land", "args": {"speed": 1.0}}));
    json!({"target": format!("drone_{drone}"), "plan": plan})
}

#[derive(Default)]
struct Samples {
    last: Option<Instant>,
    /// (phase, interval ms): phase 0 = go_to, 1 = navigate_to.
    intervals: Vec<(usize, f64)>,
}

fn percentile(sorted: &[f64], q: f64) -> f64 {
    let k = ((sorted.len() as f64 - 1.0) * q).round() as usize;
    sorted.get(k).copied().unwrap_or(f64::NAN)
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("tick_interval: run it with `cargo bench --bench tick_interval`");
        return;
    }
    let mut config = Config::default();
    config.map.size_m = Some([50.0, 50.0]);
    config.map.origin_enu_m = Some([-25.0, -25.0]);
    let mut host = simulated_host(world(), DRONES, 1, &config);
    host.step();
    for d in 0..DRONES {
        host.update(&MissionUpdate {
            drone_id: Some(format!("drone_{d}")),
            mission_id: None,
            item_id: None,
            action: Action::Execute,
            mission: Some(mission(d)),
        })
        .unwrap_or_else(|e| panic!("mission of drone_{d}: {e}"));
    }
    let samples = Arc::new(Mutex::new(Samples::default()));
    let recorder = samples.clone();
    let mut options = RuntimeOptions::new(Pace::RealTime);
    options.stop_when = Some(Box::new(move |host| {
        let now = Instant::now();
        let phase = host.cores().first().and_then(|c| {
            c.server().motion().and_then(|(name, _)| match name {
                "go_to" => Some(0),
                "navigate_to" => Some(1),
                _ => None,
            })
        });
        let mut s = recorder.lock().unwrap_or_else(|e| e.into_inner());
        if let (Some(phase), Some(last)) = (phase, s.last) {
            s.intervals
                .push((phase, now.duration_since(last).as_secs_f64() * 1000.0));
        }
        s.last = Some(now);
        host.executors().iter().all(|e| e.running_id().is_none())
            || host.now() > Duration::from_secs(120)
    }));
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(1)
        .enable_all()
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    let host = runtime.block_on(async {
        let (_stop, stop_rx) = tokio::sync::watch::channel(false);
        let spawned = runtime::spawn(host, options, stop_rx).unwrap_or_else(|e| panic!("{e}"));
        let handle = spawned.handle;
        let joined = tokio::task::spawn_blocking(move || spawned.thread.join()).await;
        drop(handle);
        joined
            .unwrap_or_else(|e| panic!("{e}"))
            .unwrap_or_else(|_| panic!("control loop panicked"))
    });
    let s = samples.lock().unwrap_or_else(|e| e.into_inner());
    let ended: Vec<String> = host
        .cores()
        .iter()
        .zip(host.executors())
        .map(|(c, e)| format!("{}: {:?}", c.drone_id(), e.status(c).last_error))
        .collect();
    println!(
        "{DRONES} drones, tick period {:?}, mission errors {ended:?}",
        host.tick_period()
    );
    println!("| phase | ticks | p50 ms | p99 ms | max ms |");
    println!("|---|---|---|---|---|");
    for (phase, name) in [
        (0, "go_to (no planning)"),
        (1, "navigate_to, a plan per drone per second"),
    ] {
        let mut v: Vec<f64> = s
            .intervals
            .iter()
            .filter(|(p, _)| *p == phase)
            .map(|(_, ms)| *ms)
            .collect();
        v.sort_by(f64::total_cmp);
        println!(
            "| {name} | {} | {:.2} | {:.2} | {:.2} |",
            v.len(),
            percentile(&v, 0.5),
            percentile(&v, 0.99),
            v.last().copied().unwrap_or(f64::NAN)
        );
    }
}
