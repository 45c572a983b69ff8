//! `kestrel explore`: N simulated drones explore a world together with the `explore` behavior
//! until no frontier is left, land, and the run is reported. The host runs on the control loop
//! `kestrel sim` serves (`host::runtime`), with plans in lock step: a seed flies the same run.
//!
//! In: a world file (its `starts_xy_yaw[N]` place the drones), the thesis's simulation
//! parameters as defaults (0.1 m map, four 4 m beams at 20 Hz, 1.0 m height, 0.75 m/s, turns at
//! 0.15 rad/s, 0.4 m from obstacles, 2.0 m between drones), a seed and an allocator, and
//! optionally what a real drone has (a drifting position estimate, range noise, dropped
//! readings; judged on the truth the log keeps beside the estimate).
//! Out: the flight log (poses at 20 Hz), a JSON report with the exploration's metrics (computed
//! by `exploration::offline::evaluate` from the log and the true world, as an outside evaluator would),
//! progress
//! lines while it runs, and the exit status: 0 when every drone explored and landed, non-zero
//! with the reason otherwise (a failed drone, a collision, or the simulated timeout).

use crate::cli::sim::{execute, load_config, parse_speedup};
use anyhow::{bail, Context, Result};
use clap::Args;
use kestrel::config::Config;
use kestrel::exploration::offline::evaluate::{self, EvalParams};
use kestrel::exploration::online::allocation::AllocatorKind;
use kestrel::flightlog::files;
use kestrel::flightlog::mcap_log::McapLog;
use kestrel::flightlog::{reader, FlightLog, LogFormat};
use kestrel::host::runtime::{self, Pace, RuntimeOptions};
use kestrel::host::Host;
use kestrel::mapping::grid::UNKNOWN;
use kestrel::scenario::sim_host::{sim_world, simulated_host_in};
use kestrel::sim::world::World;
use kestrel::types::SensorConfig;
use serde_json::{json, Value};
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct ExploreArgs {
    /// World file (JSON, the thesis layout: bounds, poles, starts per drone count).
    #[arg(long)]
    world: PathBuf,
    /// Number of drones (drone_0 ... drone_{N-1}), placed at the world's starts for N.
    #[arg(long, default_value_t = 1)]
    drones: usize,
    /// Simulated seconds per wall-clock second, or `max` for as fast as the CPU allows.
    #[arg(long, default_value = "max")]
    speedup: String,
    /// Seed for sensor noise; the same seed gives the same run.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Flight log at this path, which must not exist yet (see --log-overwrite).
    /// Default: a new kestrel-explore-<world>-<N>-<seed>-<UTC start time>.jsonl (.mcap with
    /// --log-format mcap).
    #[arg(long)]
    log: Option<PathBuf>,
    /// With --log: replace the file if it exists.
    #[arg(long, requires = "log")]
    log_overwrite: bool,
    /// Flight-log format: jsonl (JSON lines) or mcap (MCAP with Foxglove's channels: poses,
    /// frames, events, goals and paths, each drone's map and the merged map, frontiers, a
    /// world's obstacles and known area, and every record). Default: the config's `drone.log_format` (jsonl).
    #[arg(long, value_name = "FORMAT")]
    log_format: Option<LogFormat>,
    /// Report (JSON) with every metric. Default: the log's name with `.report.json`.
    #[arg(long)]
    report: Option<PathBuf>,
    /// Config file (TOML): controller, simulator, map and safety settings.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Frontier allocator: kestrel (default), thesis, nearest or farthest.
    #[arg(long, default_value = "kestrel")]
    allocator: String,
    /// Give up after this many simulated seconds (the thesis's timeout).
    #[arg(long, default_value_t = 6000.0)]
    max_sim_time_s: f64,
    /// Extra arguments of every drone's `explore` behavior (JSON object), e.g. '{"heading": "align"}'.
    #[arg(long)]
    explore_args: Option<String>,
    /// Speed at which each drone's position estimate drifts from the truth (m/s, 0 to 1):
    /// replaces the config's `[sim] position_drift_mps`.
    #[arg(long, value_name = "MPS")]
    position_drift_mps: Option<f64>,
    /// Fraction of range readings that return nothing (0 to 1): replaces the config's
    /// `[sim] range_dropout`.
    #[arg(long, value_name = "FRACTION")]
    range_dropout: Option<f64>,
    /// Standard deviation of the range noise (m): replaces the sensor's `noise_std_m` (1 cm).
    #[arg(long, value_name = "M")]
    range_noise_m: Option<f64>,
    /// Seconds of simulated time between progress lines.
    #[arg(long, default_value_t = 30.0)]
    progress_every_s: f64,
}

