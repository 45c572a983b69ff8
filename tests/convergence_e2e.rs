//! Convergence with the default profiles, as on a real autopilot: the real `kestrel run` flies
//! takeoff, a path-facing `go_to`, a path-facing `follow_path`, another `go_to` and `land`
//! against both fake autopilots, with the telemetry delayed 50 ms plus a further 0-50 ms of
//! jitter (up to 100 ms in all) and the autopilot's own hold wandering as real PX4 SIH's does,
//! in several seeded runs. In every run every goal is reached
//! within 0.1 m (the fake's true position), the vehicle lands within 0.1 m of the last goal
//! (with the wander: goals within 0.15 m of the truth, touchdown within 0.2 m), and its true horizontal speed never exceeds the behaviors'
//! `speed` by more than 3 %. One test per seeded run, so that the runs fly side by side.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::{alongside, closest_approaches, Fake, Kestrel, Personality};
use serde_json::{json, Value};
use std::time::Duration;

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
/// how near the vehicle must come (m): every item's goal 0.1; takeoff's is a height (the
/// autopilot's wander may carry it sideways while it climbs) and the path's corner a waypoint
/// passed on a smooth trajectory that rounds it (both within half a metre).
fn targets() -> Vec<([f64; 3], f64)> {
    vec![
        ([0.0, 0.0, HEIGHT_M], 0.5),
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

/// The autopilot's own velocity-tracking error (m/s, the fakes' `--velocity-wander-mps`): with
/// 0.25 the fake holds its own position to p50 0.24 m, p95 0.54 m, as real PX4 SIH did here.
const WANDER_MPS: &str = "0.25";

/// How near its last goal the vehicle touches down (m): within 0.1 m on an autopilot that holds
/// its position. With the wander, Kestrel flies the descent (PX4's `land = "setpoints"`) and waits
/// near the ground until it is over its point again, but the autopilot's drift in the last
/// few decimetres is not all taken out: within 0.2 m.
const TOUCHDOWN_M: f64 = 0.1;
const TOUCHDOWN_WANDERING_M: f64 = 0.2;

fn fly(p: Personality, seed: u64) {
    fly_with(p, p.profile(), seed, &[], HOLDS);
}

/// How near each point the vehicle must come, and how near its last goal it touches down (m).
#[derive(Clone, Copy)]
struct Tolerance {
    /// Added to each point's own tolerance (`targets`).
    slack_m: f64,
    touchdown_m: f64,
}

/// An autopilot that holds its position: every goal within 0.1 m, touchdown within 0.1 m.
const HOLDS: Tolerance = Tolerance {
    slack_m: 0.0,
    touchdown_m: TOUCHDOWN_M,
};

/// With the wander, Kestrel sees the vehicle 50-100 ms late while the autopilot's own drift
/// moves it at up to about 0.5 m/s: a goal Kestrel saw reached within 0.1 m may be up to 0.05 m
/// further in truth (seen: 0.100 m in 12 runs). Touchdown as `TOUCHDOWN_WANDERING_M`.
const WANDERS: Tolerance = Tolerance {
    slack_m: 0.05,
    touchdown_m: TOUCHDOWN_WANDERING_M,
};

fn fly_with(p: Personality, profile: &str, seed: u64, fake_args: &[&str], tolerance: Tolerance) {
    let Tolerance {
        slack_m,
        touchdown_m,
    } = tolerance;
    let seed_arg = seed.to_string();
    let mut args = vec![
        "--seed",
        &seed_arg,
        "--latency-ms",
        "50",
        "--telemetry-jitter-ms",
        "50",
    ];
    args.extend_from_slice(fake_args);
    let fake = Fake::start(p, &args);
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
            *d <= within + slack_m,
            "{p:?} seed {seed}: goal {target:?} missed by {d:.3} m (all: {approaches:.3?})\n{}",
            kestrel.output()
        );
    }
    let end = fake.state();
    assert_eq!(end["on_ground"], true, "{p:?} seed {seed}: {end}");
    let touchdown = local(&end, "position_enu_m");
    // The vehicle lands where its last go_to took it: with `land = "mode"` where the autopilot's
    // own land mode stops it, with `"setpoints"` under the go_to's goal, flown by Kestrel.
    let log = kestrel.flight_log();
    let land_at = [points[4][0], points[4][1]];
    let off = (touchdown[0] - land_at[0]).hypot(touchdown[1] - land_at[1]);
    assert!(
        off <= touchdown_m,
        "{p:?} seed {seed}: landed {off:.3} m from {land_at:?} at {touchdown:?}\n{}\n{}",
        kestrel.output(),
        fake.diagnostics()
    );
    // What the vehicle flew (the fake's truth), and what Kestrel asked for: with the autopilot's
    // own wander on top, only the command is Kestrel's to keep within the limit.
    let fastest = samples
        .iter()
        .map(|s| {
            let v = local(s, "velocity_enu_mps");
            v[0].hypot(v[1])
        })
        .fold(0.0, f64::max);
    let commanded = log
        .iter()
        .filter_map(|r| r["setpoint"]["velocity_enu_mps"].as_array().cloned())
        .map(|v| v[0].as_f64().unwrap().hypot(v[1].as_f64().unwrap()))
        .fold(0.0, f64::max);
    assert!(
        commanded <= SPEED_MPS + 1e-6,
        "{p:?} seed {seed}: commanded {commanded:.3} m/s horizontally, limit {SPEED_MPS} m/s"
    );
    let flown_limit = if fake_args.is_empty() {
        SPEED_MPS * 1.03
    } else {
        f64::INFINITY
    };
    assert!(
        fastest <= flown_limit,
        "{p:?} seed {seed}: flew {fastest:.3} m/s horizontally, limit {SPEED_MPS} m/s"
    );
    println!(
        "{p:?} seed {seed}: closest approaches {approaches:.3?} m, touchdown {off:.3} m off, \
         fastest {fastest:.3} m/s, commanded at most {commanded:.3} m/s"
    );
}

