#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Exploration through a real `kestrel sim` process: explore missions uploaded and started over
//! the API for two drones, the frontiers and each drone's goal seen at `GET /api/exploration`
//! while they fly, and both drones landed with the area explored at the end.

mod support;

use serde_json::json;
use std::path::Path;
use support::Kestrel;

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn two_drones_explore_over_the_api_and_operators_see_frontiers_and_goals() {
    let dir = tempfile::tempdir().unwrap();
    let world = Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/pole20_d010_s1.json");
    let world = world.to_str().unwrap();
    let config = dir.path().join("kestrel.toml");
    // The map covers the world exactly; the watcher keeps drones apart, the safety stage at 0.5 m.
    std::fs::write(
        &config,
        "[map]\nsize_m = [20.0, 20.0]\n[safety]\nmin_separation_m = 0.5\n",
    )
    .unwrap();
    let k = Kestrel::sim(
        dir.path(),
        "explore-secret",
        &[
            "--world",
            world,
            "--drones",
            "2",
            "--config",
            config.to_str().unwrap(),
        ],
    )
    .await;
    for drone in ["drone_0", "drone_1"] {
        let mission = json!({ "target": drone, "plan": [{ "behavior": "explore", "args": {} }] });
        let (code, up) = k.post("/api/missions", &mission).await;
        assert_eq!(code, 201, "{up}");
        let (code, v) = k
            .post(
                "/api/mission_update",
                &json!({ "drone_id": drone, "mission_id": up["mission_id"], "item_id": 0,
                          "action": 2, "mission": "" }),
            )
            .await;
        assert_eq!(code, 200, "{v}");
    }
    let seen = k
        .wait_for("/api/exploration", 120.0, |v| {
            v["frontiers"].as_array().is_some_and(|f| !f.is_empty())
                && v["goals"].as_array().is_some_and(|g| g.len() == 2)
        })
        .await;
    let goals: Vec<[f64; 2]> = seen["goals"]
        .as_array()
        .unwrap()
        .iter()
        .map(|g| {
            [
                g["goal_enu_m"][0].as_f64().unwrap(),
                g["goal_enu_m"][1].as_f64().unwrap(),
            ]
        })
        .collect();
    let apart = (goals[0][0] - goals[1][0]).hypot(goals[0][1] - goals[1][1]);
    assert!(apart > 0.5, "two drones, two goals: {seen}");
    // At 20x, a run takes 15-30 s of wall time here; a failed item ends the wait at once (its
    // error is asserted below), and an exploration still going after 240 s fails with the
    // status as it stands, not at the test runner's 10-minute limit.
    let status = k
        .wait_for("/api/status", 240.0, |s| {
            (0..2).all(|i| {
                let m = &s["drones"][i]["mission"];
                m["done_items"] == 1 || !m["last_error"].is_null()
            })
        })
        .await;
    for i in 0..2 {
        let d = &status["drones"][i];
        assert_eq!(d["mission"]["last_error"], serde_json::Value::Null, "{d}");
    }
    let (_, end) = k.get("/api/exploration").await;
    let known = end["known_pct"].as_f64().unwrap();
    assert!(known > 95.0, "{end}");
}
