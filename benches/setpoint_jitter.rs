//! Benchmark (BENCHMARKS.md, "MAVLink"): the 50 Hz setpoint stream of `kestrel run` as the fake
//! PX4 receives it, from the end of the takeoff to the start of the landing (go_to and
//! follow_path in OFFBOARD). Needs the fake autopilot's venv (`bash sitl/setup.sh`).
//!
//!     cargo bench --bench setpoint_jitter

#[path = "../tests/mavlink_support/mod.rs"]
mod mavlink_support;
#[path = "../tests/support/mod.rs"]
mod support;

use mavlink_support::{Fake, Kestrel, Personality, DEMO};
use serde_json::json;
use std::time::Duration;

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("setpoint_jitter: run it with `cargo bench --bench setpoint_jitter`");
        return;
    }
    let p = Personality::Px4;
    let fake = Fake::start(p, &[]);
    let mut kestrel = Kestrel::run(p, &fake.connection, "", DEMO);
    kestrel.wait_line("takeoff #1 succeeded", Duration::from_secs(60));
    fake.cmd(json!({"cmd": "setpoint_stats", "reset": true}));
    kestrel.wait_line("land #4 started", Duration::from_secs(60));
    let stats = fake.cmd(json!({"cmd": "setpoint_stats"}));
    println!("setpoint stream at 50 Hz seen by the fake during go_to + follow_path: {stats}");
    let status = kestrel.wait(Duration::from_secs(120));
    assert!(status.success(), "{}", kestrel.output());
}
