//! Benchmark (BENCHMARKS.md, "Fleet bus"): three `kestrel run` processes, each with its own fake
//! PX4, on one fleet bus over localhost (sitl/worlds/bays18_fleet.json, as tests/fleet_bus_e2e.rs),
//! idle on the ground and then through a three-drone exploration. Reads each node's bus report
//! (`fleet_bus` in `GET /api/status`): bytes sent per second for drone states and for map
//! regions (one drone per node, so per drone), and the latency from a peer sending a state to this
//! node taking it in, p50 and p99. Needs the fake autopilot's venv (`bash sitl/setup.sh`).
//!
//!     cargo bench --bench fleet_bus

#[path = "../tests/mavlink_support/mod.rs"]
mod mavlink_support;
#[path = "../tests/support/mod.rs"]
mod support;

use mavlink_support::bus::{Fleet, WORLD};
use mavlink_support::{repo, Fake};
use serde_json::Value;
use std::time::{Duration, Instant};

/// Each node's bus report and when it was read.
fn reports(fleet: &Fleet) -> Vec<(Instant, Value)> {
    fleet
        .apis
        .iter()
        .map(|a| (Instant::now(), a.get("/api/status")["fleet_bus"].clone()))
        .collect()
}

fn rate(a: &(Instant, Value), b: &(Instant, Value), key: &str) -> f64 {
    let d = b.1[key].as_f64().unwrap_or(0.0) - a.1[key].as_f64().unwrap_or(0.0);
    d / b.0.duration_since(a.0).as_secs_f64()
}

fn print_phase(name: &str, before: &[(Instant, Value)], after: &[(Instant, Value)]) {
    println!("{name}:");
    for (i, (a, b)) in before.iter().zip(after).enumerate() {
        println!(
            "  node_{i}: state {:.0} B/s ({:.1} msg/s), map {:.0} B/s ({:.1} msg/s), received {:.0} B/s; \
             latency p50 {} ms, p99 {} ms over the last {} states",
            rate(a, b, "state_sent_bytes"),
            rate(a, b, "state_sent"),
            rate(a, b, "map_sent_bytes"),
            rate(a, b, "map_sent"),
            rate(a, b, "received_bytes"),
            b.1["latency_p50_ms"],
            b.1["latency_p99_ms"],
            b.1["latency_samples"],
        );
    }
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("fleet_bus: run it with `cargo bench --bench fleet_bus`");
        return;
    }
    let world = repo().join(WORLD);
    let (fake, connections) = Fake::start_px4_fleet(
        3,
        &["--world", world.to_str().unwrap_or(""), "--rangers", "cf4"],
    );
    let fleet = Fleet::start(&connections);
    fleet.wait_joined(&[0, 1, 2]);
    let idle_start = reports(&fleet);
    std::thread::sleep(Duration::from_secs(20));
    let idle_end = reports(&fleet);
    print_phase("on the ground, 20 s", &idle_start, &idle_end);
    let started = Instant::now();
    for i in 0..3 {
        fleet.explore(i);
    }
    fleet.wait_explored(&[0, 1, 2], &fake);
    let end = reports(&fleet);
    print_phase(
        &format!("exploring, {:.0} s", started.elapsed().as_secs_f64()),
        &idle_end,
        &end,
    );
}
