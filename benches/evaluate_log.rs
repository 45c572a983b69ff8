//! Benchmark (BENCHMARKS.md, "Exploration metrics of a large log"): parsing and evaluating a
//! 7-drone, 600 s flight log at 20 Hz (84 000 poses) against the thesis's high-density world.
//!
//!     cargo bench --bench evaluate_log

use kestrel::exploration::offline::evaluate::{evaluate, poses_from_log, EvalParams};
use kestrel::sim::world::World;
use serde_json::json;
use std::path::Path;
use std::time::Instant;

fn pose(t: f64, drone: &str, x: f64, y: f64, z: f64, yaw: f64) -> String {
    json!({"t": t, "drone": drone, "type": "pose", "x": x, "y": y, "z": z, "yaw": yaw,
           "vx": 0.0, "vy": 0.0, "vz": 0.0, "armed": z > 0.0, "flight": "flying", "behavior": null})
    .to_string()
}

/// A lawnmower with a spin: 7 drones, 600 s at 20 Hz.
fn large_log() -> String {
    let mut lines = Vec::with_capacity(7 * 12_000);
    for k in 0..12_000u32 {
        let t = f64::from(k) * 0.05;
        for d in 0..7u32 {
            let lane = f64::from(d) * 7.0 - 21.0;
            let along = (t * 0.75) % 96.0;
            let x = if along < 48.0 {
                -24.0 + along
            } else {
                72.0 - along
            };
            let y = lane + 2.0 * (t * 0.05).sin();
            let z = if (2.0..=598.0).contains(&t) { 1.0 } else { 0.0 };
            lines.push(pose(t, &format!("d{d}"), x, y, z, 0.5 * t));
        }
    }
    lines.join("\n")
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("evaluate_log: run it with `cargo bench --bench evaluate_log`");
        return;
    }
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/high.json");
    let world = World::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let text = large_log();
    for run in 1..=3 {
        let started = Instant::now();
        let samples = poses_from_log(&text).unwrap_or_else(|e| panic!("{e}"));
        let parsed = started.elapsed();
        let m =
            evaluate(&world, &samples, &EvalParams::default()).unwrap_or_else(|e| panic!("{e}"));
        let total = started.elapsed();
        assert_eq!((samples.len(), m.drones_flown), (84_000, 7));
        println!(
            "run {run}: {} samples ({} MB): parse {:.2} s, total {:.2} s; area {:.1} %",
            samples.len(),
            text.len() / 1_000_000,
            parsed.as_secs_f64(),
            total.as_secs_f64(),
            m.area_pct,
        );
    }
}