/// Known cells of the merged map, in percent of all cells.
fn known_pct(host: &Host) -> f64 {
    host.map().map_or(0.0, |m| {
        let data = m.merged().data();
        let known = data.iter().filter(|&&v| v != UNKNOWN).count();
        100.0 * known as f64 / data.len().max(1) as f64
    })
}

pub fn run(args: ExploreArgs) -> Result<()> {
    let pace = parse_speedup(&args.speedup)?;
    if args.drones == 0 || args.drones > 64 {
        bail!("--drones must be within 1..=64, got {}", args.drones);
    }
    if !(args.max_sim_time_s.is_finite() && args.max_sim_time_s > 0.0) {
        bail!("--max-sim-time-s must be > 0 s");
    }
    let allocator: AllocatorKind = args.allocator.parse().map_err(anyhow::Error::msg)?;
    let mut config = load_config(args.config.as_deref())?;
    let mut world = World::load(&args.world)?;
    fit_config(&mut config, &args, &world);
    imperfect(&mut config, &args, &mut world)?;
    let start = std::time::SystemTime::now();
    let (file, log_path) = open_log(&args, &config, start)?;
    let report_path = args
        .report
        .clone()
        .unwrap_or_else(|| log_path.with_extension("report.json"));
    let sim = sim_world(world.clone(), args.drones, args.seed, &config);
    let mut host = simulated_host_in(sim, &config);
    if host.map().is_none() {
        bail!("exploration needs mapping: the config's [map] plugin is \"none\"");
    }
    let out = std::io::BufWriter::new(file);
    // Written on this thread (a simulation: no control loop to keep free), closed (for MCAP:
    // its summary written) before the log is read back below.
    let out: Box<dyn std::io::Write + Send> = match log_format(&args, &config) {
        LogFormat::Jsonl => Box::new(out),
        LogFormat::Mcap => Box::new(McapLog::new(out).context("starting the MCAP flight log")?),
    };
    let mut log = FlightLog::new(out, 20.0);
    log.header(crate::cli::serve::header(&crate::cli::serve::RunInfo {
        command: "explore",
        config: &config,
        seed: Some(args.seed),
        world: Some(&args.world),
        scenario: None,
        mission: None,
        geo_origin: host.cores().first().map(|c| c.geo_origin().0),
        drones: host.drone_ids(),
        start,
    }));
    host.set_log(log);
    host.step();
    let flights = start_explorations(&mut host, &args, allocator)?;
    println!(
        "kestrel explore: {} drone(s) in {}, allocator {:?}, flight log {}",
        args.drones,
        args.world.display(),
        allocator,
        log_path.display()
    );
    let started = Instant::now();
    let (mut host, outcome) = fly(host, &flights, &args, pace, started)?;
    host.close_log();
    let wall_s = started.elapsed().as_secs_f64();
    let sim_s = host.now().as_secs_f64();
    let failures: Vec<String> = match &outcome {
        Ok(results) => results
            .iter()
            .zip(host.drone_ids())
            .filter_map(|(r, id)| match r {
                Some(Err(e)) => Some(format!("{id}: {e}")),
                _ => None,
            })
            .collect(),
        Err(e) => vec![e.clone()],
    };
    // The run judged as an outside evaluator would: from the flight log and the true world.
    let text = reader::read_to_string(&log_path, u64::MAX)
        .with_context(|| format!("reading back {}", log_path.display()))?;
    let samples = evaluate::poses_from_log(&text)?;
    let metrics = evaluate::evaluate(&world, &samples, &EvalParams::default())?;
    print!("{}", crate::cli::evaluate::summary(&metrics));
    let report = json!({
        "metrics": metrics,
        "world": args.world.display().to_string(),
        "drones": args.drones,
        "seed": args.seed,
        "allocator": allocator,
        "succeeded": failures.is_empty(),
        "failures": failures,
        "simulated_s": sim_s,
        "wall_s": wall_s,
        "map_known_pct": known_pct(&host),
        "flight_log": log_path.display().to_string(),
    });
    write_report(&report_path, &report)?;
    println!(
        "simulated {sim_s:.1} s in {wall_s:.2} s wall; known {:.2} %; report {}",
        known_pct(&host),
        report_path.display()
    );
    if failures.is_empty() {
        println!("exploration succeeded");
        Ok(())
    } else {
        bail!("exploration failed: {}", failures.join("; "))
    }
}

