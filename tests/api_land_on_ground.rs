#![allow(clippy::unwrap_used, clippy::expect_used)]
//! LAND (EXECUTE of a one-item `land` mission) for a drone on the ground and disarmed: the real
//! `kestrel sim` refuses it with `409 already_landed` and stores nothing (no mission listed, no
//! mission file in the state directory); the same LAND once the drone flies is accepted.

mod support;

use serde_json::{json, Value};
use std::path::Path;
use std::time::{Duration, Instant};
use support::Kestrel;

const TOKEN: &str = "land-secret";

/// What the page's LAND button sends: EXECUTE of a one-item `land` mission.
fn land_update() -> Value {
    json!({
        "drone_id": "drone_0", "mission_id": null, "item_id": null, "action": 0,
        "mission": {"target": "drone_0", "plan": [{"behavior": "land", "args": {"speed": 0.5}}]}
    })
}

fn mission_files(state: &Path) -> usize {
    std::fs::read_dir(state.join("drones/drone_0/missions"))
        .map(|d| d.count())
        .unwrap_or(0)
}

async fn wait_drone(k: &Kestrel, max_s: f64, done: impl Fn(&Value) -> bool) -> Value {
    let deadline = Instant::now() + Duration::from_secs_f64(max_s);
    loop {
        let (_, s) = k.get("/api/status").await;
        let d = s["drones"][0].clone();
        if done(&d) {
            return d;
        }
        assert!(Instant::now() < deadline, "timed out; last status {d}");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

#[tokio::test]
async fn land_on_a_landed_drone_is_refused_and_nothing_is_stored() {
    let dir = tempfile::tempdir().unwrap();
    let k = Kestrel::sim(dir.path(), TOKEN, &["--drones", "1"]).await;
    let state = dir.path().join("state");
    wait_drone(&k, 20.0, |d| d["link"] == "ok").await;

    let (code, v) = k.post("/api/mission_update", &land_update()).await;
    assert_eq!(code, 409, "{v}");
    assert_eq!(v["accepted"], false, "{v}");
    assert_eq!(v["code"], "already_landed", "{v}");
    let reason = v["reason"].as_str().unwrap();
    assert!(
        reason.contains("drone_0 is on the ground and disarmed"),
        "{reason}"
    );

    let (_, missions) = k.get("/api/missions?drone=drone_0").await;
    assert_eq!(
        missions,
        json!([]),
        "a refused LAND leaves no mission loaded"
    );
    assert_eq!(
        mission_files(&state),
        0,
        "nor a mission file in {}",
        state.display()
    );

    // LOADing a landing for later is not landing now: kept.
    let mut load = land_update();
    load["action"] = json!(1);
    let (code, v) = k.post("/api/mission_update", &load).await;
    assert_eq!(code, 200, "{v}");
    assert_eq!(mission_files(&state), 1);

    // Airborne, the same LAND is accepted (and stored).
    let takeoff = json!({"target": "drone_0", "plan": [{"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}}]});
    let (code, v) = k.post("/api/missions", &takeoff).await;
    assert_eq!(code, 201, "{v}");
    let id = v["mission_id"].clone();
    let start = json!({"drone_id": "drone_0", "mission_id": id, "item_id": null, "action": 2, "mission": null});
    let (code, v) = k.post("/api/mission_update", &start).await;
    assert_eq!(code, 200, "{v}");
    wait_drone(&k, 60.0, |d| {
        d["armed"] == true && d["position_enu_m"][2].as_f64().unwrap_or(0.0) > 1.0
    })
    .await;
    let (code, v) = k.post("/api/mission_update", &land_update()).await;
    assert_eq!(code, 200, "LAND in the air is accepted: {v}");
    assert_eq!(v["accepted"], true, "{v}");
    wait_drone(&k, 120.0, |d| d["armed"] == false).await;
}
