//! The synchronous host: every drone's core and mission executor, the vehicles, the frames
//! registered over the API and the flight log, stepped one tick at a time. What it keeps lives
//! in services it owns, each a module with its own state and tests (`executors`, `runs`, `log`,
//! `peers`, the frame registry in `frames`, `persist`); its own methods orchestrate them.
//!
//! In: [`Command`]s (each with a one-shot reply) and ticks. Out: replies, the published
//! [`HostSnapshot`], [`HostEvent`]s, the changes to save (handed to the store after every tick
//! and before a command's answer) and a [`PersistedState`]. It never reads the clock: the
//! runtime (`host::runtime`) decides when to step, in real or simulated time.

mod bus;
mod commands;
mod executors;
mod explore;
mod frames;
mod log;
mod maps;
mod missions;
mod peers;
mod persist;
mod runs;
mod tick;

pub use super::map_view::MapView;
pub use bus::BusMapError;
pub use commands::{Command, Reply};
pub use explore::{ExplorationStarted, ReportInput, StartedDrone};
pub use frames::{FrameRegistration, MAX_FRAMES};
pub use missions::{LoadOptions, MissionView, Updated, Uploaded, ValidatedUpload};

use super::status::{DroneStatus, EventBody, HostEvent, HostSnapshot};
use super::store::Sink;
use crate::behavior::{BehaviorId, ServerError};
use crate::core::{BehaviorCommand, DroneCore};
use crate::estimator::frames::FrameError;
use crate::exploration::online::service::{ExplorationView, RemoteClaim};
use crate::flightlog::FlightLog;
use crate::mapping::merged::FleetMap;
use crate::mapping::scan::RangeScan;
use crate::mission::executor::ExecutorConfig;
use crate::mission::executor::ExecutorSnapshot;
use crate::mission::{ActionError, Limits, MissionExecutor, ValidationError};
use crate::planning::worker::{Delivery, PlanWorker};
use crate::platform::fleet::Fleet;
use crate::types::FleetView;
use crate::types::LinkHealth;
use executors::Executors;
use frames::FrameRegistry;
use log::HostLog;
use peers::Peers;
use persist::Persistence;
use runs::ExplorationRuns;
use serde::{Deserialize, Serialize};
use std::any::Any;
use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

/// Why a command failed; the API maps each to an HTTP status and a stable code.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum HostError {
    #[error("unknown drone `{0}`; this Kestrel flies {1}")]
    UnknownDrone(String, String),
    #[error("drone_id is needed: this Kestrel flies {0}")]
    DroneNeeded(String),
    #[error("mission is invalid")]
    Invalid(Vec<ValidationError>),
    #[error(transparent)]
    Action(#[from] ActionError),
    #[error("frame: {0}")]
    Frame(String),
    #[error("{0}")]
    NotSupported(String),
    #[error("{0}")]
    Unavailable(String),
    /// EXECUTE of a mission that starts by landing, for a drone on the ground and disarmed.
    #[error("{0} is on the ground and disarmed: there is nothing to land, so the mission that starts with `land` was refused and not stored")]
    AlreadyLanded(String),
    #[error(transparent)]
    Behavior(#[from] ServerError),
    /// A drone of the fleet that another Kestrel flies (heard over the fleet bus).
    #[error("{drone} is flown by the Kestrel `{node}` of the fleet, not this one: send the command to that Kestrel's API")]
    RemoteDrone { drone: String, node: String },
    /// This Kestrel lists peers in `[fleet] connect` and has not joined them yet.
    #[error("this Kestrel has not joined its fleet `{fleet}` yet, waiting for {waiting_for}: it does not take off until it has (so that it never flies unseen by the others' separation and allocation); fix the credentials or the address, or set [fleet] require_join = false to fly without the fleet")]
    FleetNotJoined { fleet: String, waiting_for: String },
}

impl From<FrameError> for HostError {
    fn from(e: FrameError) -> Self {
        HostError::Frame(e.to_string())
    }
}

/// What the state directory keeps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PersistedState {
    pub drones: BTreeMap<String, ExecutorSnapshot>,
    pub frames: Vec<FrameRegistration>,
}

/// What a host is built with besides its cores and fleet (`host::builder` makes it from the
/// config).
pub(crate) struct HostConfig {
    pub limits: Limits,
    pub executor: ExecutorConfig,
    pub tick: Duration,
}

