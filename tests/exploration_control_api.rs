#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Exploration started and stopped for chosen drones through a real `kestrel sim` process:
//! bad requests start nothing; one drone of two explores, its goal and the growing area are
//! seen in the progress of `GET /api/exploration`; the report downloads as an attachment with
//! the live measurements and the evaluator's metrics against the simulator's world; stop
//! freezes the clock.

mod support;

use serde_json::{json, Value};
use std::path::Path;
use support::Kestrel;

async fn explore_sim(dir: &Path) -> Kestrel {
    let world = Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/pole20_d010_s1.json");
    let config = dir.join("kestrel.toml");
    std::fs::write(
        &config,
        "[map]\nsize_m = [20.0, 20.0]\n[safety]\nmin_separation_m = 0.5\n",
    )
    .unwrap();
    Kestrel::sim(
        dir,
        "explore-secret",
        &[
            "--world",
            world.to_str().unwrap(),
            "--drones",
            "2",
            "--config",
            config.to_str().unwrap(),
        ],
    )
    .await
}

fn pointers(v: &Value) -> Vec<String> {
    v["error"]["details"]
        .as_array()
        .unwrap()
        .iter()
        .map(|d| d["pointer"].as_str().unwrap().to_string())
        .collect()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn bad_requests_start_nothing() {
    let dir = tempfile::tempdir().unwrap();
    let k = explore_sim(dir.path()).await;
    let (code, v) = k
        .post(
            "/api/exploration/start",
            &json!({ "drones": ["drone_0", "drone_7"] }),
        )
        .await;
    assert_eq!(code, 404, "{v}");
    assert_eq!(v["error"]["code"], "unknown_drone");
    assert!(v["error"]["message"].as_str().unwrap().contains("drone_7"));
    let (code, v) = k
        .post(
            "/api/exploration/start",
            &json!({ "drones": ["drone_0"], "args": { "speed": -1.0 } }),
        )
        .await;
    assert_eq!(code, 422, "{v}");
    assert_eq!(v["error"]["code"], "invalid_request");
    assert_eq!(pointers(&v), ["/args/speed"], "{v}");
    let (code, v) = k
        .post(
            "/api/exploration/start",
            &json!({ "drones": ["drone_1", "drone_1"] }),
        )
        .await;
    assert_eq!(code, 422, "{v}");
    assert_eq!(pointers(&v), ["/drones/1"], "{v}");
    let (code, v) = k
        .post("/api/exploration/start", &json!({ "drones": [] }))
        .await;
    assert_eq!(code, 422, "{v}");
    assert_eq!(pointers(&v), ["/drones"], "{v}");
    let (code, v) = k
        .post("/api/exploration/start", &json!({ "drone": "drone_0" }))
        .await;
    assert_eq!(code, 422, "unknown field: {v}");
    let (code, v) = k
        .post("/api/exploration/stop", &json!({ "drones": ["drone_0"] }))
        .await;
    assert_eq!(code, 409, "nothing explores: {v}");
    let (code, v) = k.get("/api/exploration/report").await;
    assert_eq!(code, 404, "no exploration yet: {v}");
    // Nothing was loaded, nothing runs.
    let (_, missions) = k.get("/api/missions").await;
    assert_eq!(missions, json!([]));
    let (_, view) = k.get("/api/exploration").await;
    assert_eq!(view["progress"], Value::Null);
    // The bearer token is required like everywhere else.
    let r = reqwest::Client::new()
        .post(format!("{}/api/exploration/start", k.base))
        .json(&json!({ "drones": ["drone_0"] }))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status().as_u16(), 401);
    let (_, spec) = k.get("/api/openapi.json").await;
    for path in ["start", "stop", "report"] {
        assert!(
            spec["paths"][format!("/api/exploration/{path}")].is_object(),
            "{path}"
        );
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn one_drone_of_two_explores_with_live_progress_a_report_and_a_stop() {
    let dir = tempfile::tempdir().unwrap();
    let k = explore_sim(dir.path()).await;
    let (code, started) = k
        .post(
            "/api/exploration/start",
            &json!({ "drones": ["drone_0"], "args": { "speed": 0.75 } }),
        )
        .await;
    assert_eq!(code, 200, "{started}");
    assert_eq!(started["drones"][0]["drone"], "drone_0");
    let mission_id = started["drones"][0]["mission_id"].as_u64().unwrap();
    // The same path as a mission: it is listed, running.
    let (_, m) = k.get(&format!("/api/missions/{mission_id}")).await;
    assert_eq!(m["plan"]["plan"][0]["behavior"], "explore", "{m}");
    let (code, v) = k
        .post("/api/exploration/start", &json!({ "drones": ["drone_0"] }))
        .await;
    assert_eq!(code, 409, "exploring already: {v}");

    let early = k
        .wait_for("/api/exploration", 120.0, |v| {
            v["progress"]["drones"][0]["goal_enu_m"].is_array()
                && v["frontiers"].as_array().is_some_and(|f| !f.is_empty())
        })
        .await;
    let p = &early["progress"];
    assert_eq!(
        p["drones"].as_array().unwrap().len(),
        1,
        "only drone_0: {p}"
    );
    assert_eq!(p["finished"], false);
    assert!(
        ["takeoff", "navigating", "sensing", "drone_avoidance"]
            .contains(&p["drones"][0]["phase"].as_str().unwrap()),
        "{p}"
    );
    let known0 = early["known_pct"].as_f64().unwrap();
    let later = k
        .wait_for("/api/exploration", 240.0, |v| {
            v["progress"]["remaining_s"].is_number()
                && v["known_pct"].as_f64().unwrap() > known0 + 5.0
        })
        .await;
    let p = &later["progress"];
    assert!(p["elapsed_s"].as_f64().unwrap() >= 10.0, "{p}");
    assert!(p["area_rate_pct_per_min"].as_f64().unwrap() > 0.0, "{p}");
    assert!(p["remaining_s"].as_f64().unwrap() > 0.0, "{p}");
    // drone_1 never took off.
    let (_, status) = k.get("/api/status").await;
    assert_eq!(status["drones"][1]["armed"], false, "{status}");
    let (code, v) = k
        .post("/api/exploration/stop", &json!({ "drones": ["drone_1"] }))
        .await;
    assert_eq!(code, 409, "drone_1 is not exploring: {v}");

    let r = k.get_raw("/api/exploration/report").await;
    assert_eq!(r.status().as_u16(), 200);
    let disposition = r
        .headers()
        .get("content-disposition")
        .unwrap()
        .to_str()
        .unwrap()
        .to_string();
    assert!(disposition.starts_with("attachment; filename=\"kestrel-exploration-"));
    let report: Value = r.json().await.unwrap();
    let curve = report["area_curve"].as_array().unwrap();
    assert!(curve.len() >= 10, "one point a second: {}", curve.len());
    let first = curve.first().unwrap()["area_pct"].as_f64().unwrap();
    let last = curve.last().unwrap()["area_pct"].as_f64().unwrap();
    assert!(last > first + 5.0, "the area grew: {first} -> {last}");
    assert!(
        report["drones"][0]["path_m"].as_f64().unwrap() > 1.0,
        "{}",
        report["drones"]
    );
    assert!(report["pose_samples"].as_u64().unwrap() > 50);
    assert!(report["frontiers_left"].as_u64().unwrap() > 0);
    assert_eq!(report["min_separation_m"], Value::Null, "one drone flew");
    let eval = &report["evaluation"];
    assert_eq!(report["evaluation_error"], Value::Null, "{report}");
    assert_eq!(eval["drones_flown"], 1, "{eval}");
    assert!(eval["area_pct"].as_f64().unwrap() > 5.0, "{eval}");

    let (code, v) = k
        .post("/api/exploration/stop", &json!({ "drones": ["drone_0"] }))
        .await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(v["stopped"], json!(["drone_0"]));
    let stopped = k
        .wait_for("/api/exploration", 10.0, |v| {
            v["progress"]["finished"] == true
        })
        .await;
    let p = &stopped["progress"];
    assert_eq!(p["remaining_s"], 0.0, "{p}");
    assert_eq!(p["drones"][0]["goal_enu_m"], Value::Null, "{p}");
    let elapsed = p["elapsed_s"].as_f64().unwrap();
    tokio::time::sleep(std::time::Duration::from_millis(500)).await;
    let (_, again) = k.get("/api/exploration").await;
    assert_eq!(
        again["progress"]["elapsed_s"].as_f64().unwrap(),
        elapsed,
        "the clock stopped"
    );
    let (_, status) = k.get("/api/status").await;
    assert_eq!(status["drones"][0]["mission"]["state"], 0, "{status}");
}
