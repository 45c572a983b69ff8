#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: what the API acknowledged survives `kill -9` right after the answer, and a bad
//! file in the state directory is quarantined and reported instead of stopping Kestrel.

mod support;

use futures::stream::{FuturesUnordered, StreamExt};
use serde_json::{json, Value};
use std::path::Path;
use support::Kestrel;

const TOKEN: &str = "durable-secret";
/// Start, check, burst, kill: this many times.
const ROUNDS: usize = 12;
/// Uploads sent at once in a round.
const BURST: usize = 6;

/// A mission told apart from every other by its takeoff height.
fn mission(tag: usize) -> Value {
    json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": height(tag), "speed": 1.0}}
    ]})
}

fn height(tag: usize) -> f64 {
    1.0 + tag as f64 / 1000.0
}

/// Uploads mission `tag`; its id when the answer is a 201 (which must say it is durable).
async fn upload(client: reqwest::Client, base: String, tag: usize) -> Option<(u64, usize)> {
    let r = client
        .post(format!("{base}/api/missions"))
        .bearer_auth(TOKEN)
        .json(&mission(tag))
        .send()
        .await
        .ok()?;
    if r.status().as_u16() != 201 {
        return None;
    }
    let body: Value = r.json().await.ok()?;
    // Answers from before `durable` existed are judged by what survives.
    assert_ne!(body["durable"], false, "a 201 that is not durable: {body}");
    Some((body["mission_id"].as_u64().unwrap(), tag))
}

/// Every acknowledged mission is loaded, as it was uploaded.
async fn assert_kept(k: &Kestrel, acked: &[(u64, usize)], round: usize) {
    for &(id, tag) in acked {
        let (code, m) = k.get(&format!("/api/missions/{id}")).await;
        assert_eq!(
            code, 200,
            "round {round}: acknowledged mission {id} lost: {m}"
        );
        let h = m["plan"]["plan"][0]["args"]["height"].as_f64().unwrap();
        assert!(
            (h - height(tag)).abs() < 1e-9,
            "round {round}: mission {id} is {m}"
        );
    }
}

#[tokio::test]
async fn every_acknowledged_mission_survives_a_kill_right_after_its_201() {
    let dir = tempfile::tempdir().unwrap();
    let client = reqwest::Client::new();
    let mut acked: Vec<(u64, usize)> = Vec::new();
    let mut tag = 0;
    let mut total = 0;
    for round in 0..ROUNDS {
        let k = Kestrel::sim(dir.path(), TOKEN, &[]).await;
        assert_kept(&k, &acked, round).await;
        // Room for the next burst: unload everything (kept or not, acknowledged or not).
        let (_, list) = k.get("/api/missions").await;
        for m in list.as_array().unwrap() {
            let id = m["mission_id"].as_u64().unwrap();
            let (code, v) = k.call("DELETE", &format!("/api/missions/{id}"), None).await;
            assert_eq!(code, 204, "{v}");
        }
        acked.clear();
        // Killed right after the 1st, 2nd, .. 6th acknowledgement, the others in flight.
        let kill_after = 1 + round % BURST;
        let mut uploads: FuturesUnordered<_> = (0..BURST)
            .map(|_| {
                tag += 1;
                upload(client.clone(), k.base.clone(), tag)
            })
            .collect();
        let mut k = k;
        while let Some(answer) = uploads.next().await {
            if let Some(ack) = answer {
                acked.push(ack);
                if acked.len() == kill_after {
                    k.process.0.kill().unwrap();
                    break;
                }
            }
        }
        assert_eq!(acked.len(), kill_after, "round {round}: uploads refused");
        total += acked.len();
        drop(uploads);
        drop(k);
    }
    let k = Kestrel::sim(dir.path(), TOKEN, &[]).await;
    assert_kept(&k, &acked, ROUNDS).await;
    assert!(total >= ROUNDS * 3, "{total} acknowledgements checked");
}

fn corrupt(path: &Path, bytes: &[u8]) {
    assert!(path.exists(), "{} is not there", path.display());
    std::fs::write(path, bytes).unwrap();
}

