#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: `kestrel report` on the logs of real `kestrel sim` and `kestrel explore` runs,
//! and `GET /api/logs/{name}/report` and `GET /api/logs/{name}` of a running `kestrel sim`.

mod support;

use kestrel::report::palette;
use serde_json::Value;
use std::collections::{BTreeMap, BTreeSet};
use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn kestrel(dir: &Path, args: &[&str]) -> Output {
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(dir)
        .env_remove("KESTREL_API_TOKEN")
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "kestrel {args:?}: {out:?}");
    out
}

fn records(log: &Path) -> Vec<Value> {
    kestrel::flightlog::read(&std::fs::read_to_string(log).unwrap()).unwrap()
}

fn repo(path: &str) -> String {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join(path)
        .display()
        .to_string()
}

/// The solar-park scenario flown in the simulator; the path of its flight log.
fn solar_park(dir: &Path) -> PathBuf {
    let scenario = repo("missions/scenarios/solar_park.json");
    kestrel(
        dir,
        &[
            "sim",
            "--scenario",
            &scenario,
            "--speedup",
            "max",
            "--exit-when-done",
            "--listen",
            "127.0.0.1:0",
            "--log",
            "flight.jsonl",
        ],
    );
    dir.join("flight.jsonl")
}

/// The `<tag ...>` elements of an SVG document that carry `attr="value"`.
fn elements_with(svg: &str, tag: &str, attr: &str, value: &str) -> usize {
    let open = format!("<{tag} ");
    let want = format!("{attr}=\"{value}\"");
    svg.split(&open)
        .skip(1)
        .filter(|e| e.split('>').next().is_some_and(|a| a.contains(&want)))
        .count()
}

fn png_size(path: &Path) -> (u32, u32) {
    let decoder = png::Decoder::new(std::fs::File::open(path).unwrap());
    let mut reader = decoder.read_info().unwrap();
    let mut buf = vec![0; reader.output_buffer_size()];
    let info = reader.next_frame(&mut buf).unwrap();
    (info.width, info.height)
}

#[test]
fn solar_park_report_has_the_flights_behaviors_tracks_and_poses() {
    let dir = tempfile::tempdir().unwrap();
    let log = solar_park(dir.path());
    kestrel(dir.path(), &["report", "flight.jsonl"]);
    let out = dir.path().join("flight-report");
    let recs = records(&log);

    // Timeline: one bar (a rect in the behavior's colour) per `started` event.
    let mut started: BTreeMap<String, usize> = BTreeMap::new();
    for r in recs
        .iter()
        .filter(|r| r["type"] == "behavior" && r["event"] == "started")
    {
        assert_eq!(r["drone"], "drone_0");
        *started
            .entry(r["behavior"].as_str().unwrap().into())
            .or_default() += 1;
    }
    for b in ["takeoff", "go_to", "follow_path", "point_gimbal"] {
        assert!(started.contains_key(b), "{b} never started: {started:?}");
    }
    let timeline = std::fs::read_to_string(out.join("timeline-drone_0.svg")).unwrap();
    for (behavior, n) in &started {
        let hex = palette::behavior_hex(behavior);
        assert_eq!(
            elements_with(&timeline, "rect", "fill", &hex),
            *n,
            "bars of {behavior} ({hex})"
        );
    }

    // Trajectory: a track stroked in the colour of every motion behavior that flew, none in
    // the gimbal's.
    let flown: BTreeSet<String> = recs
        .iter()
        .filter(|r| r["type"] == "pose")
        .filter_map(|r| r["behavior"].as_str().map(String::from))
        .collect();
    assert!(
        flown.contains("takeoff") && flown.contains("follow_path"),
        "{flown:?}"
    );
    let trajectory = std::fs::read_to_string(out.join("trajectory.svg")).unwrap();
    for behavior in &flown {
        let hex = palette::behavior_hex(behavior);
        assert!(
            elements_with(&trajectory, "polyline", "stroke", &hex) > 0,
            "no {behavior} track ({hex})"
        );
        assert!(
            trajectory.contains(behavior.as_str()),
            "legend lacks {behavior}"
        );
    }
    let gimbal = palette::behavior_hex("point_gimbal");
    assert_eq!(elements_with(&trajectory, "polyline", "stroke", &gimbal), 0);

    // poses.csv: one row per pose record, in order per drone.
    let poses = recs.iter().filter(|r| r["type"] == "pose").count();
    let csv = std::fs::read_to_string(out.join("poses.csv")).unwrap();
    let mut lines = csv.lines();
    assert_eq!(
        lines.next(),
        Some("t,drone,x,y,z,yaw,vx,vy,vz,behavior,battery_fraction")
    );
    let rows: Vec<&str> = lines.collect();
    assert_eq!(rows.len(), poses);
    assert!(rows
        .iter()
        .any(|r| r.contains(",drone_0,") && r.contains(",follow_path,")));

    // PNGs decode at the figures' sizes; the page links every figure.
    assert_eq!(png_size(&out.join("trajectory.png")), (800, 800));
    assert_eq!(png_size(&out.join("altitude.png")), (900, 420));
    let rows = started.len() as u32;
    assert_eq!(
        png_size(&out.join("timeline-drone_0.png")),
        (900, 110 + 46 * rows)
    );
    let index = std::fs::read_to_string(out.join("index.html")).unwrap();
    for f in [
        "timeline-drone_0.svg",
        "trajectory.svg",
        "altitude.svg",
        "poses.csv",
    ] {
        assert!(index.contains(f), "index.html lacks {f}");
    }
    assert!(!index.contains("explored.svg"), "not an exploration log");
}

