//! Flight logs are never overwritten: two `kestrel sim` in one folder each keep their own log,
//! a restarted `kestrel run` (even after a crash) leaves the earlier log as it was, an explicit
//! `--log FILE` refuses an existing file, and a second instance on a taken port stops.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};
use support::{free_tcp_port, wait_healthy, Process};

fn kestrel(dir: &Path, args: &[&str]) -> Process {
    let child = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir)
        .env_remove("KESTREL_API_TOKEN")
        .args(args)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    Process(child)
}

/// The flight logs named by their start time in `dir`, oldest first.
fn logs(dir: &Path, kind: &str) -> Vec<PathBuf> {
    let mut v: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| {
            let name = p.file_name().unwrap().to_string_lossy().into_owned();
            name.starts_with(kind) && name.ends_with(".jsonl")
        })
        .collect();
    v.sort();
    v
}

/// Every line parses and at least one pose record is there.
fn intact(text: &str) -> Vec<Value> {
    let records = kestrel::flightlog::read(text).expect("every line of the log is JSON");
    assert!(
        records.iter().any(|r| r["type"] == "pose"),
        "no pose record in {} records",
        records.len()
    );
    records
}

async fn get_text(base: &str, path: &str) -> String {
    reqwest::get(format!("{base}{path}"))
        .await
        .unwrap()
        .text()
        .await
        .unwrap()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_sims_in_one_folder_keep_both_logs_intact() {
    let dir = tempfile::tempdir().unwrap();
    let (pa, pb) = (free_tcp_port(), free_tcp_port());
    let (a_base, b_base) = (
        format!("http://127.0.0.1:{pa}"),
        format!("http://127.0.0.1:{pb}"),
    );
    let a_listen = format!("127.0.0.1:{pa}");
    let _a = kestrel(
        dir.path(),
        &[
            "sim",
            "--speedup",
            "5",
            "--listen",
            &a_listen,
            "--state-dir",
            "sa",
        ],
    );
    wait_healthy(&a_base).await;
    let b_listen = format!("127.0.0.1:{pb}");
    let _b = kestrel(
        dir.path(),
        &[
            "sim",
            "--speedup",
            "5",
            "--listen",
            &b_listen,
            "--state-dir",
            "sb",
        ],
    );
    wait_healthy(&b_base).await;
    tokio::time::sleep(Duration::from_secs(2)).await;

    // A third on the first one's port stops with a clear error, and says how to go elsewhere.
    let third = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir.path())
        .env_remove("KESTREL_API_TOKEN")
        .args([
            "sim",
            "--no-demo",
            "--listen",
            &a_listen,
            "--state-dir",
            "sc",
        ])
        .output()
        .unwrap();
    assert!(!third.status.success());
    let err = String::from_utf8_lossy(&third.stderr);
    assert!(
        err.contains("port is taken") && err.contains("--listen"),
        "{err}"
    );

    let listed: Vec<Value> = serde_json::from_str(&get_text(&a_base, "/api/logs").await).unwrap();
    let sims: Vec<&Value> = listed
        .iter()
        .filter(|l| l["name"].as_str().unwrap().starts_with("kestrel-sim-"))
        .collect();
    assert!(sims.len() >= 2, "{listed:?}");
    assert_eq!(
        listed.iter().filter(|l| l["current"] == true).count(),
        1,
        "{listed:?}"
    );
    for l in &sims {
        assert!(l["start_time"].as_str().unwrap().ends_with('Z'), "{l}");
    }

    // Each API serves its own log, whole, and the files on disk are two and intact.
    let a_log = intact(&get_text(&a_base, "/api/log").await);
    let b_log = intact(&get_text(&b_base, "/api/log").await);
    assert!(a_log.len() > 20 && b_log.len() > 20);
    let files = logs(dir.path(), "kestrel-sim-");
    assert!(files.len() >= 2, "{files:?}");
    for f in &files {
        intact(&std::fs::read_to_string(f).unwrap());
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_restarted_run_leaves_the_earlier_log_intact() {
    let dir = tempfile::tempdir().unwrap();
    let port = free_tcp_port();
    let base = format!("http://127.0.0.1:{port}");
    let listen = format!("127.0.0.1:{port}");
    let args = ["run", "--platform", "sim", "--listen", &listen];
    let mut first = kestrel(dir.path(), &args);
    wait_healthy(&base).await;
    // Let it write some poses, then crash it (SIGKILL: nothing flushed on the way out).
    let deadline = Instant::now() + Duration::from_secs(20);
    let earlier = loop {
        let files = logs(dir.path(), "kestrel-run-");
        if let Some(f) = files.first() {
            if std::fs::metadata(f).unwrap().len() > 2000 {
                break f.clone();
            }
        }
        assert!(Instant::now() < deadline, "kestrel run wrote no log");
        tokio::time::sleep(Duration::from_millis(200)).await;
    };
    first.0.kill().unwrap();
    first.0.wait().unwrap();
    let before = std::fs::read(&earlier).unwrap();

    let _second = kestrel(dir.path(), &args);
    wait_healthy(&base).await;
    tokio::time::sleep(Duration::from_secs(2)).await;
    let files = logs(dir.path(), "kestrel-run-");
    assert_eq!(files.len(), 2, "{files:?}");
    assert_eq!(
        std::fs::read(&earlier).unwrap(),
        before,
        "the earlier log changed"
    );
    let complete_lines = before.rsplitn(2, |b| *b == b'\n').nth(1).unwrap();
    intact(std::str::from_utf8(complete_lines).unwrap());
    // The API serves the new run's log, not the earlier one.
    let served = get_text(&base, "/api/log").await;
    intact(&served);
    assert_ne!(served.as_bytes(), &before[..]);

    // An explicit --log refuses a file that exists, unless told to replace it.
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir.path())
        .args(["run", "--platform", "sim", "--no-api", "--log"])
        .arg(&earlier)
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("--log-overwrite"));
    assert_eq!(std::fs::read(&earlier).unwrap(), before);
}

