#![allow(clippy::unwrap_used, clippy::expect_used)]
use super::*;

fn run(series: &str, drones: usize, time_s: f64, area_pct: f64) -> Run {
    Run {
        file: PathBuf::from(format!("{series}-{drones}-{time_s}")),
        series: series.into(),
        drones,
        time_s,
        area_pct,
    }
}

#[test]
fn runs_are_grouped_by_series_and_drone_count_with_mean_sd_and_range() {
    let runs = [
        run("low", 3, 100.0, 90.0),
        run("high", 3, 300.0, 80.0),
        run("low", 1, 400.0, 99.0),
        run("low", 3, 140.0, 94.0),
    ];
    let groups = group(&runs);
    let keys: Vec<(&str, usize, usize)> = groups
        .iter()
        .map(|g| (g.series.as_str(), g.drones, g.runs))
        .collect();
    assert_eq!(keys, [("high", 3, 1), ("low", 1, 1), ("low", 3, 2)]);
    let low3 = &groups[2];
    assert_eq!(low3.time_s.mean, 120.0);
    assert_eq!((low3.time_s.min, low3.time_s.max), (100.0, 140.0));
    assert!((low3.time_s.sd - 800f64.sqrt()).abs() < 1e-9, "sample sd");
    assert_eq!(low3.area_pct.mean, 92.0);
    assert_eq!(groups[0].time_s.sd, 0.0, "one run has no spread");
    let csv = csv(&groups);
    assert_eq!(csv.lines().count(), 4);
    assert!(csv.contains("\nlow,3,2,120.00,28.28,100.00,140.00,92.0000,"));
}

#[test]
fn an_explore_report_gives_world_drones_time_and_area_and_names_the_file_when_not() {
    let p = Path::new("runs/low-3-0.report.json");
    let text = r#"{"metrics":{"time_s":812.5,"area_pct":97.25},"world":"sitl/worlds/low.json",
        "drones":3,"seed":0,"allocator":"kestrel"}"#;
    let r = from_report(p, text).unwrap();
    assert_eq!(
        r,
        Run {
            file: p.into(),
            series: "low".into(),
            drones: 3,
            time_s: 812.5,
            area_pct: 97.25
        }
    );
    let other = text.replace("\"kestrel\"", "\"nearest\"");
    assert_eq!(from_report(p, &other).unwrap().series, "low/nearest");
    let e = from_report(p, &text.replace("time_s", "t"))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("low-3-0.report.json") && e.contains("/metrics/time_s"),
        "{e}"
    );
    let e = from_report(p, &text.replace("\"drones\":3", "\"drones\":0")).unwrap_err();
    assert!(e.to_string().contains("not a count"), "{e}");
}

#[test]
fn find_takes_reports_and_logs_once_each_and_bounds_the_depth() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let deep = d.join("a/b/c/d/e");
    std::fs::create_dir_all(d.join("sub")).unwrap();
    std::fs::create_dir_all(&deep).unwrap();
    for f in [
        "x.jsonl",
        "x.report.json",
        "y.mcap",
        "notes.txt",
        "sub/z.report.json",
    ] {
        std::fs::write(d.join(f), "").unwrap();
    }
    std::fs::write(deep.join("too-deep.jsonl"), "").unwrap();
    let found: Vec<String> = find(d)
        .unwrap()
        .iter()
        .map(|p| p.strip_prefix(d).unwrap().display().to_string())
        .collect();
    assert_eq!(found, ["sub/z.report.json", "x.report.json", "y.mcap"]);
}

#[test]
fn thesis_rows_are_read_by_column_name() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path().join("thesis.csv");
    std::fs::write(
        &p,
        "# a comment\nworld,drones,time_s,time_sd,area_pct,area_sd,path_m\n\
         low,3,1010.5,20.1,99.1,0.02,400\nhigh,7,600,,95.5,,\n",
    )
    .unwrap();
    let rows = thesis_rows(&p).unwrap();
    assert_eq!(rows.len(), 2);
    assert_eq!(
        (rows[0].world.as_str(), rows[0].drones, rows[0].time_s),
        ("low", 3, 1010.5)
    );
    assert_eq!((rows[1].time_sd, rows[1].area_pct), (0.0, 95.5));
    std::fs::write(&p, "world,drones,time_s\nlow,1,2\n").unwrap();
    let e = thesis_rows(&p).unwrap_err().to_string();
    assert!(e.contains("thesis.csv") && e.contains("time_sd"), "{e}");
}