/// Each seeded run of one autopilot, as its own test.
macro_rules! seeded_runs {
    ($personality:expr, $($name:ident: $seed:expr),+) => {$(
        #[test]
        fn $name() {
            let _alongside = alongside();
            fly($personality, $seed);
        }
    )+};
}

// Two seeds per personality (about a minute each, on CI's 30-minute budget); seed 3 of each
// ran in CI until 2026-11-27 and passed every time (BENCHMARKS.md, "The fakes with telemetry").
seeded_runs!(Personality::Px4,
    px4_converges_on_every_goal_with_telemetry_jitter_seed_1: 1,
    px4_converges_on_every_goal_with_telemetry_jitter_seed_2: 2);
seeded_runs!(Personality::Ardupilot,
    ardupilot_converges_on_every_goal_with_telemetry_jitter_seed_1: 1,
    ardupilot_converges_on_every_goal_with_telemetry_jitter_seed_2: 2);

/// The other way of driving (`[drive] setpoints = "position_target"`: a moving reference point
/// held by the autopilot's own position loop) converges as well on an autopilot that holds its
/// position well (no wander: with it, as on real PX4 SIH, the autopilot's P-only loop does not
/// end within 0.1 m, which is why the profiles drive with velocities).
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
    fly_with(Personality::Px4, profile.to_str().unwrap(), 1, &[], HOLDS);
}

/// PX4 whose own hold wanders as real PX4 SIH's did: its velocity estimate is off by the wander
/// (its velocity loop holds the estimate at the command, so the vehicle flies command plus
/// wander while the reported velocity shows the command; the position stays true). Kestrel's
/// velocity check (`[drive] velocity_check_s`) finds that from the position: every goal still
/// reached (`WANDERS`). It
/// lands on Kestrel's setpoints (`land = "setpoints"`, the profile's option): PX4's own
/// AUTO.LAND drifts with the wander (up to 0.6 m), which Kestrel cannot correct.
fn fly_wandering(seed: u64) {
    let _alongside = alongside();
    let dir = tempfile::tempdir().unwrap();
    let profile = dir.path().join("px4-land-on-setpoints.toml");
    let text = std::fs::read_to_string(mavlink_support::repo().join("platforms/px4.toml"))
        .unwrap()
        .replace("land = \"mode\"", "land = \"setpoints\"");
    assert!(text.contains("land = \"setpoints\""));
    std::fs::write(&profile, text).unwrap();
    fly_with(
        Personality::Px4,
        profile.to_str().unwrap(),
        seed,
        &[
            "--velocity-wander-mps",
            WANDER_MPS,
            "--velocity-wander-in-estimate",
        ],
        WANDERS,
    );
}

#[test]
fn px4_converges_on_every_goal_while_its_own_hold_wanders_seed_4() {
    fly_wandering(4);
}

#[test]
fn px4_converges_on_every_goal_while_its_own_hold_wanders_seed_5() {
    fly_wandering(5);
}
