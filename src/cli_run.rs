//! `kestrel run`: fly a real autopilot (PX4 or ArduPilot over MAVLink) with the same core and
//! behaviors as the simulator, ticked in real time by a tokio interval.
//!
//! In: `--config FILE` (TOML), `--platform` and `--connection` overriding its `[mavlink]`
//! section (`--platform platforms/sim.toml` flies the built-in simulator in real time instead).
//! Out: by default the vehicle on the host, serving the HTTP/WebSocket API (`--listen`), with
//! systemd READY and watchdog pings from the control loop: this is what the service runs. With
//! `--mission-demo`, a self-contained flight of the simulator's demo plan once the autopilot is
//! ready (resuming or landing after a link loss as `[mavlink] on_link_regained` says), without
//! the API. Both write a JSON-lines flight log and one stdout line per behavior event.

use crate::cli_serve::ServeOptions;
use anyhow::{bail, Context, Result};
use clap::Args;
use kestrel::behavior::fleet::{FleetInput, FleetView};
use kestrel::behavior::{BehaviorEvent, BehaviorResult, Registry, RunState};
use kestrel::config::Config;
use kestrel::control::{AcceptedSetpoints, Setpoint};
use kestrel::core::{BehaviorCommand, CoreConfig, DroneCore};
use kestrel::estimator::geodetic::GeodeticOrigin;
use kestrel::estimator::EstimatorPlugin;
use kestrel::flightlog::FlightLog;
use kestrel::host::demo::demo_plan;
use kestrel::host::logwriter;
use kestrel::host::runtime::Pace;
use kestrel::host::vehicle::{state_dir, vehicle_host};
use kestrel::platform::mavlink::{LinkConfig, LinkPolicy, MavlinkPlatform, Profile};
use kestrel::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use kestrel::sim::world::World;
use kestrel::sim::{Environment, SimWorld};
use kestrel::types::Vec3;
use kestrel::types::{LinkHealth, PlatformStatus, VehicleState};
use serde::Deserialize;
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::time::Duration;
use tokio::time::{Instant, MissedTickBehavior};

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Config file (TOML); its `[mavlink]` section says where the autopilot is.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Autopilot profile (`platforms/px4.toml`, `platforms/ardupilot-copter.toml`, or a
    /// built-in name `px4` / `ardupilot-copter`). Overrides `mavlink.platform`.
    #[arg(long)]
    platform: Option<String>,
    /// MAVLink connection (`udpin:0.0.0.0:14540`, `tcpout:127.0.0.1:5760`,
    /// `serial:/dev/ttyACM0:921600` ...). Overrides `mavlink.connection`.
    #[arg(long)]
    connection: Option<String>,
    /// Fly the demo plan of `kestrel sim` (takeoff, go_to, follow_path, land) once ready.
    #[arg(long)]
    mission_demo: bool,
    /// Exit when the plan is over: 0 if it succeeded, non-zero with the reason if not.
    #[arg(long)]
    exit_when_done: bool,
    /// Flight log (JSON lines). Default: kestrel-run.jsonl in `drone.log_dir` or here.
    #[arg(long)]
    log: Option<PathBuf>,
    /// Give up (and land) after this many seconds.
    #[arg(long, default_value_t = 900.0)]
    max_time_s: f64,
    /// Serve the API on ADDR:PORT (default: the config's [api] listen, 127.0.0.1:8080).
    #[arg(long)]
    listen: Option<String>,
    /// Keep loaded missions and frames here across restarts (default: $STATE_DIRECTORY, the
    /// config's [mission] state_dir, or ./kestrel-state).
    #[arg(long)]
    state_dir: Option<PathBuf>,
    /// Fly this mission (JSON, Aerostack2's format) at start, then keep serving the API.
    #[arg(long)]
    mission: Option<PathBuf>,
    /// No API: connect, print link, mode and arming changes, and log (with `--mission-demo`,
    /// fly the demo). For bench checks of a link.
    #[arg(long)]
    no_api: bool,
}

pub fn run(args: RunArgs) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(run_async(args))
}

