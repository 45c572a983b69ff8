//! Convergence with the default profiles, as on a real autopilot: the real `kestrel run` flies
//! takeoff, a path-facing `go_to`, a path-facing `follow_path`, another `go_to` and `land`
//! against both fake autopilots, with the telemetry delayed 50 ms plus a further 0-50 ms of
//! jitter (up to 100 ms in all), in several seeded runs. In every run every goal is reached
//! within 0.1 m (the fake's true position), the vehicle lands within 0.1 m of where it was
//! told to, and its true horizontal speed never exceeds the behaviors' `speed` by more than 3 %.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::{alongside, closest_approaches, Fake, Kestrel, Personality};
use serde_json::{json, Value};
use std::time::Duration;

const SEEDS: [u64; 3] = [1, 2, 3];
const SPEED_MPS: f64 = 1.0;
const HEIGHT_M: f64 = 3.0;

fn mission() -> Value {
    json!({
        "target": "drone_0",
        "plan": [
            {"behavior": "takeoff", "args": {"height": HEIGHT_M, "speed": 1.0}},
            {"behavior": "go_to", "method": "go_to_path_facing",
             "args": {"x": 5.0, "y": 0.0, "z": HEIGHT_M, "speed": SPEED_MPS}},
            {"behavior": "follow_path", "method": "follow_path_with_path_facing",
             "args": {"path": [[5.0, 4.0, HEIGHT_M], [1.0, 4.0, HEIGHT_M]], "speed": SPEED_MPS}},
            {"behavior": "go_to", "method": "go_to_path_facing",
             "args": {"x": 1.0, "y": 1.5, "z": HEIGHT_M, "speed": SPEED_MPS}},
            {"behavior": "land", "args": {"speed": 0.5}}
        ]
    })
}

/// The points flown through in order (the fake starts at the origin facing east), each with
/// how near the vehicle must come (m): every item's goal 0.1; the path's corner is a waypoint
/// passed on a smooth trajectory that rounds it, not a goal (within half a metre).
fn targets() -> Vec<([f64; 3], f64)> {
    vec![
        ([0.0, 0.0, HEIGHT_M], 0.1),
        ([5.0, 0.0, HEIGHT_M], 0.1),
        ([5.0, 4.0, HEIGHT_M], 0.5),
        ([1.0, 4.0, HEIGHT_M], 0.1),
        ([1.0, 1.5, HEIGHT_M], 0.1),
    ]
}

fn local(sample: &Value, key: &str) -> [f64; 3] {
    let v = |k: &str, i: usize| sample[k][i].as_f64().unwrap();
    let o = |i: usize| sample["local_origin_enu_m"][i].as_f64().unwrap_or(0.0);
    match key {
        "position_enu_m" => [0, 1, 2].map(|i| v(key, i) - o(i)),
        _ => [0, 1, 2].map(|i| v(key, i)),
    }
}

fn fly(p: Personality, seed: u64) {
    fly_with(p, p.profile(), seed);
}

fn fly_with(p: Personality, profile: &str, seed: u64) {
    let seed_arg = seed.to_string();
    let fake = Fake::start(
        p,
        &[
            "--seed",
            &seed_arg,
            "--latency-ms",
            "50",
            "--telemetry-jitter-ms",
            "50",
        ],
    );
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("mission.json");
    std::fs::write(&file, mission().to_string()).unwrap();
    let poller = fake.poll_states();
    let mut kestrel = Kestrel::run_with_platform(
        profile,
        &fake.connection,
        "",
        &[
            "--mission",
            file.to_str().unwrap(),
            "--no-api",
            "--exit-when-done",
            "--max-time-s",
            "150",
        ],
    );
    let status = kestrel.wait(Duration::from_secs(170));
    let samples = poller.finish();
    assert!(
        status.success(),
        "{p:?} seed {seed}: the mission failed:\n{}\n{}",
        kestrel.output(),
        fake.diagnostics()
    );
    let points: Vec<[f64; 3]> = targets().iter().map(|(p, _)| *p).collect();
    let approaches = closest_approaches(&samples, &points);
    for ((target, within), d) in targets().iter().zip(&approaches) {
        assert!(
            d <= within,
            "{p:?} seed {seed}: goal {target:?} missed by {d:.3} m (all: {approaches:.3?})\n{}",
            kestrel.output()
        );
    }
    let end = fake.state();
    assert_eq!(end["on_ground"], true, "{p:?} seed {seed}: {end}");
    let touchdown = local(&end, "position_enu_m");
    let land_at = points[4];
    let off = (touchdown[0] - land_at[0]).hypot(touchdown[1] - land_at[1]);
    assert!(
        off <= 0.1,
        "{p:?} seed {seed}: landed {off:.3} m from {land_at:?} at {touchdown:?}"
    );
    let fastest = samples
        .iter()
        .map(|s| {
            let v = local(s, "velocity_enu_mps");
            v[0].hypot(v[1])
        })
        .fold(0.0, f64::max);
    assert!(
        fastest <= SPEED_MPS * 1.03,
        "{p:?} seed {seed}: flew {fastest:.3} m/s horizontally, limit {SPEED_MPS} m/s"
    );
    println!(
        "{p:?} seed {seed}: closest approaches {approaches:.3?} m, touchdown {off:.3} m off, \
         fastest {fastest:.3} m/s"
    );
}

#[test]
fn px4_converges_on_every_goal_with_telemetry_jitter_in_every_seeded_run() {
    let _alongside = alongside();
    for seed in SEEDS {
        fly(Personality::Px4, seed);
    }
}

#[test]
fn ardupilot_converges_on_every_goal_with_telemetry_jitter_in_every_seeded_run() {
    let _alongside = alongside();
    for seed in SEEDS {
        fly(Personality::Ardupilot, seed);
    }
}

/// The other way of driving (`[drive] setpoints = "position_target"`: a moving reference point
/// held by the autopilot's own position loop) converges as well.
#[test]
fn px4_driven_by_position_targets_converges_too() {
    let _alongside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let profile = dir.path().join("px4-position-targets.toml");
    let text = std::fs::read_to_string(mavlink_support::repo().join("platforms/px4.toml"))
        .unwrap()
        .replace(
            "setpoints = \"velocity\"",
            "setpoints = \"position_target\"",
        );
    assert!(text.contains("position_target"));
    std::fs::write(&profile, text).unwrap();
    fly_with(Personality::Px4, profile.to_str().unwrap(), 1);
}
