//! Flight reports: a flight log made into a page of figures and numbers (`kestrel report` and
//! `GET /api/logs/{name}/report`).
//!
//! In: a JSON-lines flight log ([`read_file`] or [`read::read`]), and for exploration logs the
//! true world (the header's `world`, or one given). Out: a [`Report`] written either as a
//! directory ([`write_dir`]: `index.html`, each figure as SVG and PNG, `poses.csv`, and
//! `area.csv` when the world is known) or as one self-contained HTML page with the figures
//! inlined as SVG ([`inline_html`]). Exploration metrics come from `exploration::offline::evaluate`,
//! the same evaluator as `kestrel evaluate`.
//!
//! Exploration reports add the map at 25/50/75/100 % of the final area (`snapshots`). Several
//! runs together (`kestrel report --runs DIR`): [`runs::write_dir`].
//!
//! Files: `read` (the log), `stats` (the per-drone table), `snapshots`, `palette`, `figures` and
//! `tracks` (plotters drawings), `html` (the page), `csv` (the exports), `runs` and
//! `runs_figure` (several runs: reading, grouping, the figure and page).

mod csv;
pub mod figures;
mod html;
pub mod palette;
pub mod read;
pub mod runs;
mod runs_figure;
pub mod snapshots;
pub mod stats;
mod tracks;

use crate::exploration::offline::evaluate::{
    self, EvalParams, ExplorationMetrics, KnownMap, PoseSample,
};
use crate::flightlog::reader;
use crate::sim::world::World;
use figures::Figure;
use read::Flight;
use snapshots::Snapshot;
use stats::DroneStats;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// Largest flight log read (bytes), as `kestrel evaluate`.
pub const MAX_LOG_BYTES: u64 = 2 << 30;
/// Spacing of the area curve's points (s of log time).
pub const AREA_STEP_S: f64 = 1.0;
/// Figure sizes (px).
const WIDE_PX: (u32, u32) = (900, 420);
const SQUARE_PX: (u32, u32) = (800, 800);
const TIMELINE_ROW_PX: u32 = 46;

#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("{0}")]
    Io(String),
    #[error("log line {line} is longer than {max_bytes} bytes")]
    LineTooLong { line: usize, max_bytes: usize },
    #[error("log line {line}: more than {max} pose records")]
    TooManyPoses { line: usize, max: usize },
    #[error("{path} is {size} bytes, more than the {max} read")]
    TooLarge { path: String, size: u64, max: u64 },
    #[error("drawing a figure: {0}")]
    Plot(String),
}

/// Where the world of an exploration log comes from.
#[derive(Debug, Clone, Default)]
pub struct Options {
    /// A world file given by the user (wins over the header's).
    pub world: Option<PathBuf>,
    /// Directory the header's relative `world` path is tried against first (then the working
    /// directory): the log's own directory.
    pub log_dir: Option<PathBuf>,
}

/// The exploration part of a report.
pub enum Exploration {
    /// Not an exploration log (no `explore` command, behavior or world).
    None,
    /// An exploration log whose world could not be used; the reason is shown in the page.
    NoWorld(String),
    Evaluated {
        world_path: PathBuf,
        world: Box<World>,
        metrics: Box<ExplorationMetrics>,
        map: KnownMap,
        /// The map when 25, 50, 75 and 100 % of the final area was first known.
        snapshots: Vec<Snapshot>,
    },
}

pub struct Report {
    /// The log's file name, as the page shows it.
    pub name: String,
    pub flight: Flight,
    pub stats: BTreeMap<String, DroneStats>,
    pub exploration: Exploration,
}

/// Reads a log file of either format (JSON lines or MCAP, `flightlog::reader`), refusing one
/// over [`MAX_LOG_BYTES`].
pub fn read_file(path: &Path) -> Result<Flight, ReportError> {
    let io = |e: std::io::Error| ReportError::Io(format!("reading {}: {e}", path.display()));
    let size = std::fs::metadata(path).map_err(io)?.len();
    if size > MAX_LOG_BYTES {
        return Err(ReportError::TooLarge {
            path: path.display().to_string(),
            size,
            max: MAX_LOG_BYTES,
        });
    }
    read::read(reader::open(path, MAX_LOG_BYTES).map_err(io)?)
}

/// Computes the table and, for an exploration log, the evaluator's metrics and map.
pub fn analyse(name: &str, flight: Flight, options: &Options) -> Report {
    let stats = flight
        .drones
        .iter()
        .map(|(d, log)| (d.clone(), stats::stats(log)))
        .collect();
    let exploration = exploration(&flight, options);
    Report {
        name: name.to_string(),
        flight,
        stats,
        exploration,
    }
}

fn is_exploration(flight: &Flight) -> bool {
    flight.command() == Some("explore")
        || flight.world().is_some()
        || flight
            .drones
            .values()
            .any(|d| d.activations.iter().any(|a| a.behavior == "explore"))
}

