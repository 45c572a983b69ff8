//! MCAP flight logs end to end, read by an independent reader: `tests/mcap_check.py` (the
//! Python `mcap` package) checks every channel's schema, message count and content against the
//! flight's own records, for a finished `kestrel sim --log-format mcap`, a log made by
//! `kestrel log convert`, an exploration, and a sim killed with SIGKILL mid-flight. `kestrel
//! report` and `kestrel evaluate` read the MCAP logs as they read the same records in JSON lines.
//! Needs `sitl/.venv` (`bash sitl/setup.sh`, done by `.ci/run`).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Output, Stdio};
use std::time::{Duration, Instant};
use support::Process;

fn repo(path: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(path)
}

fn kestrel(dir: &Path, args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir)
        .env_remove("KESTREL_API_TOKEN")
        .args(args)
        .output()
        .unwrap()
}

fn kestrel_ok(dir: &Path, args: &[&str]) -> Output {
    let out = kestrel(dir, args);
    assert!(out.status.success(), "kestrel {args:?}: {out:?}");
    out
}

/// What `mcap_check.py` read (it fails the test on any check that does not hold).
fn python_check(file: &Path, cut: bool) -> Value {
    let python = repo("sitl/.venv/bin/python");
    assert!(
        python.exists(),
        "sitl/.venv is missing: run bash sitl/setup.sh"
    );
    let mut command = Command::new(python);
    command.arg(repo("tests/mcap_check.py")).arg(file);
    if cut {
        command.arg("--cut");
    }
    let out = command.output().unwrap();
    assert!(
        out.status.success(),
        "mcap_check.py {}: {}",
        file.display(),
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_slice(&out.stdout).unwrap()
}

fn count(summary: &Value, topic: &str) -> u64 {
    summary["channels"][topic]["count"].as_u64().unwrap_or(0)
}

/// The log's records as JSON lines, written beside it as `name`.
fn as_json_lines(log: &Path, name: &str) -> PathBuf {
    let text = kestrel::flightlog::reader::read_to_string(log, u64::MAX).unwrap();
    let out = log.with_file_name(name);
    std::fs::write(&out, text).unwrap();
    out
}

#[test]
fn a_sim_logged_as_mcap_reads_back_in_python_and_in_the_report() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let run = [
        "sim",
        "--speedup",
        "max",
        "--exit-when-done",
        "--listen",
        "127.0.0.1:0",
        "--seed",
        "5",
        "--log-format",
        "mcap",
    ];
    kestrel_ok(d, &run);
    let mut logs: Vec<PathBuf> = std::fs::read_dir(d)
        .unwrap()
        .map(|e| e.unwrap().path())
        .collect();
    logs.sort();
    assert_eq!(logs.len(), 1, "{logs:?}");
    let name = logs[0].file_name().unwrap().to_string_lossy().into_owned();
    assert!(
        name.starts_with("kestrel-sim-") && name.ends_with(".mcap"),
        "{name}"
    );
    let mcap = &logs[0];
    let summary = python_check(mcap, false);
    assert_eq!(summary["complete"], true);
    for (topic, schema) in [
        ("/kestrel/records", "kestrel.FlightLogRecord"),
        ("/tf", "foxglove.FrameTransform"),
        ("/drone_0/pose", "foxglove.PoseInFrame"),
        ("/events", "foxglove.Log"),
    ] {
        assert_eq!(summary["channels"][topic]["schema"], schema, "{summary}");
    }
    assert!(summary["poses"].as_u64().unwrap() > 100, "{summary}");
    assert!(summary["events"].as_u64().unwrap() >= 4, "{summary}");

    // The same records in JSON lines, converted back: the same channels and counts.
    let jsonl = as_json_lines(mcap, "flight.jsonl");
    kestrel_ok(d, &["log", "convert", "flight.jsonl", "--out", "conv.mcap"]);
    let converted = python_check(&d.join("conv.mcap"), false);
    assert_eq!(converted["channels"], summary["channels"]);
    let again = kestrel(d, &["log", "convert", "flight.jsonl", "--out", "conv.mcap"]);
    assert!(!again.status.success(), "an existing --out is refused");

    // The report reads both formats alike.
    kestrel_ok(d, &["report", &name, "--out", "rep-mcap"]);
    kestrel_ok(d, &["report", "flight.jsonl", "--out", "rep-jsonl"]);
    let csv = |sub: &str| std::fs::read_to_string(d.join(sub).join("poses.csv")).unwrap();
    assert_eq!(csv("rep-mcap"), csv("rep-jsonl"));
    assert!(csv("rep-mcap").lines().count() > 100);
    assert!(jsonl.exists());
}

