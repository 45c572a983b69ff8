//! `kestrel sim`: the built-in simulator, paced to wall-clock time or as fast as possible.

use anyhow::{bail, Context, Result};
use clap::Args;
use kestrel::behavior::Registry;
use kestrel::config::Config;
use kestrel::core::CoreConfig;
use kestrel::flightlog::FlightLog;
use kestrel::sim::runner::{SimConfig, SimRunner};
use kestrel::sim::script::{demo_plans, Script, ScriptState};
use kestrel::sim::world::{SensorConfig, World};
use kestrel::sim::Environment;
use kestrel::types::Vec3;
use std::path::PathBuf;
use std::time::{Duration, Instant};

#[derive(Args, Debug)]
pub struct SimArgs {
    /// World file (JSON; the thesis layout or its extensions). Default: an open field.
    #[arg(long)]
    world: Option<PathBuf>,
    /// Number of drones (drone_0 ... drone_{N-1}); start poses from the world file when it has them.
    #[arg(long, default_value_t = 1)]
    drones: usize,
    /// Simulated seconds per wall-clock second, or `max` for as fast as the CPU allows.
    #[arg(long, default_value = "1")]
    speedup: String,
    /// Seed for noise and sensors; the same seed gives the same flight.
    #[arg(long, default_value_t = 0)]
    seed: u64,
    /// Flight log (JSON lines). Default: kestrel-sim-<seed>.jsonl in the current directory.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Exit when the flight is over: 0 if it succeeded, non-zero with the reason if not.
    #[arg(long)]
    exit_when_done: bool,
    /// Config file (TOML) for controller, behaviors and simulator settings.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Range sensor of every drone: `multiranger`, `lidar` or `none` (overrides the world file).
    #[arg(long)]
    sensor: Option<String>,
    /// Give up after this many simulated seconds.
    #[arg(long, default_value_t = 600.0)]
    max_sim_time_s: f64,
}

enum Pace {
    Max,
    Factor(f64),
}

fn parse_speedup(s: &str) -> Result<Pace> {
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

pub fn run(args: SimArgs) -> Result<()> {
    let pace = parse_speedup(&args.speedup)?;
    if args.drones == 0 {
        bail!("--drones must be at least 1");
    }
    let config = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
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
    let sim_config = SimConfig {
        drones: args.drones,
        seed: args.seed,
        rate_hz: config.drone.control_rate_hz,
        environment: Environment {
            wind_mps: Vec3::from(config.sim.wind_enu_mps),
            turbulence_mps2: config.sim.turbulence_mps2,
        },
        ..SimConfig::default()
    };
    let core_config = |i: usize| {
        let mut c = CoreConfig::new(&format!("drone_{i}"));
        c.controller = config.controller;
        c.behaviors = config.behaviors;
        c.estimator = config.estimator.plugin.unwrap_or_default();
        c
    };
    let mut runner = SimRunner::new(
        world,
        &sim_config,
        core_config,
        &Registry::with_motion_behaviors(),
    );
    let log_path = args
        .log
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("kestrel-sim-{}.jsonl", args.seed)));
    runner.log = Some(
        FlightLog::create(&log_path)
            .with_context(|| format!("creating flight log {}", log_path.display()))?,
    );
    println!(
        "kestrel sim: {} drone(s), flight log {}",
        args.drones,
        log_path.display()
    );

    let mut scripts: Vec<Script> = demo_plans(&runner.world)
        .into_iter()
        .map(Script::new)
        .collect();
    let wall_start = Instant::now();
    let limit = Duration::from_secs_f64(args.max_sim_time_s);
    loop {
        let events = runner.step();
        for (i, (script, events)) in scripts.iter_mut().zip(&events).enumerate() {
            for e in events {
                println!(
                    "[{:8.2} s] drone_{i}: {}",
                    runner.now().as_secs_f64(),
                    serde_json::to_string(e).unwrap_or_default()
                );
            }
            if let Some(core) = runner.cores.get_mut(i) {
                script.update(core, events);
            }
        }
        if scripts.iter().all(Script::finished) || runner.now() > limit {
            break;
        }
        if let Pace::Factor(f) = pace {
            let target = runner.now().div_f64(f);
            if let Some(wait) = target.checked_sub(wall_start.elapsed()) {
                std::thread::sleep(wait);
            }
        }
    }
    if let Some(log) = runner.log.as_mut() {
        log.flush();
    }
    let wall = wall_start.elapsed().as_secs_f64();
    let sim_s = runner.now().as_secs_f64();
    println!(
        "simulated {sim_s:.1} s in {wall:.2} s wall-clock ({:.0}x real time)",
        sim_s / wall.max(1e-9)
    );
    let failures: Vec<String> = scripts
        .iter()
        .enumerate()
        .filter_map(|(i, s)| match &s.state {
            ScriptState::Succeeded => None,
            ScriptState::Failed(r) => Some(format!("drone_{i}: {r}")),
            ScriptState::Running { index } => Some(format!(
                "drone_{i}: still running item {index} after {sim_s:.0} s"
            )),
        })
        .collect();
    if failures.is_empty() {
        println!("flight succeeded");
        Ok(())
    } else if args.exit_when_done {
        bail!("flight failed: {}", failures.join("; "))
    } else {
        println!("flight failed: {}", failures.join("; "));
        Ok(())
    }
}