#[test]
fn the_log_says_what_ran_and_poses_name_the_motion_behavior() {
    let dir = tempfile::tempdir().unwrap();
    let scenario = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/missions/scenarios/solar_park.json"
    );
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir.path())
        .env_remove("KESTREL_API_TOKEN")
        .args(["sim", "--scenario", scenario, "--speedup", "max"])
        .args(["--exit-when-done", "--listen", "127.0.0.1:0", "--seed", "7"])
        .output()
        .unwrap();
    assert!(out.status.success(), "{out:?}");
    let files = logs(dir.path(), "kestrel-sim-");
    let records = intact(&std::fs::read_to_string(&files[0]).unwrap());

    let h = &records[0];
    assert_eq!(h["type"], "header", "{h}");
    assert_eq!(h["version"], env!("CARGO_PKG_VERSION"));
    assert_eq!(h["seed"], 7);
    assert!(h["scenario"].as_str().unwrap().ends_with("solar_park.json"));
    assert!(h["start_time"].as_str().unwrap().ends_with('Z'));
    assert!(h["geo_origin"]["lat_deg"].is_f64(), "{h}");
    assert!(h["config"]["drone"]["log_keep"].is_u64(), "{h}");

    let poses: Vec<&Value> = records.iter().filter(|r| r["type"] == "pose").collect();
    assert!(poses.len() > 100);
    for p in &poses {
        for key in [
            "t",
            "drone",
            "x",
            "y",
            "z",
            "yaw",
            "mode",
            "setpoint",
            "battery_v",
        ] {
            assert!(p.get(key).is_some(), "{key} missing in {p}");
        }
        // The gimbal points while the drone follows its path: the pose names the motion.
        assert_ne!(p["behavior"], "point_gimbal", "{p}");
    }
    assert!(poses.iter().any(|p| p["behavior"] == "follow_path"));
    assert!(poses.iter().any(|p| p["setpoint"]["kind"].is_string()));

    let flown = records
        .iter()
        .find(|r| r["type"] == "command" && r["fields"]["mission"]["plan"].is_array());
    assert!(flown.is_some(), "no command record carries the mission");
    let in_mission = records
        .iter()
        .filter(|r| r["type"] == "behavior" && r["mission"]["item"]["behavior"].is_string())
        .count();
    assert!(
        in_mission > 3,
        "behavior records without their mission item"
    );
}
