//! Several explorations side by side (`kestrel report --runs DIR`, thesis Fig. 5.23): time and
//! area known against the number of drones, mean and spread over the runs of each group.
//!
//! In: a directory holding, at most [`MAX_DEPTH`] levels down, `kestrel explore` reports
//! (`*.report.json`, their `metrics`) and flight logs of explorations (`*.jsonl`, `*.mcap`,
//! judged by the evaluator against the header's world, as `kestrel report` does); a log whose
//! `<stem>.report.json` lies beside it is counted once, through the report. Optionally the
//! thesis's table (CSV: world, drones, time_s, time_sd, area_pct, area_sd) drawn beside. Out:
//! [`Group`]s, one per (series, drone count), where the series is the world's file stem, and
//! the allocator when a report names one other than Kestrel's; written by [`write_dir`] as
//! `runs.svg/.png`, `runs.csv` and `index.html`.

use super::figures::Figure;
use super::{exploration, read_file, runs_figure, Exploration, Options, ReportError};
use serde_json::Value;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Most run files read from one directory.
pub const MAX_RUN_FILES: usize = 1000;
/// Largest explore report or thesis table read (bytes).
pub const MAX_TABLE_BYTES: u64 = 16 << 20;
/// Deepest subdirectory searched below the runs directory.
pub const MAX_DEPTH: usize = 4;
const REPORT_SUFFIX: &str = ".report.json";
/// The allocator `kestrel explore` uses unless told otherwise.
const DEFAULT_ALLOCATOR: &str = "kestrel";

/// One exploration run.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    pub file: PathBuf,
    /// The group's series: world stem, plus `/allocator` for a non-default allocator.
    pub series: String,
    pub drones: usize,
    /// First take-off to last landing (s).
    pub time_s: f64,
    /// Known cells / all grid cells x 100.
    pub area_pct: f64,
}

/// Mean, sample standard deviation (0 for one run) and range of a quantity over runs.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Spread {
    pub mean: f64,
    pub sd: f64,
    pub min: f64,
    pub max: f64,
}

impl Spread {
    /// `None` for no values.
    pub fn of(values: &[f64]) -> Option<Spread> {
        let n = values.len() as f64;
        if values.is_empty() {
            return None;
        }
        let mean = values.iter().sum::<f64>() / n;
        let var = values.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (n - 1.0).max(1.0);
        Some(Spread {
            mean,
            sd: var.sqrt(),
            min: values.iter().copied().fold(f64::INFINITY, f64::min),
            max: values.iter().copied().fold(f64::NEG_INFINITY, f64::max),
        })
    }
}

/// The runs of one series with one drone count.
#[derive(Debug, Clone, PartialEq)]
pub struct Group {
    pub series: String,
    pub drones: usize,
    pub runs: usize,
    pub time_s: Spread,
    pub area_pct: Spread,
}

/// One row of the thesis's table (means and standard deviations).
#[derive(Debug, Clone, PartialEq)]
pub struct ThesisRow {
    pub world: String,
    pub drones: usize,
    pub time_s: f64,
    pub time_sd: f64,
    pub area_pct: f64,
    pub area_sd: f64,
}

fn io(what: &str, path: &Path, e: impl std::fmt::Display) -> ReportError {
    ReportError::Io(format!("{what} {}: {e}", path.display()))
}

fn bad(path: &Path, why: &str) -> ReportError {
    ReportError::Io(format!("{}: {why}", path.display()))
}

/// The run files under `dir`, in path order.
pub fn find(dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
    let mut found = Vec::new();
    walk(dir, 0, &mut found)?;
    found.sort();
    let reports: Vec<PathBuf> = found.iter().filter(|p| is_report(p)).cloned().collect();
    found.retain(|p| is_report(p) || !reports.contains(&p.with_extension("report.json")));
    Ok(found)
}

fn is_report(path: &Path) -> bool {
    path.to_string_lossy().ends_with(REPORT_SUFFIX)
}

fn is_log(path: &Path) -> bool {
    matches!(
        path.extension().and_then(|e| e.to_str()),
        Some("jsonl" | "mcap")
    )
}

