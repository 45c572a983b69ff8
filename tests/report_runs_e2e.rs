#![allow(clippy::unwrap_used, clippy::expect_used)]
//! End to end: the thesis's exploration figures from real `kestrel explore` runs on a small
//! seeded world: `kestrel report` draws the map at 25/50/75/100 % of the final area with the
//! starts marked and gives each drone's explored area; `kestrel report --runs DIR` groups the
//! runs by world and drone count and draws time and area against the number of drones.

use kestrel::report::palette;
use std::path::Path;
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

/// Polygons of the SVG filled with `hex` (the start diamonds carry their drone's colour).
fn polygons_filled(svg: &str, hex: &str) -> usize {
    let want = format!("fill=\"{hex}\"");
    svg.split("<polygon ")
        .skip(1)
        .filter(|e| e.split('>').next().is_some_and(|a| a.contains(&want)))
        .count()
}

/// Explores the world with `drones` drones and `seed`; log and report in `runs/`.
fn explore(dir: &Path, world: &str, drones: usize, seed: u64) -> String {
    let tag = format!("runs/small-{drones}-{seed}");
    let (n, s) = (drones.to_string(), seed.to_string());
    let log = format!("{tag}.jsonl");
    kestrel(
        dir,
        &[
            "explore", "--world", world, "--drones", &n, "--seed", &s, "--log", &log,
        ],
    );
    log
}

#[test]
fn snapshots_per_drone_area_and_the_runs_figure() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    std::fs::create_dir(d.join("runs")).unwrap();
    let world = d.join("small.json").display().to_string();
    kestrel(
        d,
        &[
            "world", "generate", "--size-m", "12", "--poles", "3", "--seed", "2", "--out", &world,
        ],
    );
    let two = explore(d, &world, 2, 0);
    explore(d, &world, 2, 1);
    let one = explore(d, &world, 1, 0);

    kestrel(d, &["report", &two, "--out", "rep"]);
    let mut times = Vec::new();
    for pct in ["25", "50", "75", "100"] {
        let svg = std::fs::read_to_string(d.join(format!("rep/explored-{pct}.svg"))).unwrap();
        assert!(d.join(format!("rep/explored-{pct}.png")).is_file());
        for i in 0..2 {
            let hex = palette::hex(palette::drone(i));
            assert_eq!(
                polygons_filled(&svg, &hex),
                1,
                "one start diamond of drone {i}"
            );
        }
        let caption = svg.split("Explored by t = ").nth(1).unwrap();
        let t: f64 = caption.split(' ').next().unwrap().parse().unwrap();
        times.push(t);
    }
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    assert!(times[0] < times[3], "25 % comes before 100 %: {times:?}");
    let page = std::fs::read_to_string(d.join("rep/index.html")).unwrap();
    assert!(page.contains("explored area (%)"));
    assert!(page.contains("explored-75.svg"));
    let report: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(d.join("runs/small-2-0.report.json")).unwrap(),
    )
    .unwrap();
    for drone in report["metrics"]["drones"].as_array().unwrap() {
        let pct = drone["area_pct"].as_f64().unwrap();
        assert!(pct > 1.0, "{drone}");
        let row = format!("<td>{}</td>", drone["drone"].as_str().unwrap());
        let cells = page
            .split(&row)
            .nth(1)
            .unwrap()
            .split("</tr>")
            .next()
            .unwrap();
        assert!(cells.contains(&format!("<td>{pct:.2}</td>")), "{cells}");
    }

    // One run through its flight log only (its report removed), the others through reports.
    std::fs::remove_file(d.join(one.replace(".jsonl", ".report.json"))).unwrap();
    let out = kestrel(d, &["report", "--runs", "runs", "--out", "fig"]);
    let listed = String::from_utf8_lossy(&out.stdout);
    assert!(
        listed.contains("runs.svg") && listed.contains("runs.png"),
        "{listed}"
    );
    let csv = std::fs::read_to_string(d.join("fig/runs.csv")).unwrap();
    let groups: Vec<Vec<&str>> = csv
        .lines()
        .skip(1)
        .map(|l| l.split(',').collect())
        .collect();
    let keys: Vec<(&str, &str, &str)> = groups.iter().map(|g| (g[0], g[1], g[2])).collect();
    assert_eq!(keys, [("small", "1", "1"), ("small", "2", "2")]);
    let area_mean: f64 = groups[1][7].parse().unwrap();
    let expected = report["metrics"]["area_pct"].as_f64().unwrap();
    let other: serde_json::Value = serde_json::from_str(
        &std::fs::read_to_string(d.join("runs/small-2-1.report.json")).unwrap(),
    )
    .unwrap();
    let mean = (expected + other["metrics"]["area_pct"].as_f64().unwrap()) / 2.0;
    assert!((area_mean - mean).abs() < 1e-3, "{area_mean} vs {mean}");
    let svg = std::fs::read_to_string(d.join("fig/runs.svg")).unwrap();
    assert!(svg.contains("Time to explore against drones"));
    assert!(svg.contains("small (min–max)"));
    let index = std::fs::read_to_string(d.join("fig/index.html")).unwrap();
    assert!(
        index.contains("small-1-0.jsonl"),
        "the log read in place of its report"
    );

    // A file that is not an exploration run is refused by name.
    std::fs::write(d.join("runs/broken.report.json"), "{\"world\": 3}").unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_kestrel"))
        .current_dir(d)
        .args(["report", "--runs", "runs", "--out", "fig2"])
        .output()
        .unwrap();
    assert!(!out.status.success());
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("broken.report.json"), "{err}");
}
