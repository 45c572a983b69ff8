//! `kestrel evaluate`: exploration metrics of a flight log against the true world.
//!
//! In: a world file and a JSON-lines flight log, or one log per node of a fleet (`--log` again
//! for each; put on one clock by their `clock` records). Out: a short summary on stdout and,
//! with `--out`, the full metrics as JSON (`exploration::offline::evaluate::ExplorationMetrics`).

use anyhow::{Context, Result};
use clap::Args;
use kestrel::exploration::offline::evaluate::limits::FlightLimits;
use kestrel::exploration::offline::evaluate::{self, EvalParams, ExplorationMetrics, MergeError};
use kestrel::flightlog::reader;
use kestrel::sim::world::World;
use std::path::PathBuf;

/// Largest flight log read (bytes): a 7-drone hour at 20 Hz is well under this.
const MAX_LOG_BYTES: u64 = 2 << 30;

#[derive(Args, Debug)]
pub struct EvaluateArgs {
    /// World file the flight was flown in (JSON).
    #[arg(long)]
    world: PathBuf,
    /// Flight log (JSON lines or MCAP, `pose` records). Several (`--log A --log B`): the logs of one
    /// fleet's nodes, evaluated as one flight.
    #[arg(long, required = true)]
    log: Vec<PathBuf>,
    /// Where to write the metrics (JSON).
    #[arg(long)]
    out: Option<PathBuf>,
    /// Beam range of the evaluation sensor (m).
    #[arg(long, default_value_t = 4.0)]
    range_m: f64,
    /// Time between two points of the area-over-time curve (s, 0.1 to 3600).
    #[arg(long, default_value_t = 10.0)]
    curve_step_s: f64,
    /// Horizontal speed limit the run is judged against (m/s; flown within it + 3 %).
    #[arg(long, default_value_t = FlightLimits::default().speed_mps)]
    speed_limit_mps: f64,
    /// Yaw-rate limit (rad/s; flown within it + 3 %).
    #[arg(long, default_value_t = FlightLimits::default().yaw_rate_radps)]
    yaw_rate_limit_radps: f64,
    /// Judge the least clearance from a drone's centre to an obstacle against this (m; by
    /// default it is reported, and only a contact fails the run).
    #[arg(long)]
    clearance_limit_m: Option<f64>,
    /// Judge the least 3-D distance between two airborne drones against this (m; by default
    /// reported, and only a contact fails the run).
    #[arg(long)]
    separation_limit_m: Option<f64>,
}

pub fn run(args: EvaluateArgs) -> Result<()> {
    let world = World::load(&args.world)?;
    let mut texts = Vec::new();
    for path in &args.log {
        let size = std::fs::metadata(path)
            .with_context(|| format!("reading {}", path.display()))?
            .len();
        anyhow::ensure!(
            size <= MAX_LOG_BYTES,
            "{} is {size} bytes, more than the {MAX_LOG_BYTES} read",
            path.display()
        );
        texts.push(
            reader::read_to_string(path, MAX_LOG_BYTES)
                .with_context(|| format!("reading {}", path.display()))?,
        );
    }
    let names: Vec<String> = args.log.iter().map(|p| p.display().to_string()).collect();
    let refs: Vec<&str> = texts.iter().map(String::as_str).collect();
    let samples = evaluate::poses_from_logs(&refs).map_err(|e| match e {
        MergeError::Log { log, source } => anyhow::anyhow!("parsing {}: {source}", names[log]),
        MergeError::NoStart { log } => anyhow::anyhow!(
            "{} has no clock record (only real-time runs write one): it cannot be put on the \
             other logs' clock",
            names[log]
        ),
        MergeError::DroneTwice {
            drone,
            first,
            second,
        } => anyhow::anyhow!(
            "drone {drone} is in both {} and {}: give each drone's log once",
            names[first],
            names[second]
        ),
    })?;
    let params = EvalParams {
        beam_range_m: args.range_m,
        curve_step_s: args.curve_step_s,
        limits: FlightLimits {
            speed_mps: args.speed_limit_mps,
            yaw_rate_radps: args.yaw_rate_limit_radps,
            clearance_m: args.clearance_limit_m,
            separation_m: args.separation_limit_m,
            ..FlightLimits::default()
        },
        ..EvalParams::default()
    };
    let metrics = evaluate::evaluate(&world, &samples, &params)
        .with_context(|| format!("evaluating {}", names.join(", ")))?;
    print!("{}", summary(&metrics));
    if let Some(out) = &args.out {
        let json = serde_json::to_string_pretty(&metrics).context("writing the metrics")?;
        std::fs::write(out, json + "\n").with_context(|| format!("writing {}", out.display()))?;
    }
    Ok(())
}

pub fn summary(m: &ExplorationMetrics) -> String {
    let opt = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.2}"));
    let opt3 = |v: Option<f64>| v.map_or("-".to_string(), |v| format!("{v:.3}"));
    let f = &m.flown;
    let times: Vec<String> = m
        .time_to_pct
        .iter()
        .map(|t| format!("{:.0}%: {:.1} s", t.pct_of_final, t.time_s))
        .collect();
    format!(
        "drones {}, time {:.1} s (take-off {:.1} s, landing {:.1} s), lower bound {:.1} s (x{})\n\
         area {:.2} % (closed {:.2} %), observable {:.2} % of {:.2} % of the grid\n\
         path {:.1} m (L1 {:.1} m), overlap {:.2} %, observed by 2+ {:.2} %\n\
         min clearance {} m, min separation {} m, collisions {}\n\
         time to final area: {}\n\
         flown: speed max {} m/s (p99 {}), yaw rate max {} rad/s (p99 {}), height {} m (max {})\n\
         limits: {}\n",
        m.drones_flown,
        m.time_s,
        m.first_takeoff_s,
        m.last_landing_s,
        m.lower_bound_s,
        opt(m.time_over_bound),
        m.area_pct,
        m.area_closed_pct,
        m.observable_pct,
        m.observable_share_pct,
        m.path_m,
        m.path_l1_m,
        m.overlap_pct,
        m.multi_observed_pct,
        opt(m.min_obstacle_clearance_m),
        opt(m.min_separation_m),
        m.collisions,
        times.join(", "),
        opt3(f.max_speed_mps),
        opt3(f.p99_speed_mps),
        opt3(f.max_yaw_rate_radps),
        opt3(f.p99_yaw_rate_radps),
        opt(f.cruise_height_m),
        opt(f.max_height_m),
        if f.held {
            "held".to_string()
        } else {
            format!("BROKEN: {}", f.breaches.join("; "))
        }
    )
}