fn exploration(flight: &Flight, options: &Options) -> Exploration {
    if options.world.is_none() && !is_exploration(flight) {
        return Exploration::None;
    }
    let world_path = match (&options.world, flight.world()) {
        (Some(w), _) => w.clone(),
        (None, Some(w)) => {
            let w = PathBuf::from(w);
            match &options.log_dir {
                Some(dir) if w.is_relative() && dir.join(&w).is_file() => dir.join(&w),
                _ => w,
            }
        }
        (None, None) => {
            return Exploration::NoWorld(
                "the log names no world file (give one with --world)".into(),
            )
        }
    };
    let world = match World::load(&world_path) {
        Ok(w) => w,
        Err(e) => return Exploration::NoWorld(e.to_string()),
    };
    let samples: Vec<PoseSample> = flight
        .drones
        .iter()
        .flat_map(|(drone, log)| {
            // Judged where the drones were, not where they believed they were.
            log.poses.iter().map(move |p| {
                let [x_m, y_m, z_m, yaw_rad] = p.truth.unwrap_or([p.x_m, p.y_m, p.z_m, p.yaw_rad]);
                PoseSample {
                    t_s: p.t_s,
                    drone: drone.clone(),
                    x_m,
                    y_m,
                    z_m,
                    yaw_rad,
                    crashed: p.crashed,
                }
            })
        })
        .collect();
    let params = EvalParams {
        curve_step_s: AREA_STEP_S,
        ..EvalParams::default()
    };
    match evaluate::evaluate_with_map(&world, &samples, &params) {
        Ok((metrics, map)) => Exploration::Evaluated {
            world_path,
            world: Box::new(world),
            metrics: Box::new(metrics),
            snapshots: snapshots::snapshots(&map),
            map,
        },
        Err(e) => Exploration::NoWorld(format!("evaluating against {}: {e}", world_path.display())),
    }
}

/// One figure of the page: file stem, title, what to draw and its size.
pub struct Plot<'a> {
    pub stem: String,
    pub title: String,
    pub figure: Figure<'a>,
    pub size_px: (u32, u32),
}

/// A drone id made safe for a file name.
fn file_safe(id: &str) -> String {
    id.chars()
        .map(|c| {
            if c.is_ascii_alphanumeric() || c == '-' || c == '_' {
                c
            } else {
                '_'
            }
        })
        .collect()
}

/// The report's figures, in page order.
pub fn plots(report: &Report) -> Vec<Plot<'_>> {
    let mut out = Vec::new();
    for (drone, log) in &report.flight.drones {
        let rows = log
            .activations
            .iter()
            .map(|a| a.behavior.as_str())
            .collect::<std::collections::BTreeSet<_>>()
            .len()
            .max(1) as u32;
        out.push(Plot {
            stem: format!("timeline-{}", file_safe(drone)),
            title: format!("Behavior activations of {drone}"),
            figure: Figure::Timeline { drone, log },
            size_px: (WIDE_PX.0, 110 + TIMELINE_ROW_PX * rows),
        });
    }
    out.push(Plot {
        stem: "trajectory".into(),
        title: "Trajectories, coloured by the active motion behavior".into(),
        figure: Figure::Trajectory(&report.flight),
        size_px: SQUARE_PX,
    });
    out.push(Plot {
        stem: "altitude".into(),
        title: "Altitude over distance flown".into(),
        figure: Figure::Altitude(&report.flight),
        size_px: WIDE_PX,
    });
    if let Exploration::Evaluated {
        world,
        metrics,
        map,
        snapshots,
        ..
    } = &report.exploration
    {
        out.push(Plot {
            stem: "explored".into(),
            title: "Explored area (the evaluator's known cells) with the tracks".into(),
            figure: Figure::Explored {
                flight: &report.flight,
                map,
                world,
                until_s: None,
            },
            size_px: SQUARE_PX,
        });
        for shot in snapshots {
            out.push(Plot {
                stem: format!("explored-{:.0}", shot.pct_of_final),
                title: format!(
                    "Explored when {:.0} % of the final area was first known (log time {:.1} s), \
                     tracks up to then, starts as diamonds",
                    shot.pct_of_final, shot.t_s
                ),
                figure: Figure::Explored {
                    flight: &report.flight,
                    map: &shot.map,
                    world,
                    until_s: Some(shot.t_s),
                },
                size_px: SQUARE_PX,
            });
        }
        out.push(Plot {
            stem: "area".into(),
            title: "Known area over time".into(),
            figure: Figure::AreaCurve(&metrics.area_curve),
            size_px: WIDE_PX,
        });
    }
    out
}

/// Writes the report into `dir` (created if missing); returns the files written.
pub fn write_dir(report: &Report, dir: &Path) -> Result<Vec<PathBuf>, ReportError> {
    let io = |p: &Path, e: std::io::Error| ReportError::Io(format!("writing {}: {e}", p.display()));
    std::fs::create_dir_all(dir).map_err(|e| io(dir, e))?;
    let mut written = Vec::new();
    let mut put = |name: &str, bytes: &[u8]| -> Result<(), ReportError> {
        let path = dir.join(name);
        std::fs::write(&path, bytes).map_err(|e| io(&path, e))?;
        written.push(path);
        Ok(())
    };
    let plots = plots(report);
    for plot in &plots {
        put(
            &format!("{}.svg", plot.stem),
            plot.figure.svg(plot.size_px)?.as_bytes(),
        )?;
        put(
            &format!("{}.png", plot.stem),
            &plot.figure.png(plot.size_px)?,
        )?;
    }
    put("poses.csv", csv::poses(&report.flight).as_bytes())?;
    if let Exploration::Evaluated { metrics, .. } = &report.exploration {
        put("area.csv", csv::area(&metrics.area_curve).as_bytes())?;
    }
    let figures: Vec<(String, String)> = plots
        .iter()
        .map(|p| (p.title.clone(), html::linked(&p.stem, p.size_px)))
        .collect();
    put("index.html", html::page(report, &figures, true).as_bytes())?;
    Ok(written)
}

/// The whole report as one HTML page, figures inlined as SVG.
pub fn inline_html(report: &Report) -> Result<String, ReportError> {
    let figures = plots(report)
        .iter()
        .map(|p| Ok((p.title.clone(), p.figure.svg(p.size_px)?)))
        .collect::<Result<Vec<_>, ReportError>>()?;
    Ok(html::page(report, &figures, false))
}
