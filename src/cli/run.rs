//! `kestrel run`: fly a real autopilot (PX4 or ArduPilot over MAVLink) with the same core and
//! behaviors as the simulator, ticked in real time by a tokio interval.
//!
//! In: `--config FILE` (TOML), `--platform` and `--connection` overriding its `[mavlink]`
//! section (`--platform platforms/sim.toml` flies the built-in simulator in real time instead,
//! with the config's `[sim]` drift and dropped readings; its log holds the estimate only).
//! A `[[vehicle]]` list in the config flies several autopilots, each over its own connection
//! with its own core and mission executor, its local frame shifted into the shared one.
//! Out: the vehicles on the host, serving the HTTP/WebSocket API (`--listen`; `--no-api`: none),
//! with systemd READY and watchdog pings from the control loop: this is what the service runs.
//! `--mission FILE` flies a mission at start; `--mission-demo` flies the simulator's demo plan as
//! a mission once the autopilot is ready. `--virtual-world FILE` casts each vehicle's range
//! sensor against a world file's obstacles from its reported pose (`sim::virtual_world`, in the
//! shared frame), in place of the autopilot's own range readings. Missions follow `[mission]
//! on_link_regained` after a link loss, as on every platform. It writes a JSON-lines flight
//! log, one line per behavior event and one per change of link, mode, arming and readiness, and
//! tells each autopilot's ground station the behavior and mission events as STATUSTEXT
//! (`cli::announce`).

use crate::cli::flights::Flights;
use crate::cli::serve::ServeOptions;
use crate::cli::startup::{prepare, Overrides, PlatformPlan, Startup, VehiclePlan};
use anyhow::{Context, Result};
use clap::Args;
use kestrel::config::vehicles::same_endpoint;
use kestrel::config::Config;
use kestrel::control::Setpoint;
use kestrel::core::{CoreConfig, DroneCore};
use kestrel::estimator::geodetic::GeodeticOrigin;
use kestrel::estimator::map_correction::AUTOPILOT_DRIFT_MPS;
use kestrel::estimator::EstimatorPlugin;
use kestrel::flightlog::{FlightLog, LogFormat};
use kestrel::host::runtime::Pace;
use kestrel::host::HostBuilder;
use kestrel::platform::mavlink::{start_hub, LinkConfig, LinkHub, MavlinkPlatform, TextSender};
use kestrel::platform::shifted::Shifted;
use kestrel::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use kestrel::sim::spatial::ShapeIndex;
use kestrel::sim::virtual_world::{VirtualRanges, VirtualSensors};
use kestrel::sim::{Environment, SimWorld};
use kestrel::types::Vec3;
use std::path::PathBuf;
use std::time::Duration;

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Config file (TOML); its `[mavlink]` section says where the autopilot is.
    #[arg(long)]
    config: Option<PathBuf>,
    /// Autopilot profile: a built-in name (`px4`, `ardupilot-copter`, `sim`) or a file
    /// (`platforms/px4.toml`; relative paths not found here are looked up in
    /// /usr/share/kestrel). Overrides `mavlink.platform` (with a `[[vehicle]]` list: the
    /// profile of the vehicles that name none).
    #[arg(long)]
    platform: Option<String>,
    /// MAVLink connection (`udpin:0.0.0.0:14540`, `tcpout:127.0.0.1:5760`,
    /// `serial:/dev/ttyACM0:921600` ...). Overrides `mavlink.connection`; refused with a
    /// `[[vehicle]]` list (each vehicle names its own).
    #[arg(long)]
    connection: Option<String>,
    /// Fly the demo plan of `kestrel sim` (takeoff, go_to, follow_path, land) as a mission, from
    /// where the (first) vehicle stands once it is ready.
    #[arg(long)]
    mission_demo: bool,
    /// Exit when the plan is over: 0 if it succeeded, non-zero with the reason if not.
    #[arg(long)]
    exit_when_done: bool,
    /// Flight log at this path, which must not exist yet (see --log-overwrite).
    /// Default: a new kestrel-run-<UTC start time>.jsonl (.mcap with --log-format mcap) in
    /// `drone.log_dir` or here.
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
    /// With `--exit-when-done` or `--no-api`: stop after this many seconds whatever happens.
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
    /// No API: connect, print link, mode and arming changes, log, and fly what `--mission` or
    /// `--mission-demo` say. For bench checks of a link.
    #[arg(long)]
    no_api: bool,
    /// Fly in this world (a `kestrel sim` world file, e.g. sitl/worlds/low.json) with virtual
    /// range sensors: each vehicle's sensor (its `[[vehicle]] sensor`, else `[sim] sensor`,
    /// else the file's, else the four-beam multi-ranger) is cast from its reported pose against
    /// the world's obstacles, replacing the autopilot's own range readings; coming within
    /// `[sim] vehicle_radius_m` of an obstacle fails what runs (`virtual_collision`) and holds.
    #[arg(long, value_name = "FILE")]
    virtual_world: Option<PathBuf>,
}