fn walk(dir: &Path, depth: usize, found: &mut Vec<PathBuf>) -> Result<(), ReportError> {
    let entries = std::fs::read_dir(dir).map_err(|e| io("reading directory", dir, e))?;
    for entry in entries {
        let path = entry.map_err(|e| io("reading directory", dir, e))?.path();
        if path.is_dir() {
            if depth < MAX_DEPTH {
                walk(&path, depth + 1, found)?;
            }
        } else if is_report(&path) || is_log(&path) {
            if found.len() >= MAX_RUN_FILES {
                return Err(bad(
                    dir,
                    &format!("more than {MAX_RUN_FILES} run files (reports and logs)"),
                ));
            }
            found.push(path);
        }
    }
    Ok(())
}

fn read_bounded(path: &Path) -> Result<String, ReportError> {
    let size = std::fs::metadata(path)
        .map_err(|e| io("reading", path, e))?
        .len();
    if size > MAX_TABLE_BYTES {
        return Err(ReportError::TooLarge {
            path: path.display().to_string(),
            size,
            max: MAX_TABLE_BYTES,
        });
    }
    std::fs::read_to_string(path).map_err(|e| io("reading", path, e))
}

fn world_stem(world: &str) -> String {
    Path::new(world)
        .file_stem()
        .map_or_else(|| world.to_string(), |s| s.to_string_lossy().into_owned())
}

/// A run from a `kestrel explore` report.
pub fn from_report(path: &Path, text: &str) -> Result<Run, ReportError> {
    let v: Value = serde_json::from_str(text).map_err(|e| bad(path, &format!("not JSON: {e}")))?;
    let num = |p: &str| v.pointer(p).and_then(Value::as_f64);
    let need = |p: &str| num(p).ok_or_else(|| bad(path, &format!("no number at {p}")));
    let world = v
        .get("world")
        .and_then(Value::as_str)
        .ok_or_else(|| bad(path, "no \"world\" (is it a kestrel explore report?)"))?;
    let mut series = world_stem(world);
    if let Some(a) = v.get("allocator").and_then(Value::as_str) {
        if a != DEFAULT_ALLOCATOR {
            series = format!("{series}/{a}");
        }
    }
    let drones = need("/drones")?;
    if !(drones >= 1.0 && drones.fract() == 0.0) {
        return Err(bad(path, &format!("\"drones\" is {drones}, not a count")));
    }
    Ok(Run {
        file: path.to_path_buf(),
        series,
        drones: drones as usize,
        time_s: need("/metrics/time_s")?,
        area_pct: need("/metrics/area_pct")?,
    })
}

/// A run from a flight log, judged against its header's world.
fn from_log(path: &Path) -> Result<Run, ReportError> {
    let flight = read_file(path).map_err(|e| bad(path, &e.to_string()))?;
    let options = Options {
        world: None,
        log_dir: path.parent().map(Path::to_path_buf),
    };
    let world = flight
        .world()
        .ok_or_else(|| bad(path, "the header names no world: not an exploration log"))?
        .to_string();
    let drones = flight
        .header
        .as_ref()
        .and_then(|h| h.get("drones"))
        .and_then(Value::as_array)
        .map_or(flight.drones.len(), Vec::len);
    match exploration(&flight, &options) {
        Exploration::Evaluated { metrics, .. } => Ok(Run {
            file: path.to_path_buf(),
            series: world_stem(&world),
            drones,
            time_s: metrics.time_s,
            area_pct: metrics.area_pct,
        }),
        Exploration::NoWorld(why) => Err(bad(path, &why)),
        Exploration::None => Err(bad(path, "not an exploration log")),
    }
}

/// Reads one run file (report or log).
pub fn read_run(path: &Path) -> Result<Run, ReportError> {
    if is_report(path) {
        from_report(path, &read_bounded(path)?)
    } else {
        from_log(path)
    }
}

/// The runs grouped by (series, drone count), in that order.
pub fn group(runs: &[Run]) -> Vec<Group> {
    let mut by: BTreeMap<(&str, usize), Vec<&Run>> = BTreeMap::new();
    for r in runs {
        by.entry((&r.series, r.drones)).or_default().push(r);
    }
    by.into_iter()
        .filter_map(|((series, drones), rs)| {
            let times: Vec<f64> = rs.iter().map(|r| r.time_s).collect();
            let areas: Vec<f64> = rs.iter().map(|r| r.area_pct).collect();
            Some(Group {
                series: series.to_string(),
                drones,
                runs: rs.len(),
                time_s: Spread::of(&times)?,
                area_pct: Spread::of(&areas)?,
            })
        })
        .collect()
}

