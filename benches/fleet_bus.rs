//! Benchmark (BENCHMARKS.md, "Fleet bus"): three `kestrel run` processes, each with its own fake
//! PX4, on one fleet bus over localhost, idle on the ground and then through a three-drone
//! exploration of three bays (`FLEET_BUS_ARENA`: `bays30`, three 10 x 10 m bays, the default;
//! `bays18`, the 6 x 6 m bays of tests/fleet_bus_e2e.rs). Reads each node's bus report
//! (`fleet_bus` in `GET /api/status`): bytes sent per second for drone states and for map
//! regions (one drone per node, so per drone), and the latency from a peer sending a state to this
//! node taking it in, p50 and p99. Then one Kestrel explores the same bays alone with one drone,
//! and both flights are judged from their flight logs by `kestrel evaluate` (the three nodes'
//! logs as one flight): time from the first take-off to the last landing, area, and the ratio
//! of the times. Needs the fake autopilot's venv (`bash sitl/setup.sh`).
//!
//!     cargo bench --bench fleet_bus     (FLEET_BUS_RUNS=N: N rounds, default 1;
//!                                         FLEET_BUS_ARENA=bays18|bays30)

#[path = "../tests/mavlink_support/mod.rs"]
mod mavlink_support;
#[path = "../tests/support/mod.rs"]
mod support;

use mavlink_support::bus::{Arena, Fleet, BAYS, BAYS30};
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

/// Share of the observable area both flights are timed to as well (%): the end of an
/// exploration depends on which last frontiers are left, this does not.
const COMMON_PCT: f64 = 95.0;

/// One line about a flight judged by `kestrel evaluate`; returns its time to the end and its
/// time to `COMMON_PCT` % of the observable area (s, from the first take-off).
fn judged(name: &str, m: &Value) -> (f64, f64) {
    let nan = f64::NAN;
    let time = m["time_s"].as_f64().unwrap_or(nan);
    let takeoff = m["first_takeoff_s"].as_f64().unwrap_or(nan);
    // area_pct is of the whole grid; the observable area is observable_share_pct of it.
    let target = COMMON_PCT / 100.0 * m["observable_share_pct"].as_f64().unwrap_or(nan);
    let to_common = m["area_curve"]
        .as_array()
        .and_then(|c| {
            c.iter()
                .find(|p| p["area_pct"].as_f64().unwrap_or(0.0) >= target)
                .and_then(|p| p["t_s"].as_f64())
        })
        .map_or(nan, |t| t - takeoff);
    println!(
        "{name}: first take-off to last landing {time:.1} s, to {COMMON_PCT} % of the observable \
         area {to_common:.1} s; area {:.1} % of the observable, path {:.0} m, collisions {}, \
         least separation {} m",
        m["observable_pct"].as_f64().unwrap_or(nan),
        m["path_m"].as_f64().unwrap_or(nan),
        m["collisions"],
        m["min_separation_m"],
    );
    (time, to_common)
}

/// Three nodes on the bus, then one drone alone; returns their times (s).
fn round(arena: &Arena) -> ((f64, f64), (f64, f64)) {
    let world_path = repo().join(arena.world);
    let world = world_path.as_path();
    let (fake, connections) = Fake::start_px4_fleet(
        3,
        &["--world", world.to_str().unwrap_or(""), "--rangers", "cf4"],
    );
    let fleet = Fleet::start(arena, &connections);
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
    std::thread::sleep(Duration::from_secs(1));
    let three = judged("three nodes", &fleet.evaluate(&[0, 1, 2], world));
    drop(fleet);
    drop(fake);

    let (fake, connections) = Fake::start_px4_fleet(
        1,
        &["--world", world.to_str().unwrap_or(""), "--rangers", "cf4"],
    );
    let alone = Fleet::start_alone(arena, &connections[0]);
    alone.wait_joined(&[0]);
    alone.explore(0);
    alone.wait_explored(&[0], &fake);
    std::thread::sleep(Duration::from_secs(1));
    let one = judged("one drone alone", &alone.evaluate(&[0], world));
    (three, one)
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("fleet_bus: run it with `cargo bench --bench fleet_bus`");
        return;
    }
    let arena = match std::env::var("FLEET_BUS_ARENA").as_deref() {
        Ok("bays18") => BAYS,
        Ok("bays30") | Err(_) => BAYS30,
        Ok(other) => panic!("FLEET_BUS_ARENA: unknown arena `{other}`: use bays18 or bays30"),
    };
    println!("arena: {}", arena.world);
    let rounds: usize = std::env::var("FLEET_BUS_RUNS")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(1);
    let mut ratios = Vec::new();
    for r in 0..rounds {
        println!("== round {} of {rounds}", r + 1);
        let (three, one) = round(&arena);
        let ratio = (three.0 / one.0, three.1 / one.1);
        ratios.push(ratio);
        println!(
            "three nodes / one drone: {:.2} to the end, {:.2} to {COMMON_PCT} % of the observable area",
            ratio.0, ratio.1
        );
    }
    println!("ratios (to the end, to {COMMON_PCT} %): {ratios:.2?}");
}