fn log_format(args: &ExploreArgs, config: &Config) -> LogFormat {
    args.log_format.unwrap_or(config.drone.log_format)
}

/// The config as an exploration of `world` needs it, where the file leaves it open.
fn fit_config(config: &mut Config, args: &ExploreArgs, world: &World) {
    // Drones give way to each other through the explore behavior's watcher (2.0 m, climbing
    // 1 m); the safety stage is the last line behind it, at the 0.5 m the exploration must
    // never go below (braking to stop 0.2 m outside it, well inside the watcher's trigger).
    if args.config.is_none() {
        config.safety.min_separation_m = 0.5;
    }
    // The area to explore is the world's: the map covers its bounds exactly (the thesis's
    // 500 x 500 cells for 50 x 50 m), unless the config sets a size.
    if config.map.size_m.is_none() {
        let b = &world.bounds_m;
        config.map.size_m = Some([b.x[1] - b.x[0], b.y[1] - b.y[0]]);
    }
}

/// The simulated drones' sensor (the config's `[sim] sensor`, else the world's) and the
/// imperfections the command line sets, checked as the config's own values are; the config
/// keeps them, so the log's header says what the run had.
fn imperfect(config: &mut Config, args: &ExploreArgs, world: &mut World) -> Result<()> {
    let mut sensor = config.sim.sensor.unwrap_or(world.sensor);
    if let Some(noise) = args.range_noise_m {
        match &mut sensor {
            SensorConfig::Multiranger { noise_std_m, .. }
            | SensorConfig::Lidar360 { noise_std_m, .. } => *noise_std_m = noise,
            SensorConfig::None => bail!("--range-noise-m: the drones carry no range sensor"),
        }
        config.sim.sensor = Some(sensor);
    }
    world.sensor = sensor;
    if let Some(drift) = args.position_drift_mps {
        config.sim.position_drift_mps = drift;
    }
    if let Some(dropout) = args.range_dropout {
        config.sim.range_dropout = dropout;
    }
    config.check("the command line")?;
    Ok(())
}

/// The flight log: `--log`, or a new file named by the world, the drones, the seed and the
/// start in the config's log directory (older ones pruned to its limit).
fn open_log(
    args: &ExploreArgs,
    config: &Config,
    start: std::time::SystemTime,
) -> Result<(std::fs::File, PathBuf)> {
    if let Some(path) = &args.log {
        let file = files::create_at(path, args.log_overwrite)
            .with_context(|| format!("creating flight log {}", path.display()))?;
        return Ok((file, path.clone()));
    }
    let stem = args
        .world
        .file_stem()
        .map_or("world".into(), |s| s.to_string_lossy().into_owned());
    let kind = format!("kestrel-explore-{stem}-{}-{}", args.drones, args.seed);
    let dir = config.drone.log_dir.clone().unwrap_or_default();
    let ext = log_format(args, config).extension();
    let (file, path) = files::create(&dir, &kind, ext, start)
        .with_context(|| format!("creating a flight log in {}", dir.display()))?;
    files::prune(&dir, &kind, config.drone.log_keep, &path).context("pruning old flight logs")?;
    Ok((file, path))
}

