//! Memory of a drone's full mission store (issue 29, item 10): 64 missions (`MAX_MISSIONS`),
//! each the largest that validates within the API's default body limit (13 `follow_path` items
//! of 10 000 waypoints, 1 MiB), loaded into a simulated host with its state directory, written,
//! then read back from the directory as at a restart; and what starting such an item costs on
//! the control loop now that its goal is derived again from its text.
//!
//! Run: `cargo bench --bench mission_memory` (`--profile dev` for the figures in BENCHMARKS.md,
//! "Memory of a stored mission"). Prints the bytes held (counted by a counting global
//! allocator) and the process's resident memory after each step, and the time per item start.

use kestrel::config::Config;
use kestrel::host::store;
use kestrel::host::LoadOptions;
use kestrel::mission::executor::MAX_MISSIONS;
use kestrel::mission::Limits;
use kestrel::scenario::sim_host::simulated_host;
use kestrel::sim::world::World;
use serde_json::Value;
use stats_alloc::{StatsAlloc, INSTRUMENTED_SYSTEM};
use std::alloc::System;
use std::time::{Duration, Instant};

#[global_allocator]
static GLOBAL: &StatsAlloc<System> = &INSTRUMENTED_SYSTEM;

/// Item starts timed.
const STARTS: u32 = 20;

fn live_bytes() -> i128 {
    let s = GLOBAL.stats();
    s.bytes_allocated as i128 - s.bytes_deallocated as i128
}

fn resident_mb() -> f64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let kb = status
        .lines()
        .find_map(|l| l.strip_prefix("VmRSS:"))
        .and_then(|v| v.trim().trim_end_matches("kB").trim().parse::<f64>().ok())
        .unwrap_or(0.0);
    kb / 1024.0
}

fn mb(bytes: i128) -> f64 {
    bytes as f64 / 1e6
}

/// The largest mission of waypoints within `budget` bytes.
fn largest_mission(budget: usize) -> String {
    let limits = Limits::default();
    let path = vec!["[0,0,1]"; limits.max_waypoints].join(",");
    let item = format!(r#"{{"behavior":"follow_path","args":{{"path":[{path}],"speed":1}}}}"#);
    let mut text = String::from(r#"{"target":"drone_0","plan":["#);
    for k in 0..limits.max_items {
        if text.len() + item.len() + 3 > budget {
            break;
        }
        if k > 0 {
            text.push(',');
        }
        text.push_str(&item);
    }
    text.push_str("]}");
    text
}

fn main() {
    let config = Config::default();
    let text = largest_mission(config.api.max_body_bytes);
    let mission: Value = serde_json::from_str(&text).unwrap_or_else(|e| panic!("{e}"));
    let state_dir = tempfile::tempdir().unwrap_or_else(|e| panic!("{e}"));
    let mut host = simulated_host(World::empty(), 1, 1, &config);
    let (_, report) =
        store::load(state_dir.path(), &host.drone_ids()).unwrap_or_else(|e| panic!("{e}"));
    let sink = store::Sink::start(state_dir.path(), report).unwrap_or_else(|e| panic!("{e}"));
    host.set_store(sink.clone());
    host.step();
    println!(
        "mission: {} bytes of JSON; {MAX_MISSIONS} of them: {:.1} MB",
        text.len(),
        mb((text.len() * MAX_MISSIONS) as i128)
    );
    let rt = tokio::runtime::Builder::new_current_thread()
        .enable_time()
        .build()
        .unwrap_or_else(|e| panic!("{e}"));
    // The host's own growth over as many steps with no mission, to tell it apart.
    let before = live_bytes();
    for _ in 0..MAX_MISSIONS {
        host.step();
    }
    println!(
        "{MAX_MISSIONS} steps without a mission: {:.1} MB",
        mb(live_bytes() - before)
    );
    let before = live_bytes();
    let rss_before = resident_mb();
    for _ in 0..MAX_MISSIONS {
        host.load_mission(&mission, LoadOptions::default())
            .unwrap_or_else(|e| panic!("{e}"));
        host.step();
        // Written, and the writer done with it.
        let saved = rt.block_on(sink.saved(Duration::from_secs(60)));
        assert_eq!(saved, store::Saved::Durable);
    }
    let held = live_bytes() - before;
    println!(
        "{MAX_MISSIONS} loaded and written: {:.1} MB held ({:.2}x their JSON); resident {:.0} -> {:.0} MB",
        mb(held),
        held as f64 / (text.len() * MAX_MISSIONS) as f64,
        rss_before,
        resident_mb()
    );

    let before = live_bytes();
    let (state, _) =
        store::load(state_dir.path(), &host.drone_ids()).unwrap_or_else(|e| panic!("{e}"));
    let restored = live_bytes() - before;
    println!(
        "read back from the state directory: {:.1} MB held ({:.2}x)",
        mb(restored),
        restored as f64 / (text.len() * MAX_MISSIONS) as f64
    );
    drop(state);

    let executor = &host.executors()[0];
    let item = executor
        .missions()
        .values()
        .next()
        .and_then(|l| l.mission.items.first())
        .unwrap_or_else(|| panic!("no item loaded"));
    let registry = kestrel::behavior::Registry::with_motion_behaviors();
    let spec = registry
        .get("follow_path")
        .unwrap_or_else(|| panic!("no follow_path"));
    let started = Instant::now();
    for _ in 0..STARTS {
        let goal = item.goal().unwrap_or_else(|e| panic!("{e}"));
        (spec.parse)(&goal).unwrap_or_else(|e| panic!("{e}"));
    }
    println!(
        "starting an item of 10 000 waypoints (its goal derived and parsed): {:.2} ms",
        started.elapsed().as_secs_f64() * 1e3 / f64::from(STARTS)
    );
    // Before, a start cloned the item (three value trees of its waypoints, the typed goal and
    // a point per waypoint) and parsed nothing: the trees' clone is most of that.
    let goal = item.goal().unwrap_or_else(|e| panic!("{e}"));
    let started = Instant::now();
    for _ in 0..STARTS {
        let copies = [goal.clone(), goal.clone(), goal.clone()];
        std::hint::black_box(&copies);
    }
    println!(
        "for comparison, three clones of its goal's value tree: {:.2} ms",
        started.elapsed().as_secs_f64() * 1e3 / f64::from(STARTS)
    );
}