/// The thesis's rows from its CSV table (`#` lines are comments; the header names the columns).
pub fn thesis_rows(path: &Path) -> Result<Vec<ThesisRow>, ReportError> {
    let text = read_bounded(path)?;
    let mut lines = text
        .lines()
        .filter(|l| !l.starts_with('#') && !l.is_empty());
    let header: Vec<&str> = lines.next().unwrap_or_default().split(',').collect();
    let col = |name: &str| {
        header
            .iter()
            .position(|h| h.trim() == name)
            .ok_or_else(|| bad(path, &format!("no column {name}")))
    };
    let cols = [
        col("world")?,
        col("drones")?,
        col("time_s")?,
        col("time_sd")?,
        col("area_pct")?,
        col("area_sd")?,
    ];
    let mut out = Vec::new();
    for (n, line) in lines.enumerate() {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let row = thesis_row(&cells, &cols);
        out.push(row.ok_or_else(|| bad(path, &format!("data row {} is incomplete", n + 1)))?);
    }
    Ok(out)
}

/// A row from its cells and the positions of world, drones, time_s, time_sd, area_pct and
/// area_sd; the standard deviations may be empty.
fn thesis_row(cells: &[&str], cols: &[usize; 6]) -> Option<ThesisRow> {
    let cell = |i: usize| cells.get(cols[i]).copied().unwrap_or_default();
    let num = |i: usize| cell(i).parse::<f64>().ok();
    Some(ThesisRow {
        world: cell(0).to_string(),
        drones: cell(1).parse().ok()?,
        time_s: num(2)?,
        time_sd: num(3).unwrap_or(0.0),
        area_pct: num(4)?,
        area_sd: num(5).unwrap_or(0.0),
    })
}

/// `runs.csv`: one line per group.
pub fn csv(groups: &[Group]) -> String {
    use std::fmt::Write;
    let mut out = String::from(
        "series,drones,runs,time_mean_s,time_sd_s,time_min_s,time_max_s,\
         area_mean_pct,area_sd_pct,area_min_pct,area_max_pct\n",
    );
    for g in groups {
        let (t, a) = (g.time_s, g.area_pct);
        let _ = writeln!(
            out,
            "{},{},{},{:.2},{:.2},{:.2},{:.2},{:.4},{:.4},{:.4},{:.4}",
            super::csv::cell(&g.series),
            g.drones,
            g.runs,
            t.mean,
            t.sd,
            t.min,
            t.max,
            a.mean,
            a.sd,
            a.min,
            a.max
        );
    }
    out
}

/// Reads every run under `dir`, writes the figure, `runs.csv` and `index.html` into `out`;
/// returns the files written.
pub fn write_dir(
    dir: &Path,
    out: &Path,
    thesis: Option<&Path>,
) -> Result<Vec<PathBuf>, ReportError> {
    let files = find(dir)?;
    if files.is_empty() {
        return Err(bad(
            dir,
            "no exploration runs (*.report.json, *.jsonl, *.mcap)",
        ));
    }
    let runs = files
        .iter()
        .map(|f| read_run(f))
        .collect::<Result<Vec<_>, _>>()?;
    let groups = group(&runs);
    let thesis = thesis.map(thesis_rows).transpose()?.unwrap_or_default();
    std::fs::create_dir_all(out).map_err(|e| io("creating", out, e))?;
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), ReportError> {
        let path = out.join(name);
        std::fs::write(&path, bytes).map_err(|e| io("writing", &path, e))?;
        written.push(path);
        Ok(())
    };
    let figure = Figure::Runs {
        groups: &groups,
        thesis: &thesis,
    };
    let size = runs_figure::SIZE_PX;
    put("runs.svg", figure.svg(size)?.as_bytes())?;
    put("runs.png", &figure.png(size)?)?;
    put("runs.csv", csv(&groups).as_bytes())?;
    let page = runs_figure::page(dir, &runs, &groups, !thesis.is_empty());
    put("index.html", page.as_bytes())?;
    Ok(written)
}

#[cfg(test)]
mod tests;