#[test]
fn an_exploration_logged_as_mcap_is_evaluated_as_its_records() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let world = d.join("world.json").display().to_string();
    kestrel_ok(
        d,
        &[
            "world", "generate", "--size-m", "12", "--poles", "4", "--seed", "1", "--out", &world,
        ],
    );
    // 20 s of the exploration (it ends unfinished, non-zero): enough for the log, fast.
    kestrel(
        d,
        &[
            "explore",
            "--world",
            &world,
            "--drones",
            "2",
            "--max-sim-time-s",
            "20",
            "--log",
            "ex.mcap",
            "--log-format",
            "mcap",
        ],
    );
    let summary = python_check(&d.join("ex.mcap"), false);
    assert!(count(&summary, "/drone_1/pose") > 100, "{summary}");
    assert_eq!(summary["world"], 1, "the world's obstacles: {summary}");
    as_json_lines(&d.join("ex.mcap"), "ex.jsonl");
    for log in ["ex.mcap", "ex.jsonl"] {
        let out = format!("{log}.metrics.json");
        kestrel_ok(
            d,
            &["evaluate", "--world", &world, "--log", log, "--out", &out],
        );
    }
    let metrics = |f: &str| -> Value {
        serde_json::from_str(&std::fs::read_to_string(d.join(f)).unwrap()).unwrap()
    };
    let from_mcap = metrics("ex.mcap.metrics.json");
    assert_eq!(
        summary["known_cells"], from_mcap["known_cells"],
        "the log's /map/known grid is the evaluator's known map"
    );
    assert_eq!(from_mcap, metrics("ex.jsonl.metrics.json"));
    assert!(
        from_mcap["area_pct"].as_f64().unwrap() > 10.0,
        "{from_mcap}"
    );
}

#[test]
fn a_sim_killed_mid_flight_leaves_an_mcap_log_readable_to_its_last_flush() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let log = d.join("killed.mcap");
    let mut sim = Process(
        Command::new(env!("CARGO_BIN_EXE_kestrel"))
            .current_dir(d)
            .env_remove("KESTREL_API_TOKEN")
            .args(["sim", "--speedup", "10", "--listen", "127.0.0.1:0"])
            .args(["--log-format", "mcap", "--log", "killed.mcap"])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap(),
    );
    // The writer closes a chunk at least every second: wait for a few to be on disk.
    let started = Instant::now();
    let size = || std::fs::metadata(&log).map_or(0, |m| m.len());
    while (started.elapsed() < Duration::from_secs(3) || size() < 20_000)
        && started.elapsed() < Duration::from_secs(20)
    {
        std::thread::sleep(Duration::from_millis(100));
    }
    sim.0.kill().unwrap(); // SIGKILL: no summary, maybe half a chunk at the end
    sim.0.wait().unwrap();
    let summary = python_check(&log, true);
    assert!(summary["poses"].as_u64().unwrap() > 10, "{summary}");
    assert!(count(&summary, "/drone_0/pose") > 10, "{summary}");

    // Kestrel's own reader recovers at least as much (also the whole records of a cut chunk);
    // the report reads them.
    let jsonl = as_json_lines(&log, "killed.jsonl");
    let lines = std::fs::read_to_string(&jsonl).unwrap().lines().count() as u64;
    assert!(
        lines >= summary["records"].as_u64().unwrap(),
        "{lines}: {summary}"
    );
    kestrel_ok(d, &["report", "killed.mcap", "--out", "rep"]);
    assert!(d.join("rep/index.html").exists());
}