#[tokio::test]
async fn a_corrupt_mission_file_is_quarantined_reported_and_the_rest_loads() {
    let dir = tempfile::tempdir().unwrap();
    {
        let k = Kestrel::sim(dir.path(), TOKEN, &[]).await;
        for tag in 1..=4 {
            let (code, v) = k.post("/api/missions", &mission(tag)).await;
            assert_eq!((code, &v["durable"]), (201, &json!(true)), "{v}");
        }
    } // killed
    let missions = dir.path().join("state/drones/drone_0/missions");
    let text = std::fs::read_to_string(missions.join("2.json")).unwrap();
    corrupt(&missions.join("2.json"), &text.as_bytes()[..text.len() / 2]);
    corrupt(&missions.join("3.json"), &[0u8; 64]);
    corrupt(
        &dir.path().join("state/drones/drone_0/executor.json"),
        b"[]",
    );
    std::fs::write(dir.path().join("state/state.json"), b"{\"drones\": 7}").unwrap();

    let k = Kestrel::sim(dir.path(), TOKEN, &[]).await;
    let (_, list) = k.get("/api/missions").await;
    let ids: Vec<u64> = list
        .as_array()
        .unwrap()
        .iter()
        .map(|m| m["mission_id"].as_u64().unwrap())
        .collect();
    assert_eq!(ids, [1, 4], "{list}");
    let (code, health) = k.get("/api/health").await;
    assert_eq!(code, 200);
    let storage = &health["storage"];
    assert_eq!(storage["missions_loaded"], 2, "{health}");
    let mut bad: Vec<String> = storage["quarantined"]
        .as_array()
        .unwrap()
        .iter()
        .map(|p| {
            let moved = p["quarantined_as"].as_str().unwrap();
            assert!(dir.path().join("state").join(moved).exists(), "{p}");
            assert!(!p["reason"].as_str().unwrap().is_empty(), "{p}");
            p["file"].as_str().unwrap().to_string()
        })
        .collect();
    bad.sort();
    assert_eq!(
        bad,
        [
            "drones/drone_0/executor.json",
            "drones/drone_0/missions/2.json",
            "drones/drone_0/missions/3.json",
            "state.json"
        ],
        "{health}"
    );
    assert_eq!(storage["saving"], true, "{health}");
    // New missions never take a loaded mission's id, and are saved as before.
    let (code, v) = k.post("/api/missions", &mission(5)).await;
    assert_eq!((code, &v["durable"]), (201, &json!(true)), "{v}");
    assert!(![1, 4].contains(&v["mission_id"].as_u64().unwrap()), "{v}");
}

#[tokio::test]
async fn an_old_single_file_state_is_migrated_to_one_file_per_mission() {
    let made = tempfile::tempdir().unwrap();
    {
        let k = Kestrel::sim(made.path(), TOKEN, &[]).await;
        let (code, _) = k.post("/api/missions?mission_id=7", &mission(7)).await;
        assert_eq!(code, 201);
    }
    // The same mission as an older Kestrel kept it: everything in one state.json.
    let drone = made.path().join("state/drones/drone_0");
    let read = |p: &Path| -> Value { serde_json::from_slice(&std::fs::read(p).unwrap()).unwrap() };
    let mut snapshot = read(&drone.join("executor.json"));
    snapshot["missions"] = json!({ "7": read(&drone.join("missions/7.json")) });
    let legacy = json!({ "drones": { "drone_0": snapshot }, "frames": [] });
    let dir = tempfile::tempdir().unwrap();
    std::fs::create_dir_all(dir.path().join("state")).unwrap();
    std::fs::write(dir.path().join("state/state.json"), legacy.to_string()).unwrap();

    let k = Kestrel::sim(dir.path(), TOKEN, &[]).await;
    assert_kept(&k, &[(7, 7)], 0).await;
    let (_, health) = k.get("/api/health").await;
    assert_eq!(
        health["storage"]["migrated"], "state.json.migrated",
        "{health}"
    );
    assert!(dir
        .path()
        .join("state/drones/drone_0/missions/7.json")
        .exists());
    assert!(!dir.path().join("state/state.json").exists());
}
