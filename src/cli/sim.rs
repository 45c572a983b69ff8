//! `kestrel sim`: the built-in simulator on the host, serving the API. By default every drone
//! flies the demo mission; `--mission FILE` flies that mission, `--scenario FILE` registers
//! its frames and flies its mission, `--no-demo` waits for the API.

use crate::cli::flights::Flights;
use crate::cli::serve::{self, LogChoice, ServeOptions};
use anyhow::{bail, Context, Result};
use clap::Args;
use kestrel::config::Config;
use kestrel::flightlog::{FlightLog, LogFormat};
use kestrel::host::runtime::Pace;
use kestrel::host::{Host, HostError, LoadOptions};
use kestrel::scenario::coverage::fleet_missions;
use kestrel::scenario::demo::demo_missions;
use kestrel::scenario::file::Scenario;
use kestrel::scenario::sim_host::{sim_world, simulated_host_in};
use kestrel::sim::world::World;
use kestrel::types::SensorConfig;
use kestrel::types::Vec3;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;

#[derive(Args, Debug)]
pub struct SimArgs {
    /// World file (JSON; the thesis layout or its extensions). Default: an open field.
    #[arg(long)]
    pub(crate) world: Option<PathBuf>,
    /// Number of drones (drone_0 ... drone_{N-1}); start poses from the world file when it has them.
    #[arg(long, default_value_t = 1)]
    pub(crate) drones: usize,
    /// Simulated seconds per wall-clock second, or `max` for as fast as the CPU allows.
    #[arg(long, default_value = "1")]
    pub(crate) speedup: String,
    /// Seed for noise and sensors; the same seed gives the same flight.
    #[arg(long, default_value_t = 0)]
    pub(crate) seed: u64,
    /// Flight log at this path, which must not exist yet (see --log-overwrite).
    /// Default: a new kestrel-sim-<UTC start time>.jsonl (.mcap with --log-format mcap) in the
    /// config's `drone.log_dir` or the current directory.
    #[arg(long)]
    pub(crate) log: Option<PathBuf>,
    /// With --log: replace the file if it exists.
    #[arg(long, requires = "log")]
    pub(crate) log_overwrite: bool,
    /// Flight-log format: jsonl (JSON lines) or mcap (MCAP with Foxglove's channels: poses,
    /// frames, events, goals and paths, each drone's map and the merged map, frontiers, a
    /// world's obstacles and known area, and every record). Default: the config's `drone.log_format` (jsonl).
    #[arg(long, value_name = "FORMAT")]
    pub(crate) log_format: Option<LogFormat>,
    /// Exit when the flight is over: 0 if it succeeded, non-zero with the reason if not.
    #[arg(long)]
    pub(crate) exit_when_done: bool,
    /// Config file (TOML) for controller, behaviors, simulator, API and geofence settings.
    #[arg(long)]
    pub(crate) config: Option<PathBuf>,
    /// Range sensor of every drone: `multiranger`, `lidar` or `none` (overrides the world file).
    #[arg(long)]
    pub(crate) sensor: Option<String>,
    /// With --exit-when-done: give up after this many simulated seconds.
    #[arg(long, default_value_t = 600.0)]
    pub(crate) max_sim_time_s: f64,
    /// Serve the API on ADDR:PORT (default: the config's [api] listen, 127.0.0.1:8080).
    #[arg(long)]
    pub(crate) listen: Option<String>,
    /// Fly this mission (JSON, Aerostack2's format) instead of the demo.
    #[arg(long)]
    pub(crate) mission: Option<PathBuf>,
    /// Scenario (JSON): frames to register and the mission to fly.
    #[arg(long)]
    pub(crate) scenario: Option<PathBuf>,
    /// Start with every drone landed and idle, waiting for the API.
    #[arg(long)]
    pub(crate) no_demo: bool,
    /// Keep loaded missions and frames in this directory across restarts.
    #[arg(long)]
    pub(crate) state_dir: Option<PathBuf>,
}

pub fn parse_speedup(s: &str) -> Result<Pace> {
    if s == "max" {
        return Ok(Pace::Max);
    }
    let f: f64 = s
        .parse()
        .with_context(|| format!("--speedup takes a positive number or `max`, got `{s}`"))?;
    if !(f.is_finite() && f > 0.0) {
        bail!("--speedup must be > 0, got {f}");
    }
    Ok(Pace::Factor(f))
}

fn read_json(path: &Path) -> Result<Value> {
    let text =
        std::fs::read_to_string(path).with_context(|| format!("cannot read {}", path.display()))?;
    serde_json::from_str(&text).with_context(|| format!("{} is not valid JSON", path.display()))
}

/// Loads and starts `mission` on the drone it names; returns (drone index, mission id).
pub fn execute(host: &mut Host, mission: Value) -> Result<(usize, u32)> {
    let up = host
        .load_mission(&mission, LoadOptions::start())
        .map_err(|e| match e {
            HostError::Invalid(errors) => {
                let lines: Vec<String> = errors.iter().map(|e| format!("  {e}")).collect();
                anyhow::anyhow!("the mission is invalid:\n{}", lines.join("\n"))
            }
            other => anyhow::anyhow!("{other}"),
        })?;
    let index = host
        .drone_ids()
        .iter()
        .position(|d| *d == up.drone)
        .with_context(|| format!("{} is not one of the drones", up.drone))?;
    Ok((index, up.mission_id))
}