pub struct Host {
    cores: Vec<DroneCore>,
    /// Each drone's missions, and what missions are checked against.
    executors: Executors,
    fleet: Box<dyn Fleet>,
    /// The frames registered over the API.
    frames: FrameRegistry,
    /// The flight log (off until one is set).
    log: HostLog,
    now: Duration,
    tick: Duration,
    events: Vec<HostEvent>,
    links: Vec<LinkHealth>,
    errors: Vec<Option<String>>,
    modes: Vec<String>,
    /// The fleet's merged map (`None` when mapping is off).
    map: Option<FleetMap>,
    /// Scans sent over the API, handed to each drone's next tick.
    api_scans: Vec<Vec<RangeScan>>,
    /// Runs the drones' plans off the tick.
    planner: PlanWorker,
    /// The fleet view the cores saw this tick.
    fleet_view: Arc<FleetView>,
    /// The frontier allocator, the exploration run started over the API and its true world.
    exploration: ExplorationRuns,
    /// What changed, handed to the state directory's store.
    persistence: Persistence,
    /// The drones other Kestrels fly, heard over the fleet bus, and the bus's last report.
    peers: Peers,
}

impl Host {
    /// One core per vehicle of `fleet`, in the same order; built by `host::HostBuilder`.
    pub(crate) fn new(cores: Vec<DroneCore>, fleet: Box<dyn Fleet>, config: HostConfig) -> Self {
        let n = cores.len();
        Self {
            executors: Executors::new(n, config.executor, config.limits),
            cores,
            fleet,
            frames: FrameRegistry::default(),
            log: HostLog::default(),
            now: Duration::ZERO,
            tick: config.tick,
            events: Vec::new(),
            links: vec![LinkHealth::Connecting; n],
            errors: vec![None; n],
            modes: vec![String::new(); n],
            map: None,
            api_scans: vec![Vec::new(); n],
            planner: PlanWorker::new(Delivery::Lockstep),
            fleet_view: Arc::default(),
            exploration: ExplorationRuns::new(),
            persistence: Persistence::new(n),
            peers: Peers::default(),
        }
    }

    /// Keeps what changes from now on in the state directory behind `store`.
    pub fn set_store(&mut self, store: Sink) {
        self.persistence.set_store(store);
    }

    pub fn store(&self) -> Option<&Sink> {
        self.persistence.store()
    }

    /// Hands what changed since the last call to the store: the missions that changed (copied
    /// one by one, never all of them), an executor's small state, the frames. No I/O here.
    pub fn commit(&mut self) {
        let executors = self
            .cores
            .iter()
            .map(|c| c.drone_id())
            .zip(self.executors.iter_mut());
        self.persistence.commit(executors, &self.frames);
    }

    /// How plans and the frontier allocator's answers reach the behaviors: in lock step (the
    /// default: simulated time, reproducible) or, paced to the wall clock, as soon as they are
    /// done (plans with a deadline). Set before the first tick: a new allocator starts afresh.
    pub fn set_plan_delivery(&mut self, delivery: Delivery) {
        if self.planner.delivery() != delivery {
            self.planner = PlanWorker::new(delivery);
        }
        self.exploration.set_delivery(delivery);
    }

    /// Writes the wall clock at this moment's host time to the flight log (a `clock` record).
    pub fn log_wall_clock(&mut self, now: std::time::SystemTime) {
        self.log.wall_clock(self.now, now);
    }

    pub fn set_log(&mut self, log: FlightLog) {
        self.log.set(log);
    }

    pub fn now(&self) -> Duration {
        self.now
    }

    pub fn tick_period(&self) -> Duration {
        self.tick
    }

    pub fn is_simulated(&self) -> bool {
        self.fleet.is_simulated()
    }

    /// Nothing is flying or about to: no mission runs, no behavior is active, no drone is armed.
    pub fn is_idle(&self) -> bool {
        self.executors.all_idle()
            && self
                .cores
                .iter()
                .all(|c| c.server().is_idle() && !c.platform_status().armed)
    }

    /// Every drone's state as the cores saw it at the last tick.
    pub fn fleet_view(&self) -> &FleetView {
        &self.fleet_view
    }

    /// The fleet as the type it was built with (`None` for another type): how whoever built
    /// the host over a fleet of its own reaches it again (the simulator's ground truth).
    pub fn fleet_as<T: Fleet>(&self) -> Option<&T> {
        (self.fleet.as_ref() as &dyn Any).downcast_ref()
    }