#[test]
fn exploration_report_area_curve_ends_where_the_evaluator_does() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let world = d.join("world.json").display().to_string();
    kestrel(
        d,
        &[
            "world", "generate", "--size-m", "12", "--poles", "4", "--seed", "1", "--out", &world,
        ],
    );
    kestrel(
        d,
        &[
            "explore",
            "--world",
            &world,
            "--drones",
            "3",
            "--speedup",
            "max",
            "--log",
            "ex.jsonl",
        ],
    );
    kestrel(d, &["report", "ex.jsonl", "--out", "rep"]);
    kestrel(
        d,
        &[
            "evaluate",
            "--world",
            &world,
            "--log",
            "ex.jsonl",
            "--out",
            "metrics.json",
        ],
    );
    let metrics: Value =
        serde_json::from_str(&std::fs::read_to_string(d.join("metrics.json")).unwrap()).unwrap();
    let final_pct = metrics["area_pct"].as_f64().unwrap();
    assert!(final_pct > 50.0, "the drones explored: {final_pct}");

    let area = std::fs::read_to_string(d.join("rep/area.csv")).unwrap();
    let points: Vec<(f64, f64)> = area
        .lines()
        .skip(1)
        .map(|l| {
            let (t, a) = l.split_once(',').unwrap();
            (t.parse().unwrap(), a.parse().unwrap())
        })
        .collect();
    assert!(points.len() > 10, "a curve, not a point: {points:?}");
    assert!(
        points.windows(2).all(|w| w[0].1 <= w[1].1),
        "area never shrinks"
    );
    let last = points.last().unwrap().1;
    assert!(
        (last - final_pct).abs() < 1e-6,
        "curve ends at {last}, evaluate says {final_pct}"
    );

    let curve_svg = std::fs::read_to_string(d.join("rep/area.svg")).unwrap();
    assert!(curve_svg.contains("<polyline"));
    let explored = std::fs::read_to_string(d.join("rep/explored.svg")).unwrap();
    for i in 0..3 {
        let hex = palette::hex(palette::drone(i));
        assert!(
            elements_with(&explored, "polyline", "stroke", &hex) > 0,
            "drone {i}"
        );
    }
    assert!(explored.contains("drone_2"));
    let index = std::fs::read_to_string(d.join("rep/index.html")).unwrap();
    assert!(
        index.contains(&format!("{final_pct:.2} %")),
        "the page gives the final area"
    );

    // Without its world the report still draws the tracks and says why the map is missing.
    let text = std::fs::read_to_string(d.join("ex.jsonl")).unwrap();
    let moved = text.replacen(&world, "/nonexistent/world.json", 1);
    std::fs::write(d.join("moved.jsonl"), moved).unwrap();
    kestrel(d, &["report", "moved.jsonl"]);
    let page = std::fs::read_to_string(d.join("moved-report/index.html")).unwrap();
    assert!(page.contains("No explored-area map"), "{page}");
    assert!(page.contains("/nonexistent/world.json"));
    assert!(d.join("moved-report/trajectory.svg").exists());
    assert!(!d.join("moved-report/explored.svg").exists());
}