/// `platforms/sim.toml`: the built-in simulator, stepped in real time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimPlatformFile {
    platform: String,
    name: String,
    world: Option<PathBuf>,
    #[serde(default)]
    seed: u64,
}

/// A simulated vehicle behind the `Platform` trait, its physics advanced to each poll's time.
struct RealtimeSim {
    world: SimWorld,
    stepped_to: Duration,
}

/// Physics step of the real-time simulator.
const SIM_STEP: Duration = Duration::from_millis(5);

impl Platform for RealtimeSim {
    fn capabilities(&self) -> Capabilities {
        self.world.vehicles.first().map_or(
            Capabilities {
                setpoints: AcceptedSetpoints {
                    velocity: true,
                    position: true,
                },
                native_takeoff: false,
                native_land: false,
            },
            |v| v.capabilities(),
        )
    }

    fn poll(&mut self, now: Duration) -> PlatformFeedback {
        while self.stepped_to < now {
            let dt = SIM_STEP.min(now - self.stepped_to);
            self.world.step(self.stepped_to, dt.as_secs_f64());
            self.stepped_to += dt;
        }
        self.world
            .vehicles
            .first_mut()
            .map(|v| v.poll(now))
            .unwrap_or_default()
    }

    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]) {
        if let Some(v) = self.world.vehicles.first_mut() {
            v.command(now, setpoint, requests);
        }
    }
}

/// `mavlink` or `sim`: the `platform` key of a file in `platforms/`, or a built-in name.
fn platform_kind(name: &str) -> Result<String> {
    let path = Path::new(name);
    if !path.exists() {
        return match name {
            "px4" | "ardupilot-copter" => Ok("mavlink".into()),
            "sim" => Ok("sim".into()),
            _ => bail!("no platform file `{name}` (and no built-in profile of that name)"),
        };
    }
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {name}"))?;
    let value: toml::Value = toml::from_str(&text).with_context(|| format!("parsing {name}"))?;
    match value.get("platform").and_then(|v| v.as_str()) {
        Some(k @ ("mavlink" | "sim")) => Ok(k.to_string()),
        other => bail!("{name}: `platform` must be \"mavlink\" or \"sim\", got {other:?}"),
    }
}

fn load_profile(name: &str) -> Result<Profile> {
    let path = Path::new(name);
    if !path.exists() {
        if let Some(p) = Profile::builtin(name) {
            return Ok(p?);
        }
    }
    Ok(Profile::load(path)?)
}

/// Starts the platform named in config: (platform, readiness timeout, estimator by default).
fn start_platform(config: &Config) -> Result<(Box<dyn Platform>, Duration, EstimatorPlugin)> {
    let m = &config.mavlink;
    if platform_kind(&m.platform)? == "sim" {
        let file: SimPlatformFile = if Path::new(&m.platform).exists() {
            toml::from_str(&std::fs::read_to_string(&m.platform)?)
                .with_context(|| format!("parsing {}", m.platform))?
        } else {
            SimPlatformFile {
                platform: "sim".into(),
                name: "Built-in simulator".into(),
                world: None,
                seed: 0,
            }
        };
        if file.platform != "sim" {
            bail!("{}: not a simulator platform file", m.platform);
        }
        let world = match &file.world {
            Some(p) => World::load(p)?,
            None => World::empty(),
        };
        let environment = Environment {
            wind_mps: Vec3::from(config.sim.wind_enu_mps),
            turbulence_mps2: config.sim.turbulence_mps2,
        };
        println!("kestrel run: {} (profile {})", file.name, m.platform);
        let sim = RealtimeSim {
            world: SimWorld::new(world, 1, file.seed, environment),
            stepped_to: Duration::ZERO,
        };
        return Ok((
            Box::new(sim),
            SIM_READY_TIMEOUT,
            EstimatorPlugin::GroundTruth,
        ));
    }
    let profile = load_profile(&m.platform)?;
    let ready_timeout = profile.ready_timeout;
    println!(
        "kestrel run: {} over {} (profile {})",
        profile.name, m.connection, m.platform
    );
    let link = LinkConfig {
        connection: m.connection.clone(),
        forward: m.forward.clone(),
    };
    let platform = MavlinkPlatform::start(profile, m.session_config(), link)?;
    Ok((
        Box::new(platform),
        ready_timeout,
        EstimatorPlugin::AutopilotOdometry,
    ))
}

