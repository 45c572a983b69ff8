//! The exploration evaluator end to end: the real `kestrel` binary generates a world and
//! evaluates a hand-written flight log in it; an ignored test times a large log in process.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kestrel::sim::world::World;
use serde_json::{json, Value};
use std::process::Command;

fn kestrel(args: &[&str]) -> String {
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(args)
        .output()
        .unwrap();
    assert!(
        out.status.success(),
        "kestrel {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8(out.stdout).unwrap()
}

/// One pose record as `kestrel sim` writes it.
fn pose(t: f64, drone: &str, x: f64, y: f64, z: f64, yaw: f64) -> String {
    json!({"t": t, "drone": drone, "type": "pose", "x": x, "y": y, "z": z, "yaw": yaw,
           "vx": 0.0, "vy": 0.0, "vz": 0.0, "armed": z > 0.0, "flight": "flying", "behavior": null})
    .to_string()
}

#[test]
fn generate_a_world_then_evaluate_a_log_flown_in_it() {
    let dir = tempfile::tempdir().unwrap();
    let world_path = dir.path().join("w.json");
    let w = world_path.to_str().unwrap();
    kestrel(&[
        "world",
        "generate",
        "--size-m",
        "20",
        "--density",
        "0.1",
        "--seed",
        "7",
        "--out",
        w,
    ]);
    let world = World::load(&world_path).unwrap();
    assert_eq!(world.poles_xy_m.len(), 40);
    let [x0, y0, yaw0] = world.starts_xy_yaw["2"][0];
    let [x1, y1, _] = world.starts_xy_yaw["2"][1];

    // d0 takes off at 1 s, turns a quarter turn, lands at 12 s; d1 hovers from 2 s to 4 s.
    let mut lines = vec![
        r#"{"t":0.0,"drone":"d0","type":"command","command":"start","fields":{}}"#.to_string(),
    ];
    for k in 0..=130 {
        let t = f64::from(k) * 0.1;
        let z = if (1.0..=12.0).contains(&t) { 1.0 } else { 0.0 };
        let yaw = yaw0 + std::f64::consts::FRAC_PI_2 * (t / 13.0);
        lines.push(pose(t, "d0", x0, y0, z, yaw));
        let z1 = if (2.0..=4.0).contains(&t) { 1.0 } else { 0.0 };
        lines.push(pose(t, "d1", x1, y1, z1, 0.0));
    }
    lines.push(r#"{"t":13.0,"drone":"d0","type":"behavior","event":"finished"}"#.to_string());
    let log_path = dir.path().join("flight.jsonl");
    std::fs::write(&log_path, lines.join("\n")).unwrap();
    let report_path = dir.path().join("report.json");
    let summary = kestrel(&[
        "evaluate",
        "--world",
        w,
        "--log",
        log_path.to_str().unwrap(),
        "--out",
        report_path.to_str().unwrap(),
    ]);
    assert!(summary.contains("area"), "{summary}");
    let m: Value = serde_json::from_str(&std::fs::read_to_string(&report_path).unwrap()).unwrap();
    assert_eq!(m["drones_flown"], 2);
    assert!(
        (m["first_takeoff_s"].as_f64().unwrap() - 1.0).abs() < 1e-9,
        "{m}"
    );
    assert!((m["time_s"].as_f64().unwrap() - 11.0).abs() < 1e-9, "{m}");
    let area = m["area_pct"].as_f64().unwrap();
    assert!(
        area > 5.0 && area < 15.0,
        "one disc of 4 m and a few beams: {area}"
    );
    assert!(m["observable_share_pct"].as_f64().unwrap() > 90.0);
    assert_eq!(m["path_m"], 0.0);
    assert!(m["min_obstacle_clearance_m"].as_f64().unwrap() >= 1.75);
    let sep = m["min_separation_m"].as_f64().unwrap();
    assert!(sep >= 2.4 - 1e-9, "starts are 2.4 m apart: {sep}");
    assert_eq!(m["collisions"], 0);
    assert_eq!(m["drones"].as_array().unwrap().len(), 2);
}
