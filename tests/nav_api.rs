#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end through a real `kestrel sim` process: the map as JSON, PNG and metadata, map
//! updates over the WebSocket, scans sent over the API, coverage for two drones, a mission with
//! `navigate_to`, `kestrel map export`, and a second Kestrel starting from the exported map.

mod support;

use futures::{SinkExt, StreamExt};
use serde_json::{json, Value};
use std::path::Path;
use std::process::Command;
use std::time::{Duration, Instant};
use support::Kestrel;
use tokio_tungstenite::tungstenite::Message;

const TOKEN: &str = "nav-secret";

async fn start(dir: &Path, args: &[&str]) -> Kestrel {
    Kestrel::sim(dir, TOKEN, args).await
}

/// A 20 m x 20 m world with three poles, drones starting near the origin.
fn write_world(dir: &Path) -> std::path::PathBuf {
    let world = json!({
        "name": "three-poles",
        "bounds_m": { "x": [-10.0, 10.0], "y": [-10.0, 10.0] },
        "starts_xy_yaw": { "2": [[0.0, 0.0, 0.0], [-2.0, -2.0, 0.0]] },
        "cylinders": [
            { "xy_m": [3.0, 0.0], "radius_m": 0.3 },
            { "xy_m": [0.0, 4.0], "radius_m": 0.2 },
            { "xy_m": [-5.0, -5.0], "radius_m": 0.2 }
        ],
    });
    let path = dir.join("world.json");
    std::fs::write(&path, world.to_string()).unwrap();
    path
}

/// Values of the cells whose centres lie in `[x0, x1] x [y0, y1]` of a `{spec, data}` answer.
fn cells(map: &Value, [x0, x1]: [f64; 2], [y0, y1]: [f64; 2]) -> Vec<i64> {
    let spec = &map["spec"];
    let r = spec["resolution_m"].as_f64().unwrap();
    let (ox, oy) = (
        spec["origin_enu_m"][0].as_f64().unwrap(),
        spec["origin_enu_m"][1].as_f64().unwrap(),
    );
    let w = spec["width_cells"].as_u64().unwrap() as usize;
    let data = map["data"].as_array().unwrap();
    let mut out = Vec::new();
    for (i, v) in data.iter().enumerate() {
        let (cx, cy) = (
            ox + ((i % w) as f64 + 0.5) * r,
            oy + ((i / w) as f64 + 0.5) * r,
        );
        if (x0..=x1).contains(&cx) && (y0..=y1).contains(&cy) {
            out.push(v.as_i64().unwrap());
        }
    }
    out
}

/// Most occupied cell around the west face of the pole at (3, 0) (radius 0.3 m).
fn pole_face(map: &Value) -> i64 {
    cells(map, [2.6, 2.8], [-0.15, 0.15])
        .into_iter()
        .max()
        .unwrap()
}

async fn next_map_update(k: &Kestrel) -> Value {
    let (mut socket, _) =
        tokio_tungstenite::connect_async(format!("ws://127.0.0.1:{}/api/ws?token={TOKEN}", k.port))
            .await
            .unwrap();
    // A scan now, so the map changes while this client listens.
    let (code, v) = k.post("/api/scans", &point_cloud_scan()).await;
    assert_eq!(code, 200, "{v}");
    let deadline = Instant::now() + Duration::from_secs(10);
    loop {
        assert!(Instant::now() < deadline, "no map_update");
        match tokio::time::timeout(Duration::from_secs(10), socket.next()).await {
            Ok(Some(Ok(Message::Text(t)))) => {
                let m: Value = serde_json::from_str(t.as_str()).unwrap();
                if m["type"] == "map_update" {
                    let _ = socket.send(Message::Close(None)).await;
                    return m;
                }
            }
            Ok(Some(Ok(_))) => continue,
            other => panic!("websocket ended: {other:?}"),
        }
    }
}