pub fn run(args: RunArgs) -> Result<()> {
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the tokio runtime")?;
    runtime.block_on(run_async(args))
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
        self.world
            .vehicles
            .first()
            .map_or(Capabilities::setpoints_only(), |v| v.capabilities())
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

/// Connections several vehicles share (the config checked that each names its system id), each
/// opened once, for the first vehicle on it.
#[derive(Default)]
struct SharedLinks {
    shared: Vec<String>,
    open: Vec<(String, LinkHub)>,
}

impl SharedLinks {
    fn new(plans: &[VehiclePlan]) -> Self {
        let shared = plans
            .iter()
            .filter(|p| matches!(p.platform, PlatformPlan::Mavlink(_)))
            .filter(|p| {
                plans
                    .iter()
                    .filter(|q| same_endpoint(&q.connection, &p.connection))
                    .count()
                    > 1
            })
            .map(|p| p.connection.clone())
            .collect();
        SharedLinks {
            shared,
            open: Vec::new(),
        }
    }

    /// The hub of `link`'s connection when vehicles share it (opened on first use).
    fn hub(&mut self, link: &LinkConfig) -> Result<Option<&LinkHub>> {
        if !self
            .shared
            .iter()
            .any(|c| same_endpoint(c, &link.connection))
        {
            return Ok(None);
        }
        let at = match self
            .open
            .iter()
            .position(|(c, _)| same_endpoint(c, &link.connection))
        {
            Some(i) => i,
            None => {
                let hub = start_hub(link.clone())?;
                self.open.push((link.connection.clone(), hub));
                self.open.len() - 1
            }
        };
        Ok(Some(&self.open[at].1))
    }
}

/// A started vehicle: the platform, its readiness timeout, its estimator by default and, over
/// MAVLink, where its texts for the ground station go.
type Started = (
    Box<dyn Platform>,
    Duration,
    EstimatorPlugin,
    Option<TextSender>,
);

/// Starts a vehicle's platform prepared by [`crate::cli::startup::prepare`]. `several`: name
/// the vehicle in the banner.
fn start_platform(
    config: &Config,
    plan: VehiclePlan,
    several: bool,
    links: &mut SharedLinks,
) -> Result<Started> {
    let VehiclePlan {
        id,
        platform_origin,
        platform,
        connection,
        forward,
        target_system,
        origin_enu_m,
        sensor: _,
    } = plan;
    let who = if several {
        format!("{id}: ")
    } else {
        String::new()
    };
    let (platform, ready_timeout, estimator, texts): Started = match platform {
        PlatformPlan::Sim { file, world } => {
            let environment = Environment {
                wind_mps: Vec3::from(config.sim.wind_enu_mps),
                turbulence_mps2: config.sim.turbulence_mps2,
            };
            println!(
                "kestrel run: {who}{} (profile {platform_origin})",
                file.name
            );
            let mut world = SimWorld::new(*world, 1, file.seed, environment);
            for v in &mut world.vehicles {
                v.params.radius_m = config.sim.vehicle_radius_m;
            }
            world.set_imperfections(config.sim.imperfections());
            let sim = RealtimeSim {
                world,
                stepped_to: Duration::ZERO,
            };
            (
                Box::new(sim),
                SIM_READY_TIMEOUT,
                EstimatorPlugin::GroundTruth,
                None,
            )
        }
        PlatformPlan::Mavlink(profile) => {
            let m = &config.mavlink;
            let ready_timeout = profile.ready_timeout;
            println!(
                "kestrel run: {who}{} over {connection} (profile {platform_origin})",
                profile.name
            );
            let mut peers = m.peer_policy();
            peers.target_system = target_system;
            let mut session = m.session_config();
            session.target_system = target_system;
            let link = LinkConfig {
                connection,
                forward,
                peers,
            };
            let platform = match links.hub(&link)? {
                Some(hub) => {
                    println!(
                        "kestrel run: {who}system {} on the shared {}",
                        target_system.map_or(0, u32::from),
                        link.connection
                    );
                    MavlinkPlatform::start_shared(*profile, session, hub)
                }
                None => MavlinkPlatform::start(*profile, session, link),
            }
            .with_context(|| format!("vehicle {id}"))?;
            let texts = platform.texts();
            (
                Box::new(platform),
                ready_timeout,
                EstimatorPlugin::AutopilotOdometry,
                Some(texts),
            )
        }
    };
    let origin = Vec3::from(origin_enu_m);
    let platform: Box<dyn Platform> = if origin == Vec3::zeros() {
        platform
    } else {
        Box::new(Shifted::new(platform, origin))
    };
    Ok((platform, ready_timeout, estimator, texts))
}

/// The simulator is ready at once; this only bounds a broken setup.
const SIM_READY_TIMEOUT: Duration = Duration::from_secs(5);

async fn run_async(args: RunArgs) -> Result<()> {
    let startup = prepare(
        args.config.as_deref(),
        &Overrides {
            platform: args.platform.clone(),
            connection: args.connection.clone(),
            listen: args.listen.clone(),
            state_dir: args.state_dir.clone(),
            no_api: args.no_api,
            virtual_world: args.virtual_world.clone(),
        },
    )?;
    for w in &startup.warnings {
        tracing::warn!("{w}");
    }
    let (listen, token, state_dir, map) = (
        startup.listen,
        startup.token.clone(),
        startup.state_dir.clone(),
        startup.map.clone(),
    );
    let Startup {
        config,
        vehicles,
        virtual_world,
        ..
    } = startup;
    let several = vehicles.len() > 1 || !config.vehicles.is_empty();
    let mut fleet = Vec::with_capacity(vehicles.len());
    let mut ready_timeout = Duration::ZERO;
    let mut links = SharedLinks::new(&vehicles);
    let obstacles = virtual_world
        .as_ref()
        .map(|v| std::sync::Arc::new(ShapeIndex::new(v.world.shapes())));
    let mut texts = Vec::new();
    for (k, plan) in vehicles.into_iter().enumerate() {
        let id = plan.id.clone();
        let ranges = virtual_world.as_ref().zip(obstacles.clone()).map(|(v, o)| {
            VirtualRanges::new(o, v.sensor(&plan, &config), config.sim.vehicle_radius_m)
        });
        let (platform, ready, estimator, sender) =
            start_platform(&config, plan, several, &mut links)?;
        texts.extend(sender.map(|s| (id.clone(), s)));
        // Outside the shift: the scans are cast in the shared frame, where the world is.
        let platform: Box<dyn Platform> = match ranges {
            Some(ranges) => Box::new(VirtualSensors::new(platform, ranges, &id, k as u64)),
            None => platform,
        };
        ready_timeout = ready_timeout.max(ready);
        let mut core_config = CoreConfig::new(&id);
        core_config.estimator = config.estimator.plugin.unwrap_or(estimator);
        core_config.map_correction = config
            .estimator
            .map_correction
            .for_vehicle(AUTOPILOT_DRIFT_MPS);
        core_config.controller = config.controller;
        core_config.behaviors = config.behaviors;
        core_config.exploration = config.exploration;
        core_config.map.clone_from(&map);
        core_config.safety = config.safety_config();
        if let Some(o) = config.drone.geodetic_origin {
            core_config.geo_origin = GeodeticOrigin(o);
        }
        let core = DroneCore::new(
            core_config,
            platform.capabilities(),
            kestrel::behavior::payload::registry(),
        );
        fleet.push((core, platform));
    }
    let api = Api {
        listen,
        token,
        state_dir,
    };
    if let Some(v) = &virtual_world {
        println!(
            "kestrel run: virtual world {} ({} obstacles): range sensors cast there",
            v.path.display(),
            v.world.shapes().len()
        );
    }
    serve_vehicles(
        &args,
        &config,
        api,
        fleet,
        (ready_timeout, texts),
        virtual_world.map(|v| v.world),
    )
    .await
}

/// The API's address (`None`: `--no-api`) and token, and the state directory, as checked.
struct Api {
    listen: Option<std::net::SocketAddr>,
    token: Option<String>,
    state_dir: PathBuf,
}

/// The service path: the vehicles on the host, the API served until interrupted.
async fn serve_vehicles(
    args: &RunArgs,
    config: &Config,
    api: Api,
    fleet: Vec<(DroneCore, Box<dyn Platform>)>,
    (ready_timeout, texts): (Duration, Vec<(String, TextSender)>),
    virtual_world: Option<kestrel::sim::world::World>,
) -> Result<()> {
    // In a virtual world the merged map is framed on it and exploration is judged against it.
    let mut host = match virtual_world {
        Some(world) => HostBuilder::vehicles(fleet, config).world(world),
        None => HostBuilder::vehicles(fleet, config),
    }
    .build();
    let Api {
        listen,
        token,
        state_dir: dir,
    } = api;
    let listener = match listen {
        Some(listen) => Some(crate::cli::serve::bind(listen, token.as_deref())?),
        None => None,
    };
    let start = std::time::SystemTime::now();
    let (writer, log_file) = crate::cli::serve::open_log(&crate::cli::serve::LogChoice {
        explicit: args.log.clone(),
        overwrite: args.log_overwrite,
        dir: config.drone.log_dir.clone().unwrap_or_default(),
        kind: "kestrel-run".into(),
        keep: config.drone.log_keep,
        start,
        format: args.log_format.unwrap_or(config.drone.log_format),
    })?;
    let log_path = log_file.path.clone();
    let mut log = FlightLog::new(Box::new(writer), 10.0);
    log.header(crate::cli::serve::header(&crate::cli::serve::RunInfo {
        command: "run",
        config,
        seed: None,
        world: args.virtual_world.as_deref(),
        scenario: None,
        mission: args.mission.as_deref(),
        // From the config only: otherwise the autopilot's home, not known yet.
        geo_origin: config.drone.geodetic_origin,
        drones: host.drone_ids(),
        start,
    }));
    host.set_log(log);
    crate::cli::serve::open_state(&mut host, &dir)?;
    let flights = match &args.mission {
        Some(file) => {
            let text = std::fs::read_to_string(file)
                .with_context(|| format!("cannot read {}", file.display()))?;
            let mission = serde_json::from_str(&text)
                .with_context(|| format!("{} is not valid JSON", file.display()))?;
            vec![crate::cli::sim::execute(&mut host, mission)
                .with_context(|| format!("flying {}", file.display()))?]
        }
        None => Vec::new(),
    };
    println!("flight log {}", log_path.display());
    let between_ticks = join_fleet_bus(config, &mut host).await?;
    let options = ServeOptions {
        listener,
        token,
        api: config.api.clone(),
        pace: Pace::RealTime,
        log: Some(log_file),
        flights: Flights::new(flights, args.mission_demo),
        demo_within: args
            .mission_demo
            .then_some(ready_timeout + DEMO_READY_MARGIN),
        exit_when_done: args.exit_when_done,
        max_time: (args.exit_when_done || args.no_api)
            .then(|| Duration::from_secs_f64(args.max_time_s.max(1.0))),
        between_ticks,
        ros2: config.ros2.enabled.then(|| config.ros2.clone()),
        texts_pending: (!texts.is_empty()).then(|| {
            let senders: Vec<TextSender> = texts.iter().map(|(_, s)| s.clone()).collect();
            Box::new(move || senders.iter().any(TextSender::pending))
                as Box<dyn Fn() -> bool + Send>
        }),
        on_event: (!texts.is_empty()).then(|| {
            let mut ground = crate::cli::announce::GroundTexts::new(texts);
            Box::new(move |e: &_| ground.on_event(e)) as crate::cli::serve::EventTap
        }),
    };
    let outcome = crate::cli::serve::serve(host, options).await?;
    crate::cli::serve::report(&outcome, args.exit_when_done)
}

/// Opens the fleet bus when `[fleet] enabled`: the session is opened now (a bad configuration
/// stops the start), peers are reached in the background, and the control loop exchanges with
/// it between ticks.
#[cfg(feature = "fleet-bus")]
async fn join_fleet_bus(
    config: &Config,
    host: &mut kestrel::host::Host,
) -> Result<Option<kestrel::host::runtime::BetweenTicks>> {
    use kestrel::fleet_bus::node::{start, NodeConfig};
    use kestrel::fleet_bus::remote::SilencePolicy;
    use kestrel::host::bus_link::BusLink;
    let fleet = &config.fleet;
    if !fleet.enabled {
        return Ok(None);
    }
    let node = fleet.node_name(&host.drone_ids());
    let (signer, members) = crate::cli::fleet_key::identity(fleet, &node)?;
    let roster = members
        .iter()
        .map(|(n, m)| (n.clone(), m.drones.clone()))
        .collect();
    let port = start(NodeConfig {
        section: fleet.clone(),
        node: node.clone(),
        max_map_cells: host.map_cells(),
        signer,
        members,
    })
    .await?;
    host.enable_fleet_bus(
        SilencePolicy {
            peer_timeout: Duration::from_secs_f64(fleet.peer_timeout_s),
            lost_after: Duration::from_secs_f64(fleet.lost_after_s),
            keepout_m: fleet.silent_keepout_m,
        },
        roster,
    );
    println!(
        "fleet bus: fleet `{}` as node `{node}` of {} members, listening on [{}], connecting \
         to [{}]",
        fleet.name,
        fleet.roster.len(),
        fleet.listen.join(", "),
        fleet.connect.join(", ")
    );
    let mut link = BusLink::new(port, fleet, node);
    Ok(Some(Box::new(move |host: &mut kestrel::host::Host| {
        link.exchange(host)
    })))
}

/// Without the bus built in, `[fleet] enabled` was refused by `prepare`.
#[cfg(not(feature = "fleet-bus"))]
async fn join_fleet_bus(
    _config: &Config,
    _host: &mut kestrel::host::Host,
) -> Result<Option<kestrel::host::runtime::BetweenTicks>> {
    Ok(None)
}

/// How long past the profile's readiness timeout the demo waits for the vehicle.
const DEMO_READY_MARGIN: Duration = Duration::from_secs(30);