/// Gives every drone a one-item `explore` mission (with `--explore-args` and the allocator) and
/// starts it; returns (drone, mission id) for each.
fn start_explorations(
    host: &mut Host,
    args: &ExploreArgs,
    allocator: AllocatorKind,
) -> Result<Vec<(usize, u32)>> {
    let mut flights = Vec::new();
    let mut explore_args = match &args.explore_args {
        Some(text) => serde_json::from_str::<Value>(text).context("--explore-args is not JSON")?,
        None => json!({}),
    };
    let Some(fields) = explore_args.as_object_mut() else {
        bail!("--explore-args must be a JSON object");
    };
    fields.insert("allocator".into(), json!(allocator));
    for id in host.drone_ids() {
        let mission = json!({
            "target": id,
            "plan": [{"behavior": "explore", "args": explore_args}],
        });
        flights.push(execute(host, mission)?);
    }
    Ok(flights)
}

/// How each flight ended (`None`: not yet), in words.
type Outcomes = Vec<Option<std::result::Result<(), String>>>;

/// Runs the host on the control loop of `kestrel sim` (`host::runtime`, paced to `pace`, plans
/// in lock step so a seed flies the same at any pace) until every flight ended or the
/// simulated time is up, printing progress; gives the host back with each flight's outcome, or
/// the timeout in words.
fn fly(
    host: Host,
    flights: &[(usize, u32)],
    args: &ExploreArgs,
    pace: Pace,
    started: Instant,
) -> Result<(Host, std::result::Result<Outcomes, String>)> {
    let max_time = Duration::from_secs_f64(args.max_sim_time_s);
    let every_s = args.progress_every_s;
    let mut next_progress = every_s;
    let watched = flights.to_vec();
    let stop_when = move |host: &Host| {
        let t = host.now().as_secs_f64();
        if t >= next_progress {
            next_progress += every_s;
            println!(
                "t {t:7.1} s  known {:5.1} %  frontiers {:3}  ({:.1} s wall)",
                known_pct(host),
                host.exploration_view().frontiers.len(),
                started.elapsed().as_secs_f64()
            );
        }
        outcomes(host, &watched).iter().all(Option::is_some) || host.now() >= max_time
    };
    let mut options = RuntimeOptions::new(pace);
    options.stop_when = Some(Box::new(stop_when));
    options.lock_step = true;
    // The loop ends when its handle's commands close or `shutdown` drops: both are held until
    // it has stopped by itself.
    let (shutdown, shutdown_rx) = tokio::sync::watch::channel(false);
    let spawned =
        runtime::spawn(host, options, shutdown_rx).context("starting the control loop")?;
    let host = spawned
        .thread
        .join()
        .map_err(|_| anyhow::anyhow!("the control loop panicked"))?;
    drop((spawned.handle, shutdown));
    let results = outcomes(&host, flights);
    if results.iter().all(Option::is_some) {
        return Ok((host, Ok(results)));
    }
    let timeout = format!(
        "timeout: exploration not finished after {:.0} s",
        args.max_sim_time_s
    );
    Ok((host, Err(timeout)))
}

/// Each flight's outcome so far.
fn outcomes(host: &Host, flights: &[(usize, u32)]) -> Outcomes {
    flights
        .iter()
        .map(|&(i, id)| {
            let (ex, core) = (host.executors().get(i)?, host.cores().get(i)?);
            Some(ex.status(core).outcome(id)?.map_err(|e| e.to_string()))
        })
        .collect()
}

fn write_report(path: &std::path::Path, report: &Value) -> Result<()> {
    let text = serde_json::to_string_pretty(report).context("encoding the report")?;
    std::fs::write(path, text).with_context(|| format!("writing report {}", path.display()))
}