    /// The fleet as the type it was built with, to change it mid-run (the simulator's weather,
    /// a pilot taking over a simulated vehicle).
    pub fn fleet_as_mut<T: Fleet>(&mut self) -> Option<&mut T> {
        (self.fleet.as_mut() as &mut dyn Any).downcast_mut()
    }

    /// Sends a behavior command straight to one drone's behavior server, bypassing missions
    /// (behavior-level tests and tools).
    pub fn behavior_command(
        &mut self,
        drone: usize,
        command: BehaviorCommand,
    ) -> Result<Option<BehaviorId>, HostError> {
        let known = self.drone_ids().join(", ");
        let core = self
            .cores
            .get_mut(drone)
            .ok_or_else(|| HostError::UnknownDrone(drone.to_string(), known))?;
        Ok(core.command(command)?)
    }

    pub fn drone_ids(&self) -> Vec<String> {
        self.cores
            .iter()
            .map(|c| c.drone_id().to_string())
            .collect()
    }

    pub fn cores(&self) -> &[DroneCore] {
        &self.cores
    }

    pub fn executors(&self) -> &[MissionExecutor] {
        self.executors.list()
    }

    /// Restores missions (never running) and frames kept by a previous run.
    pub fn restore(&mut self, state: PersistedState) {
        for (i, core) in self.cores.iter().enumerate() {
            if let Some(snap) = state.drones.get(core.drone_id()) {
                self.executors.restore(i, snap);
            }
        }
        for frame in state.frames {
            if let Err(e) = self.set_frame(frame.clone()) {
                tracing::warn!("saved frame {} not restored: {e}", frame.frame_id);
            }
        }
    }

    pub fn persisted(&self) -> PersistedState {
        PersistedState {
            drones: self
                .cores
                .iter()
                .zip(self.executors.list())
                .map(|(c, e)| (c.drone_id().to_string(), e.snapshot()))
                .collect(),
            frames: self.frames.list().to_vec(),
        }
    }

    pub fn snapshot(&self) -> HostSnapshot {
        HostSnapshot {
            remote: self.peers.statuses(self.now),
            fleet_bus: self.peers.report().cloned(),
            t: self.now.as_secs_f64(),
            drones: self
                .cores
                .iter()
                .zip(self.executors.list())
                .map(|(c, e)| DroneStatus::of(c, e))
                .collect(),
        }
    }

    /// Events since the last call, with a mission status for every executor that changed.
    pub fn drain_events(&mut self) -> Vec<HostEvent> {
        for i in self.executors.take_unpublished() {
            if let (Some(core), Some(ex)) = (self.cores.get(i), self.executors.get(i)) {
                self.events.push(HostEvent::MissionStatus {
                    drone: core.drone_id().to_string(),
                    status: ex.status(core),
                });
            }
        }
        std::mem::take(&mut self.events)
    }

    fn event(&mut self, i: usize, body: EventBody) {
        let drone = self
            .cores
            .get(i)
            .map(|c| c.drone_id().to_string())
            .unwrap_or_default();
        self.events.push(HostEvent::Event {
            drone,
            t: self.now.as_secs_f64(),
            event: body,
        });
    }

    /// The goals of drones other Kestrel processes fly, for this fleet's frontier allocator:
    /// (drone, goal, stamp on this host's clock, as [`Host::now`]); each replaces the last set.
    pub fn set_remote_claims(&mut self, claims: Vec<RemoteClaim>) {
        self.exploration.set_remote_claims(claims);
    }

    /// The frontiers and the goals the drones hold, as the allocator last saw them.
    pub fn exploration_view(&self) -> ExplorationView {
        ExplorationView {
            frontiers: self.exploration.frontiers().to_vec(),
            goals: self.exploration.claims().to_vec(),
            known_pct: self.map.as_ref().map(|m| known_pct(m.merged())),
            progress: self.exploration_progress(),
        }
    }

    pub fn flush_log(&mut self) {
        self.log.flush();
    }

    /// Flushes the flight log and lets it go: nothing is logged after this, and a log written
    /// in place (an MCAP log's summary) is finished.
    pub fn close_log(&mut self) {
        self.log.close();
    }
}

/// Known cells of a grid, in percent of all its cells.
fn known_pct(grid: &crate::mapping::grid::OccupancyGrid) -> f64 {
    let data = grid.data();
    let known = data.iter().filter(|&&v| v >= 0).count();
    100.0 * known as f64 / data.len().max(1) as f64
}
