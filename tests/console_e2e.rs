//! What `kestrel sim` prints when its output is not a terminal (a pipe, a file, the journal):
//! readable behavior lines, no JSON and no ANSI colour codes; a `run_for_s` item that ran its
//! time is reported as done.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod support;

use std::process::Command;
use support::free_tcp_port;

fn sim(dir: &std::path::Path, extra: &[&str]) -> String {
    let listen = format!("127.0.0.1:{}", free_tcp_port());
    let mut args = vec![
        "sim",
        "--speedup",
        "max",
        "--exit-when-done",
        "--listen",
        &listen,
    ];
    args.extend_from_slice(extra);
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir)
        .env_remove("KESTREL_API_TOKEN")
        .env_remove("RUST_LOG")
        .args(&args)
        .output()
        .unwrap();
    let text =
        String::from_utf8_lossy(&out.stdout).into_owned() + &String::from_utf8_lossy(&out.stderr);
    assert!(out.status.success(), "{text}");
    text
}

#[test]
fn the_demo_prints_readable_lines_without_colour_codes() {
    let dir = tempfile::tempdir().unwrap();
    let out = sim(dir.path(), &[]);
    assert!(
        !out.contains('\u{1b}'),
        "ANSI escape in piped output:\n{out}"
    );
    for line in [
        "drone_0: takeoff #1 started (",
        "drone_0: takeoff #1 succeeded",
        "drone_0: land #4 started",
        "drone_0: land #4 succeeded",
    ] {
        assert!(out.contains(line), "`{line}` missing:\n{out}");
    }
    assert!(
        !out.lines().any(|l| l.contains("{\"event\"")),
        "raw JSON events:\n{out}"
    );
}

#[test]
fn an_item_that_ran_its_run_for_s_is_reported_done() {
    let dir = tempfile::tempdir().unwrap();
    let mission = serde_json::json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "follow_reference",
         "args": {"x": 1.0, "y": 1.0, "z": 2.0, "frame_id": "earth", "wait": true, "run_for_s": 3.0}},
        {"behavior": "land", "args": {}}]});
    let path = dir.path().join("timed.json");
    std::fs::write(&path, mission.to_string()).unwrap();
    let out = sim(dir.path(), &["--mission", path.to_str().unwrap()]);
    assert!(
        out.contains("follow_reference #2 succeeded"),
        "the timed item must end as done:\n{out}"
    );
    assert!(!out.contains("aborted"), "{out}");
}