#[tokio::test]
async fn api_serves_the_report_of_a_listed_log_only() {
    let dir = tempfile::tempdir().unwrap();
    let flown = tempfile::tempdir().unwrap();
    let log = solar_park(flown.path());
    let name = "kestrel-sim-2026-01-01T00-00-00Z.jsonl";
    std::fs::copy(&log, dir.path().join(name)).unwrap();
    std::fs::write(flown.path().join("secret.jsonl"), "{}\n").unwrap();
    let k = support::Kestrel::sim(dir.path(), "", &[]).await;

    let r = k.get_raw(&format!("/api/logs/{name}/report")).await;
    assert_eq!(r.status().as_u16(), 200);
    let content_type = r.headers()["content-type"].to_str().unwrap().to_string();
    assert!(content_type.starts_with("text/html"), "{content_type}");
    let page = r.text().await.unwrap();
    assert!(page.contains(name));
    assert!(page.matches("<svg").count() >= 3, "figures inlined");
    assert!(!page.contains("<img"), "one self-contained page");
    let follow = palette::behavior_hex("follow_path");
    assert!(elements_with(&page, "polyline", "stroke", &follow) > 0);

    let (_, spec) = k.get("/api/openapi.json").await;
    assert!(spec["paths"].get("/api/logs/{name}/report").is_some());

    for bad in [
        "kestrel-sim-2026-01-02T00-00-00Z.jsonl".to_string(),
        format!(
            "..%2F{}%2Fsecret.jsonl",
            flown.path().file_name().unwrap().to_string_lossy()
        ),
        "%2Fetc%2Fpasswd".to_string(),
    ] {
        let (status, body) = k.get(&format!("/api/logs/{bad}/report")).await;
        assert_eq!(status, 404, "{bad}: {body}");
    }
}

#[tokio::test]
async fn api_downloads_a_listed_log_only_and_the_current_one_flushed() {
    let dir = tempfile::tempdir().unwrap();
    let outside = tempfile::tempdir().unwrap();
    let name = "kestrel-sim-2026-01-01T00-00-00Z.jsonl";
    // Larger than one 64 KiB chunk, so the download is assembled from several.
    let past: String = (0..3000)
        .map(|i| format!("{{\"t\":{i}.0,\"drone\":\"drone_0\",\"type\":\"pose\"}}\n"))
        .collect();
    assert!(past.len() > 2 * 64 * 1024);
    std::fs::write(dir.path().join(name), &past).unwrap();
    std::fs::write(outside.path().join("secret.jsonl"), "{}\n").unwrap();
    let k = support::Kestrel::sim(dir.path(), "s3cret", &[]).await;

    let r = k.get_raw(&format!("/api/logs/{name}")).await;
    assert_eq!(r.status().as_u16(), 200);
    assert_eq!(r.headers()["content-type"], "application/x-ndjson");
    assert_eq!(
        r.headers()["content-disposition"],
        format!("attachment; filename=\"{name}\"").as_str()
    );
    assert_eq!(r.text().await.unwrap(), past, "the file byte for byte");

    // The current log: what was written up to the request, header record first.
    let (_, listed) = k.get("/api/logs").await;
    let current = listed
        .as_array()
        .unwrap()
        .iter()
        .find(|e| e["current"] == true)
        .unwrap()["name"]
        .as_str()
        .unwrap()
        .to_string();
    let text = k
        .get_raw(&format!("/api/logs/{current}"))
        .await
        .text()
        .await
        .unwrap();
    let first: Value = serde_json::from_str(text.lines().next().unwrap()).unwrap();
    assert_eq!(first["type"], "header", "{first}");

    let (_, spec) = k.get("/api/openapi.json").await;
    assert!(spec["paths"].get("/api/logs/{name}").is_some());

    // Without the token: 401, nothing served.
    let anon = reqwest::get(format!("{}/api/logs/{name}", k.base))
        .await
        .unwrap();
    assert_eq!(anon.status().as_u16(), 401);

    for bad in [
        "kestrel-sim-2026-01-02T00-00-00Z.jsonl".to_string(),
        format!(
            "..%2F{}%2Fsecret.jsonl",
            outside.path().file_name().unwrap().to_string_lossy()
        ),
        "%2Fetc%2Fpasswd".to_string(),
    ] {
        let (status, body) = k.get(&format!("/api/logs/{bad}")).await;
        assert_eq!(status, 404, "{bad}: {body}");
    }
}