/// The simulator is ready at once; this only bounds a broken setup.
const SIM_READY_TIMEOUT: Duration = Duration::from_secs(5);

async fn run_async(args: RunArgs) -> Result<()> {
    let mut config = match &args.config {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    if let Some(p) = &args.platform {
        config.mavlink.platform = p.clone();
    }
    if let Some(c) = &args.connection {
        config.mavlink.connection = c.clone();
    }
    config
        .mavlink
        .validate()
        .map_err(|(field, message)| anyhow::anyhow!("{field}: {message}"))?;
    let (mut platform, ready_timeout, estimator) = start_platform(&config)?;
    let mut core_config = CoreConfig::new(&config.drone.id);
    core_config.estimator = config.estimator.plugin.unwrap_or(estimator);
    core_config.controller = config.controller;
    core_config.behaviors = config.behaviors;
    core_config.map = config.map.config(None).context("[map]")?;
    if let Some(o) = config.drone.geodetic_origin {
        core_config.geo_origin = GeodeticOrigin(o);
    }
    if !args.mission_demo && !args.no_api {
        let core = DroneCore::new(
            core_config,
            platform.capabilities(),
            kestrel::host::payload::registry(),
        );
        return serve_vehicle(&args, &config, core, platform).await;
    }
    let mut core = DroneCore::new(
        core_config,
        platform.capabilities(),
        Registry::with_motion_behaviors(),
    );
    let log_path = args.log.clone().unwrap_or_else(|| {
        config
            .drone
            .log_dir
            .clone()
            .unwrap_or_default()
            .join("kestrel-run.jsonl")
    });
    let mut log = FlightLog::create(&log_path)
        .with_context(|| format!("creating flight log {}", log_path.display()))?;
    println!("flight log {}", log_path.display());

    let period = Duration::from_secs_f64(1.0 / config.drone.control_rate_hz);
    let mut interval = tokio::time::interval(period);
    interval.set_missed_tick_behavior(MissedTickBehavior::Skip);
    let start = Instant::now();
    let limit = Duration::from_secs_f64(args.max_time_s.max(1.0));
    let mut plan = args.mission_demo.then(|| Plan::new(ready_timeout));
    let mut watch = StatusWatch::default();
    let policy = config.mavlink.on_link_regained;
    let ctrl_c = tokio::signal::ctrl_c();
    tokio::pin!(ctrl_c);
    let alone = std::sync::Arc::new(FleetView::default());
    let outcome = loop {
        tokio::select! {
            _ = interval.tick() => {}
            _ = &mut ctrl_c => break Err("interrupted".to_string()),
        }
        let now = start.elapsed();
        let feedback = platform.poll(now);
        let out = core.tick(
            now,
            &feedback,
            FleetInput {
                view: &alone,
                map: None,
            },
        );
        platform.command(now, out.setpoint, &out.requests);
        let state = core.vehicle_state();
        for line in watch.changes(&state.platform) {
            say(now, &line);
            log.event(now, core.drone_id(), "platform", &line);
        }
        for r in &feedback.request_results {
            if let Err(e) = &r.outcome {
                say(now, &format!("{:?} refused: {e}", r.request));
            }
        }
        let active = active_motion(&core);
        log.pose(now, &state, active.as_deref());
        for e in &out.events {
            say(now, &serde_json::to_string(e).unwrap_or_default());
            log.behavior(now, core.drone_id(), e);
        }
        if let Some(p) = plan.as_mut() {
            if let Some(result) = p.update(now, &mut core, &state, &out.events, policy) {
                if args.exit_when_done {
                    break result;
                }
                say(now, &format!("plan over: {result:?}"));
                plan = None;
            }
        }
        if now > limit {
            break Err(format!("no end after {:.0} s", limit.as_secs_f64()));
        }
    };
    log.flush();
    drop(platform);
    match outcome {
        Ok(()) => {
            println!("flight succeeded");
            Ok(())
        }
        Err(e) => bail!("flight failed: {e}"),
    }
}

/// The service path: the vehicle on the host, the API served until interrupted.
async fn serve_vehicle(
    args: &RunArgs,
    config: &Config,
    core: DroneCore,
    platform: Box<dyn Platform>,
) -> Result<()> {
    let mut host = vehicle_host(vec![(core, platform)], config);
    let log_path = args.log.clone().unwrap_or_else(|| {
        config
            .drone
            .log_dir
            .clone()
            .unwrap_or_default()
            .join("kestrel-run.jsonl")
    });
    let (writer, log_file) = logwriter::open(&log_path)
        .with_context(|| format!("creating flight log {}", log_path.display()))?;
    host.set_log(FlightLog::new(Box::new(writer), 10.0));
    let state_file = state_dir(args.state_dir.clone(), config).join("state.json");
    if let Some(state) = kestrel::mission::store::load(&state_file)? {
        host.restore(state, Duration::from_secs_f64(config.mission.switch_hold_s));
        println!(
            "restored missions from {} (not resumed)",
            state_file.display()
        );
    }
    let flights = match &args.mission {
        Some(file) => {
            let text = std::fs::read_to_string(file)
                .with_context(|| format!("cannot read {}", file.display()))?;
            let mission = serde_json::from_str(&text)
                .with_context(|| format!("{} is not valid JSON", file.display()))?;
            vec![crate::cli_sim::execute(&mut host, mission)
                .with_context(|| format!("flying {}", file.display()))?]
        }
        None => Vec::new(),
    };
    println!("flight log {}", log_path.display());
    let (listen, token) = crate::cli_serve::listen_and_token(args.listen.as_deref(), config)?;
    let options = ServeOptions {
        listen,
        listen_is_default: false,
        token,
        api: config.api.clone(),
        pace: Pace::RealTime,
        state_file: Some(state_file),
        log: Some(log_file),
        flights,
        exit_when_done: args.exit_when_done,
        max_time: Duration::from_secs_f64(args.max_time_s.max(1.0)),
    };
    let outcome = crate::cli_serve::serve(host, options).await?;
    crate::cli_serve::report(&outcome, args.exit_when_done)
}

fn say(now: Duration, line: &str) {
    println!("[{:8.2} s] {line}", now.as_secs_f64());
}

fn active_motion(core: &DroneCore) -> Option<String> {
    core.server()
        .active()
        .iter()
        .find(|a| a.state == RunState::Running || a.state == RunState::Paused)
        .map(|a| a.behavior.clone())
}

/// Reports link, mode, arming and error changes once each.
#[derive(Default)]
struct StatusWatch {
    last: Option<PlatformStatus>,
}

impl StatusWatch {
    fn changes(&mut self, s: &PlatformStatus) -> Vec<String> {
        let mut out = Vec::new();
        let prev = self.last.clone().unwrap_or_default();
        let first = self.last.is_none();
        if first || prev.link != s.link {
            out.push(format!("link: {:?}", s.link).to_lowercase());
        }
        if prev.mode != s.mode {
            out.push(format!("mode: {}", s.mode));
        }
        if prev.armed != s.armed {
            out.push(if s.armed { "armed" } else { "disarmed" }.to_string());
        }
        if prev.ready_to_fly != s.ready_to_fly {
            out.push(format!("ready to fly: {}", s.ready_to_fly));
        }
        if prev.boot_counter != s.boot_counter {
            out.push(format!("autopilot reboot #{}", s.boot_counter));
        }
        self.last = Some(s.clone());
        out
    }
}

/// The demo plan, placed at the vehicle's pose once the autopilot is ready and flown in order;
/// the interrupted item restarts after a link loss when the policy is `resume`, and a failure
/// ends with a landing.
struct Plan {
    items: Vec<(String, Value)>,
    ready_timeout: Duration,
    phase: Phase,
    started_at: Option<Duration>,
}

#[derive(Debug, Clone, PartialEq)]
enum Phase {
    WaitReady,
    Running(usize),
    /// The link dropped during item `usize`; resume it when the link is back.
    WaitLink(usize, Duration),
    /// Failed: landing (if airborne) before reporting the reason.
    Landing(String, Duration, bool),
}

/// How long the plan waits for a lost link before giving up, and for a landing to finish.
const LINK_WAIT: Duration = Duration::from_secs(30);
const LANDING_WAIT: Duration = Duration::from_secs(120);

impl Plan {
    fn new(ready_timeout: Duration) -> Self {
        Self {
            items: Vec::new(),
            ready_timeout,
            phase: Phase::WaitReady,
            started_at: None,
        }
    }

    fn start(&mut self, now: Duration, core: &mut DroneCore, index: usize) -> Option<String> {
        let Some((behavior, goal)) = self.items.get(index).cloned() else {
            return Some(format!("no plan item {index}"));
        };
        self.phase = Phase::Running(index);
        let cmd = BehaviorCommand::Start {
            behavior: behavior.clone(),
            goal,
        };
        match core.command(cmd) {
            Ok(_) => None,
            Err(e) => {
                say(now, &format!("{behavior} refused: {e}"));
                Some(format!("{behavior}: {e}"))
            }
        }
    }

    fn fail(&mut self, now: Duration, reason: String) {
        say(now, &format!("plan failed: {reason}"));
        self.phase = Phase::Landing(reason, now, false);
    }

    /// Advances; `Some` when the plan is over.
    fn update(
        &mut self,
        now: Duration,
        core: &mut DroneCore,
        state: &VehicleState,
        events: &[BehaviorEvent],
        policy: LinkPolicy,
    ) -> Option<Result<(), String>> {
        let link_ok = state.platform.link == LinkHealth::Ok;
        match self.phase.clone() {
            Phase::WaitReady => {
                let since = *self.started_at.get_or_insert(now);
                if link_ok && state.platform.ready_to_fly && state.estimate.valid.position {
                    let pose = &state.estimate.pose;
                    self.items = demo_plan(pose.position_m, pose.yaw_rad());
                    if let Some(e) = self.start(now, core, 0) {
                        self.fail(now, e);
                    }
                } else if now.saturating_sub(since) > self.ready_timeout + LINK_WAIT {
                    let why = state
                        .platform
                        .last_error
                        .clone()
                        .unwrap_or_else(|| format!("link {:?}", state.platform.link));
                    return Some(Err(format!("the autopilot never became ready: {why}")));
                }
            }
            Phase::Running(index) => {
                for e in events {
                    let BehaviorEvent::Finished {
                        behavior, result, ..
                    } = e
                    else {
                        continue;
                    };
                    match result {
                        BehaviorResult::Succeeded if index + 1 >= self.items.len() => {
                            return Some(Ok(()));
                        }
                        BehaviorResult::Succeeded => {
                            if let Some(e) = self.start(now, core, index + 1) {
                                self.fail(now, e);
                            }
                        }
                        BehaviorResult::Failed { reason: r, .. }
                        | BehaviorResult::Aborted { reason: r, .. } => {
                            if !link_ok && policy == LinkPolicy::Resume {
                                say(
                                    now,
                                    &format!("{behavior} interrupted ({r}): waiting for the link"),
                                );
                                self.phase = Phase::WaitLink(index, now);
                            } else {
                                self.fail(now, format!("{behavior}: {r}"));
                            }
                        }
                    }
                    break;
                }
            }
            Phase::WaitLink(index, since) => {
                if link_ok && state.estimate.valid.position {
                    if !state.platform.armed {
                        self.fail(now, "the vehicle landed during the link loss".into());
                    } else {
                        say(now, "link back: resuming the plan");
                        if let Some(e) = self.start(now, core, index) {
                            self.fail(now, e);
                        }
                    }
                } else if now.saturating_sub(since) > LINK_WAIT {
                    return Some(Err("the link did not come back".into()));
                }
            }
            Phase::Landing(reason, since, requested) => {
                if !state.platform.armed || now.saturating_sub(since) > LANDING_WAIT {
                    return Some(Err(reason));
                }
                if link_ok && !requested && core.server().active().is_empty() {
                    let land = BehaviorCommand::Start {
                        behavior: "land".into(),
                        goal: serde_json::json!({}),
                    };
                    let started = core.command(land).is_ok();
                    self.phase = Phase::Landing(reason, since, started);
                }
            }
        }
        None
    }
}
