//! `kestrel report`: a flight log made into a page of figures (the thesis's figures).
//!
//! In: a flight log (JSON lines or MCAP), optionally `--out DIR` and `--world FILE` (the true world of
//! an exploration log, when its header's is missing or moved). Out: DIR (default
//! `<log stem>-report/` beside the log) with `index.html`, every figure as SVG and PNG,
//! `poses.csv`, and `area.csv` for an evaluated exploration; the files written on stdout.
//! With `--runs DIR` instead: every exploration run under DIR in one figure of time and area
//! against the number of drones (`report::runs`), into `--out` (default `DIR/runs-report/`).

use anyhow::{Context, Result};
use clap::Args;
use kestrel::report::{self, Exploration, Options};
use std::path::PathBuf;

#[derive(Args, Debug)]
pub struct ReportArgs {
    /// Flight log to report on (JSON lines or MCAP, told apart by the file's first bytes).
    #[arg(required_unless_present = "runs", conflicts_with = "runs")]
    flight_log: Option<PathBuf>,
    /// Directory of exploration runs (`kestrel explore` reports and flight logs) to draw
    /// together: time and area against the number of drones.
    #[arg(long, value_name = "DIR", conflicts_with = "world")]
    runs: Option<PathBuf>,
    /// The thesis's table (CSV) to draw beside the runs, e.g. benches/thesis-exploration-results.csv.
    #[arg(long, value_name = "CSV", requires = "runs")]
    thesis: Option<PathBuf>,
    /// Directory to write into (created if missing). Default: <log stem>-report/ beside the log.
    #[arg(long)]
    out: Option<PathBuf>,
    /// World file of an exploration log (JSON), instead of the one its header names.
    #[arg(long)]
    world: Option<PathBuf>,
}

pub fn run(args: ReportArgs) -> Result<()> {
    let (Some(log), None) = (&args.flight_log, &args.runs) else {
        return runs(&args);
    };
    let flight =
        report::read_file(log).with_context(|| format!("reading flight log {}", log.display()))?;
    let dir = log.parent().map(PathBuf::from).unwrap_or_default();
    let stem = log
        .file_stem()
        .map_or("flight".into(), |s| s.to_string_lossy().into_owned());
    let out = args
        .out
        .clone()
        .unwrap_or_else(|| dir.join(format!("{stem}-report")));
    let name = log
        .file_name()
        .map_or(stem.clone(), |s| s.to_string_lossy().into_owned());
    let options = Options {
        world: args.world.clone(),
        log_dir: Some(dir),
    };
    let report = report::analyse(&name, flight, &options);
    if report.flight.skipped_lines > 0 {
        eprintln!(
            "kestrel report: skipped {} malformed line(s) of {}",
            report.flight.skipped_lines,
            log.display()
        );
    }
    if let Exploration::NoWorld(reason) = &report.exploration {
        eprintln!("kestrel report: no explored-area figures: {reason}");
    }
    let written = report::write_dir(&report, &out)
        .with_context(|| format!("writing the report into {}", out.display()))?;
    for path in written {
        println!("{}", path.display());
    }
    Ok(())
}

fn runs(args: &ReportArgs) -> Result<()> {
    let Some(dir) = &args.runs else {
        anyhow::bail!("give a flight log or --runs DIR");
    };
    let out = args.out.clone().unwrap_or_else(|| dir.join("runs-report"));
    let written = report::runs::write_dir(dir, &out, args.thesis.as_deref())
        .with_context(|| format!("reporting the runs under {}", dir.display()))?;
    for path in written {
        println!("{}", path.display());
    }
    Ok(())
}