/// Builds the simulated host (config, world, sensors, scenario frames, saved state) and the
/// demo plan of each drone, placed clear of obstacles and of each other.
pub fn build(
    args: &SimArgs,
    config: &Config,
    scenario: Option<&Scenario>,
) -> Result<(Host, Vec<Value>)> {
    let mut world = match &args.world {
        Some(p) => World::load(p)?,
        None => World::empty(),
    };
    if let Some(sensor) = config.sim.sensor {
        world.sensor = sensor;
    }
    if let Some(name) = &args.sensor {
        world.sensor = SensorConfig::by_name(name)
            .with_context(|| format!("--sensor takes multiranger, lidar or none, got `{name}`"))?;
    }
    let drones = args
        .drones
        .max(scenario.and_then(|s| s.drones).unwrap_or(1));
    let sim = sim_world(world, drones, args.seed, config);
    let demos = demo_missions(&sim);
    let mut host = simulated_host_in(sim, config);
    // One tick, so every drone has a position before missions are validated and started.
    host.step();
    if let Some(dir) = &args.state_dir {
        crate::cli::serve::open_state(&mut host, dir)?;
    }
    for frame in scenario.map(|s| s.frames.clone()).unwrap_or_default() {
        let id = frame.frame_id.clone();
        host.set_frame(frame)
            .with_context(|| format!("registering frame {id}"))?;
    }
    Ok((host, demos))
}

pub fn load_config(path: Option<&Path>) -> Result<Config> {
    Ok(match path {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    })
}

pub fn run(args: SimArgs) -> Result<()> {
    let pace = parse_speedup(&args.speedup)?;
    if args.drones == 0 {
        bail!("--drones must be at least 1");
    }
    let config = load_config(args.config.as_deref())?;
    let scenario = args.scenario.as_deref().map(Scenario::load).transpose()?;
    let (mut host, demos) = build(&args, &config, scenario.as_ref())?;
    let (listen, token) = serve::listen_and_token(args.listen.as_deref(), &config)?;
    let listener = serve::bind(listen, token.as_deref())?;
    let start = std::time::SystemTime::now();
    let (writer, log_file) = serve::open_log(&LogChoice {
        explicit: args.log.clone(),
        overwrite: args.log_overwrite,
        dir: config.drone.log_dir.clone().unwrap_or_default(),
        kind: "kestrel-sim".into(),
        keep: config.drone.log_keep,
        start,
        format: args.log_format.unwrap_or(config.drone.log_format),
    })?;
    let log_path = log_file.path.clone();
    let split = scenario
        .as_ref()
        .filter(|_| args.mission.is_none())
        .and_then(|s| s.split_coverage(host.drone_ids().len()));
    let mission_file = args.mission.clone().or_else(|| {
        scenario
            .as_ref()
            .filter(|_| split.is_none())
            .and_then(|s| s.mission.clone())
    });
    let mut log = FlightLog::new(Box::new(writer), 10.0);
    log.header(serve::header(&serve::RunInfo {
        command: "sim",
        config: &config,
        seed: Some(args.seed),
        world: args.world.as_deref(),
        scenario: args.scenario.as_deref(),
        mission: mission_file.as_deref(),
        geo_origin: host.cores().first().map(|c| c.geo_origin().0),
        drones: host.drone_ids(),
        start,
    }));
    host.set_log(log);
    let flights = if args.no_demo {
        Vec::new()
    } else if let Some(spec) = split {
        let drones: Vec<(String, Vec3)> = host
            .cores()
            .iter()
            .map(|c| (c.drone_id().to_string(), c.estimate().pose.position_m))
            .collect();
        let frames = host.cores().first().map(|c| c.frames().clone());
        let missions = fleet_missions(spec, &frames.unwrap_or_default(), &drones)
            .context("splitting the scenario's coverage among the drones")?;
        missions
            .into_iter()
            .map(|mission| execute(&mut host, mission))
            .collect::<Result<Vec<_>>>()?
    } else if let Some(file) = &mission_file {
        vec![execute(&mut host, read_json(file)?)
            .with_context(|| format!("flying {}", file.display()))?]
    } else {
        demos
            .into_iter()
            .map(|mission| execute(&mut host, mission))
            .collect::<Result<Vec<_>>>()?
    };
    println!(
        "kestrel sim: {} drone(s), flight log {}",
        host.drone_ids().len(),
        log_path.display()
    );
    let options = ServeOptions {
        listener: Some(listener),
        token,
        api: config.api.clone(),
        pace,
        log: Some(log_file),
        flights: Flights::new(flights, false),
        demo_within: None,
        exit_when_done: args.exit_when_done,
        max_time: args
            .exit_when_done
            .then(|| Duration::from_secs_f64(args.max_sim_time_s)),
        between_ticks: None,
        ros2: config.ros2.enabled.then(|| config.ros2.clone()),
        on_event: None,
        texts_pending: None,
    };
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting tokio")?;
    let outcome = runtime.block_on(serve::serve(host, options))?;
    println!(
        "simulated {:.1} s in {:.2} s wall-clock ({:.0}x real time)",
        outcome.simulated_s,
        outcome.wall_s,
        outcome.simulated_s / outcome.wall_s.max(1e-9)
    );
    serve::report(&outcome, args.exit_when_done)
}
