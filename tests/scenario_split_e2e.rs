//! `kestrel sim --scenario missions/scenarios/solar_park.json --drones 3` splits the park among
//! the three drones (the thesis's multi-drone solar-park inspection): together they fly every
//! street of the sweep, each only a part of it, and they keep apart.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use serde_json::Value;
use std::collections::BTreeMap;
use std::process::Command;
use support::free_tcp_port;

/// The park's frame in `earth` (missions/scenarios/solar_park.json).
const PARK_ORIGIN_M: [f64; 2] = [20.0, 10.0];
const PARK_YAW_RAD: f64 = 0.3;

fn park_to_earth(x: f64, y: f64) -> (f64, f64) {
    let (s, c) = PARK_YAW_RAD.sin_cos();
    (
        PARK_ORIGIN_M[0] + c * x - s * y,
        PARK_ORIGIN_M[1] + s * x + c * y,
    )
}

#[test]
fn three_drones_share_the_solar_park() {
    let dir = tempfile::tempdir().unwrap();
    let log = dir.path().join("split.jsonl");
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/missions/scenarios/solar_park.json"
    );
    let listen = format!("127.0.0.1:{}", free_tcp_port());
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir.path())
        .env_remove("KESTREL_API_TOKEN")
        .args([
            "sim",
            "--scenario",
            scenario,
            "--drones",
            "3",
            "--speedup",
            "max",
        ])
        .args(["--exit-when-done", "--listen", &listen, "--log"])
        .arg(&log)
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success(), "{text}");

    let records = kestrel::flightlog::read(&std::fs::read_to_string(&log).unwrap()).unwrap();
    let mut tracks: BTreeMap<String, Vec<[f64; 4]>> = BTreeMap::new();
    for r in records.iter().filter(|r| r["type"] == "pose") {
        let f = |k: &str| r[k].as_f64().unwrap();
        tracks
            .entry(r["drone"].as_str().unwrap().to_string())
            .or_default()
            .push([r["t"].as_f64().unwrap(), f("x"), f("y"), f("z")]);
    }
    assert_eq!(tracks.len(), 3, "three drones flew");

    // Every street of the 5 m sweep (the middles of the park's four 5 m strips, y = 2.5 ...
    // 17.5), sampled every 2 m, was flown over at 8 m by some drone; by each only a part of it.
    let mut near_by: BTreeMap<&str, usize> = BTreeMap::new();
    let mut samples = 0;
    for street in 0..4 {
        for i in 0..=15 {
            let (ex, ey) = park_to_earth(2.0 * i as f64, 2.5 + 5.0 * street as f64);
            samples += 1;
            let flown_by: Vec<&str> = tracks
                .iter()
                .filter(|(_, t)| {
                    t.iter()
                        .any(|p| (p[1] - ex).hypot(p[2] - ey) < 1.0 && (p[3] - 8.0).abs() < 0.5)
                })
                .map(|(d, _)| d.as_str())
                .collect();
            assert!(
                !flown_by.is_empty(),
                "park point ({}, {}) not flown over",
                2 * i,
                2.5 + 5.0 * street as f64
            );
            for d in flown_by {
                *near_by.entry(d).or_default() += 1;
            }
        }
    }
    for (drone, n) in &near_by {
        assert!(
            *n < samples * 2 / 3,
            "{drone} flew over {n} of {samples} points: the park was not split"
        );
    }
    assert_eq!(near_by.len(), 3, "each drone swept a piece: {near_by:?}");

    // Apart all along: the closest two drones came at the same pose time.
    let ids: Vec<&String> = tracks.keys().collect();
    let mut closest = f64::INFINITY;
    for a in 0..ids.len() {
        for b in a + 1..ids.len() {
            for (p, q) in tracks[ids[a]].iter().zip(&tracks[ids[b]]) {
                if (p[0] - q[0]).abs() < 1e-6 {
                    closest = closest.min(
                        ((p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2) + (p[3] - q[3]).powi(2))
                            .sqrt(),
                    );
                }
            }
        }
    }
    assert!(closest > 1.0, "two drones came within {closest:.2} m");
    assert!(
        !records.iter().any(|r: &Value| r["type"] == "collision"),
        "collision in the log"
    );
}