/// A point cloud from a sensor in the map's south-west corner, beyond the lidars' reach: one
/// point 0.5 m east of it at its height, one above the height band.
fn point_cloud_scan() -> Value {
    json!({ "drone": "drone_0", "scans": [{
        "kind": "point_cloud", "origin_enu_m": [-11.45, -11.45, 0.0], "yaw_rad": 0.0,
        "points_flu_m": [[0.5, 0.0, 0.0], [0.5, 0.0, 3.0]], "z_min_m": -0.3, "z_max_m": 0.3,
        "range_min_m": 0.1, "range_max_m": 8.0 }] })
}

#[tokio::test]
async fn maps_scans_coverage_and_navigation_through_the_api() {
    let dir = tempfile::tempdir().unwrap();
    let world = write_world(dir.path());
    let k = start(
        dir.path(),
        &[
            "--world",
            world.to_str().unwrap(),
            "--sensor",
            "lidar",
            "--drones",
            "2",
        ],
    )
    .await;

    // The lidar maps the poles while the drones wait on the ground.
    let info = k
        .wait_for("/api/map/info", 20.0, |v| {
            v["cells_occupied"].as_u64().unwrap_or(0) > 5
        })
        .await;
    assert_eq!(info["layers"], json!(["drone_0", "drone_1"]), "{info}");
    let (code, merged) = k.get("/api/map").await;
    assert_eq!(code, 200);
    let spec = &merged["spec"];
    let n_cells = spec["width_cells"].as_u64().unwrap() * spec["height_cells"].as_u64().unwrap();
    assert_eq!(merged["data"].as_array().unwrap().len() as u64, n_cells);
    assert!(pole_face(&merged) > 30, "the pole's west face is occupied");
    let before = cells(&merged, [1.45, 1.55], [-0.05, 0.05]);
    assert!(
        before.iter().all(|&v| v == 0),
        "free in front of it: {before:?}"
    );
    let (code, own) = k.get("/api/map?drone=drone_1").await;
    assert_eq!((code, own["drone"].clone()), (200, json!("drone_1")));
    let (code, e) = k.get("/api/map?drone=drone_7").await;
    assert_eq!(
        (code, e["error"]["code"].clone()),
        (404, json!("unknown_drone"))
    );
    let png = reqwest::Client::new()
        .get(format!("{}/api/map.png", k.base))
        .bearer_auth(TOKEN)
        .send()
        .await
        .unwrap();
    assert_eq!(png.headers()["content-type"], "image/png");
    assert_eq!(&png.bytes().await.unwrap()[..4], b"\x89PNG");

    // Scans over the API reach the drone's own map and the merged one; changes stream out.
    let update = next_map_update(&k).await;
    assert_eq!(update["drone"], Value::Null);
    let w = update["spec"]["width_cells"].as_u64().unwrap();
    let h = update["spec"]["height_cells"].as_u64().unwrap();
    assert_eq!(update["data"].as_array().unwrap().len() as u64, w * h);
    let bbox: Vec<f64> = serde_json::from_value(update["bbox"].clone()).unwrap();
    assert!(bbox[0] < bbox[2] && bbox[1] < bbox[3], "{bbox:?}");
    let hit = |m: &Value| cells(m, [-10.96, -10.94], [-11.46, -11.44]);
    let own = k
        .wait_for("/api/map?drone=drone_0", 5.0, |m| hit(m) == [40])
        .await;
    assert_eq!(
        cells(&own, [-11.26, -11.24], [-11.46, -11.44]),
        [0],
        "cleared on the way"
    );
    let (_, merged) = k.get("/api/map").await;
    assert_eq!(hit(&merged), [40]);
    let (code, bad) = k
        .post(
            "/api/scans",
            &json!({ "drone": "drone_0", "scans": [{ "kind": "multiranger",
            "origin_enu_m": [0, 0, 0], "yaw_rad": 0, "front_left_back_right_m": [1, 1, 1, 1],
            "range_min_m": 2, "range_max_m": 1 }] }),
        )
        .await;
    assert_eq!(
        (code, bad["error"]["details"][0]["pointer"].clone()),
        (422, json!("/scans/0"))
    );

    // Coverage of a square by both drones, and a request that points at its mistakes.
    let (code, cov) = k
        .post(
            "/api/coverage",
            &json!({ "polygon_enu_m": [[-6, 6], [6, 6], [6, 14], [-6, 14]], "street_spacing_m": 4,
                      "angle_deg": null, "drones": ["drone_0", "drone_1"], "height_m": 4 }),
        )
        .await;
    assert_eq!(code, 200, "{cov}");
    for d in ["drone_0", "drone_1"] {
        let points = cov["per_drone"][d].as_array().unwrap();
        assert!(points.len() >= 2, "{cov}");
        assert_eq!(points[0][2], 4.0);
        assert!(cov["lengths_m"][d].as_f64().unwrap() > 0.0);
    }
    let (code, bad) = k
        .post(
            "/api/coverage",
            &json!({ "polygon_enu_m": [[0, 0], [4, 0], [4, 4]], "street_spacing_m": 2,
                      "angle_deg": null, "drones": ["drone_9"], "height_m": 3 }),
        )
        .await;
    assert_eq!(code, 422);
    assert_eq!(bad["error"]["details"][0]["pointer"], "/drones/0", "{bad}");
    let (_, fence) = k.get("/api/geofence").await;
    assert_eq!(fence["max_altitude_m"], 120.0);

    // A mission flies navigate_to around the pole east of drone_0.
    let mission = json!({ "target": "drone_0", "plan": [
        { "behavior": "takeoff", "args": { "height": 1.0, "speed": 1.0 } },
        { "behavior": "navigate_to", "args": { "x": 6.0, "y": 0.0, "z": 1.0, "speed": 1.0,
                                               "safety_distance": 0.4 } },
        { "behavior": "land", "args": { "speed": 0.5 } } ] });
    let (code, up) = k.post("/api/missions", &mission).await;
    assert_eq!(code, 201, "{up}");
    let id = up["mission_id"].as_u64().unwrap();
    let (code, v) = k
        .post(
            "/api/mission_update",
            &json!({ "drone_id": "drone_0", "mission_id": id, "item_id": 0, "action": 2,
                      "mission": "" }),
        )
        .await;
    assert_eq!(code, 200, "{v}");
    let status = k
        .wait_for("/api/status", 60.0, |s| {
            s["drones"][0]["mission"]["done_items"] == 3
        })
        .await;
    let d = &status["drones"][0];
    assert_eq!(d["mission"]["last_error"], Value::Null, "{d}");
    let [x, y] = [
        d["position_enu_m"][0].as_f64().unwrap(),
        d["position_enu_m"][1].as_f64().unwrap(),
    ];
    assert!((x - 6.0).hypot(y) < 0.3, "landed at ({x:.2}, {y:.2})");

    // Export the merged map, then start a Kestrel that knows it from the start.
    let out = dir.path().join("export");
    let exported = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .args(["map", "export", "--from", &k.base, "--out"])
        .arg(&out)
        .env("KESTREL_API_TOKEN", TOKEN)
        .output()
        .unwrap();
    assert!(
        exported.status.success(),
        "{}",
        String::from_utf8_lossy(&exported.stderr)
    );
    let yaml = std::fs::read_to_string(out.join("map.yaml")).unwrap();
    assert!(yaml.contains("image: map.pgm"), "{yaml}");
    assert!(std::fs::read(out.join("map.pgm"))
        .unwrap()
        .starts_with(b"P5"));
    drop(k);
    let config = dir.path().join("known.toml");
    std::fs::write(
        &config,
        format!(
            "[map]\nknown_map = \"{}\"\n",
            out.join("map.yaml").display()
        ),
    )
    .unwrap();
    let second = dir.path().join("second");
    std::fs::create_dir_all(&second).unwrap();
    let k2 = start(
        &second,
        &["--config", config.to_str().unwrap(), "--sensor", "none"],
    )
    .await;
    let (_, known) = k2.get("/api/map/info").await;
    assert_eq!(known["layers"], json!(["known"]), "{known}");
    assert!(known["cells_occupied"].as_u64().unwrap() > 5, "{known}");
    let (_, own) = k2.get("/api/map?drone=drone_0").await;
    assert!(pole_face(&own) > 30, "the drone starts from the known map");
}
