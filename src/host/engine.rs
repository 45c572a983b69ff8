//! The synchronous host: every drone's core and mission executor, the vehicles, the frames
//! registered over the API and the flight log, stepped one tick at a time.
//!
//! In: [`Command`]s (each with a one-shot reply) and ticks. Out: replies, the published
//! [`HostSnapshot`], [`HostEvent`]s and a [`PersistedState`]. It never reads the clock: the
//! runtime (`host::runtime`) decides when to step, in real or simulated time.

use super::fleet::Fleet;
pub use super::map_view::MapView;
use super::status::{link_word, DroneStatus, EventBody, HostEvent, HostSnapshot};
use crate::behavior::RunState;
use crate::core::DroneCore;
use crate::estimator::frames::{FrameError, FrameMotion, EARTH};
use crate::flightlog::FlightLog;
use crate::mapping::merged::FleetMap;
use crate::mapping::scan::RangeScan;
use crate::mission::executor::{ExecutorSnapshot, Progress};
use crate::mission::{
    ActionError, ExecState, Limits, Mission, MissionExecutor, MissionStatus, MissionUpdate,
    Request, ValidationContext, ValidationError,
};
use crate::types::{LinkHealth, Pose, Vec3};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::collections::BTreeMap;
use std::time::Duration;
use tokio::sync::oneshot;

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
}

impl From<FrameError> for HostError {
    fn from(e: FrameError) -> Self {
        HostError::Frame(e.to_string())
    }
}

pub type Reply<T> = oneshot::Sender<Result<T, HostError>>;

/// Most API scans waiting for one drone's next tick.
const MAX_QUEUED_SCANS: usize = 64;

/// A request from the API (or the CLI) to the host.
#[derive(Debug)]
pub enum Command {
    /// Load a mission for the drone its `target` names; `mission_id` None = a new id.
    Upload {
        mission: Value,
        mission_id: Option<u32>,
        reply: Reply<Uploaded>,
    },
    Update {
        update: MissionUpdate,
        reply: Reply<Updated>,
    },
    Delete {
        drone: Option<String>,
        mission_id: u32,
        reply: Reply<()>,
    },
    Missions {
        drone: Option<String>,
        reply: Reply<Vec<MissionView>>,
    },
    Mission {
        drone: Option<String>,
        mission_id: u32,
        reply: Reply<MissionView>,
    },
    SetFrame {
        frame: FrameRegistration,
        reply: Reply<()>,
    },
    Frames {
        reply: Reply<Vec<FrameRegistration>>,
    },
    /// Simulator only: cut or restore a drone's link.
    Fault {
        drone_id: String,
        link_lost: bool,
        reply: Reply<()>,
    },
    /// Flush the flight log so readers see every record.
    FlushLog { reply: Reply<()> },
    /// A copy of a drone's map (the one it plans on), or of the merged map when `drone` is
    /// absent.
    Map {
        drone: Option<String>,
        reply: Reply<MapView>,
    },
    /// Scans from outside (API) for a drone's next tick; replies with the number queued.
    Scans {
        drone: Option<String>,
        scans: Vec<RangeScan>,
        reply: Reply<usize>,
    },
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct Uploaded {
    pub drone: String,
    pub mission_id: u32,
    pub warnings: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct Updated {
    pub drone: String,
    pub status: MissionStatus,
}

/// A loaded mission as `GET /api/missions` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct MissionView {
    pub mission_id: u32,
    pub drone: String,
    pub target: String,
    pub items: usize,
    /// 0 idle, 1 running, 2 paused (this mission, not the executor).
    #[schema(value_type = u8)]
    pub state: ExecState,
    pub cursor: usize,
    pub finished: bool,
    pub warnings: Vec<String>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub plan: Option<Mission>,
    #[serde(skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Object)]
    pub progress: Option<Value>,
}

fn earth() -> String {
    EARTH.to_string()
}

/// A user frame: its pose in a parent frame now, and optionally how it moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FrameRegistration {
    pub frame_id: String,
    #[serde(default = "earth")]
    pub parent: String,
    #[serde(default)]
    pub translation_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
    /// Constant velocity of the frame in its parent (m/s).
    #[serde(default)]
    pub velocity_mps: [f64; 3],
    /// Constant yaw rate (rad/s), e.g. a nacelle turning into the wind.
    #[serde(default)]
    pub yaw_rate_radps: f64,
    /// Only this drone; absent = every drone.
    #[serde(default)]
    pub drone_id: Option<String>,
}

impl FrameRegistration {
    fn check(&self) -> Result<(), HostError> {
        let numbers = self
            .translation_m
            .iter()
            .chain(&self.velocity_mps)
            .chain([&self.yaw_rad, &self.yaw_rate_radps]);
        for v in numbers {
            if !v.is_finite() {
                return Err(HostError::Frame(format!(
                    "{}: every number must be finite",
                    self.frame_id
                )));
            }
        }
        Ok(())
    }

    fn motion(&self, now: Duration) -> FrameMotion {
        let [x, y, z] = self.translation_m;
        let [vx, vy, vz] = self.velocity_mps;
        FrameMotion {
            pose_in_parent: Pose::from_position_yaw(Vec3::new(x, y, z), self.yaw_rad),
            stamp: now,
            velocity_mps: Vec3::new(vx, vy, vz),
            yaw_rate_radps: self.yaw_rate_radps,
        }
    }
}

/// What the state directory keeps.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct PersistedState {
    pub drones: BTreeMap<String, ExecutorSnapshot>,
    pub frames: Vec<FrameRegistration>,
}

pub struct HostConfig {
    pub limits: Limits,
    pub switch_hold: Duration,
    pub tick: Duration,
}

pub struct Host {
    cores: Vec<DroneCore>,
    executors: Vec<MissionExecutor>,
    fleet: Box<dyn Fleet>,
    limits: Limits,
    frames: Vec<FrameRegistration>,
    revision: u64,
    log: Option<FlightLog>,
    now: Duration,
    tick: Duration,
    events: Vec<HostEvent>,
    published: Vec<u64>,
    links: Vec<LinkHealth>,
    errors: Vec<Option<String>>,
    /// The fleet's merged map (`None` when mapping is off).
    map: Option<FleetMap>,
    /// Scans sent over the API, handed to each drone's next tick.
    api_scans: Vec<Vec<RangeScan>>,
}

impl Host {
    /// One core per vehicle of `fleet`, in the same order.
    pub fn new(cores: Vec<DroneCore>, fleet: Box<dyn Fleet>, config: HostConfig) -> Self {
        let n = cores.len();
        Self {
            executors: (0..n)
                .map(|_| MissionExecutor::new(config.switch_hold))
                .collect(),
            cores,
            fleet,
            limits: config.limits,
            frames: Vec::new(),
            revision: 0,
            log: None,
            now: Duration::ZERO,
            tick: config.tick,
            events: Vec::new(),
            published: vec![u64::MAX; n],
            links: vec![LinkHealth::Connecting; n],
            errors: vec![None; n],
            map: None,
            api_scans: vec![Vec::new(); n],
        }
    }

    /// Keeps the fleet's merged map, fed with every drone's scans.
    pub fn set_map(&mut self, map: FleetMap) {
        self.map = Some(map);
    }

    pub fn map(&self) -> Option<&FleetMap> {
        self.map.as_ref()
    }

    /// The merged map's regions changed since the last call, as `map_update` events.
    pub fn take_map_updates(&mut self) -> Vec<HostEvent> {
        self.map
            .as_mut()
            .map(|m| {
                m.take_patches()
                    .into_iter()
                    .map(HostEvent::map_update)
                    .collect()
            })
            .unwrap_or_default()
    }

    pub fn set_log(&mut self, log: FlightLog) {
        self.log = Some(log);
    }

    pub fn now(&self) -> Duration {
        self.now
    }

    /// What missions are checked against (speed limit, geofence).
    pub fn limits(&self) -> &Limits {
        &self.limits
    }

    pub fn tick_period(&self) -> Duration {
        self.tick
    }

    pub fn is_simulated(&self) -> bool {
        self.fleet.is_simulated()
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
        &self.executors
    }

    /// Restores missions (never running) and frames kept by a previous run.
    pub fn restore(&mut self, state: PersistedState, switch_hold: Duration) {
        for (i, core) in self.cores.iter().enumerate() {
            if let (Some(snap), Some(ex)) =
                (state.drones.get(core.drone_id()), self.executors.get_mut(i))
            {
                *ex = MissionExecutor::restore(snap.clone(), switch_hold);
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
                .zip(&self.executors)
                .map(|(c, e)| (c.drone_id().to_string(), e.snapshot()))
                .collect(),
            frames: self.frames.clone(),
        }
    }

    /// Changes whenever something worth persisting changed.
    pub fn revision(&self) -> u64 {
        self.revision + self.executors.iter().map(|e| e.revision()).sum::<u64>()
    }

    pub fn snapshot(&self) -> HostSnapshot {
        HostSnapshot {
            t: self.now.as_secs_f64(),
            drones: self
                .cores
                .iter()
                .zip(&self.executors)
                .map(|(c, e)| DroneStatus::of(c, e))
                .collect(),
        }
    }

    /// Events since the last call, with a mission status for every executor that changed.
    pub fn drain_events(&mut self) -> Vec<HostEvent> {
        for (i, (core, ex)) in self.cores.iter().zip(&self.executors).enumerate() {
            if self.published.get(i) != Some(&ex.revision()) {
                self.events.push(HostEvent::MissionStatus {
                    drone: core.drone_id().to_string(),
                    status: ex.status(core),
                });
                if let Some(p) = self.published.get_mut(i) {
                    *p = ex.revision();
                }
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

    /// One control tick at the host's own clock.
    pub fn step(&mut self) {
        let now = self.now;
        self.step_at(now);
        self.now = now + self.tick;
    }

    /// One control tick at `now` (real-time drivers pass the wall-clock time since start).
    pub fn step_at(&mut self, now: Duration) {
        self.now = now;
        for i in 0..self.cores.len() {
            let mut feedback = self.fleet.poll(i, now);
            if let Some(scans) = self.api_scans.get_mut(i) {
                feedback.scans.append(scans);
            }
            let Some(core) = self.cores.get_mut(i) else {
                continue;
            };
            let out = core.tick(now, &feedback);
            self.fleet.command(i, now, out.setpoint, &out.requests);
            if let Some(map) = self.map.as_mut() {
                for scan in &feedback.scans {
                    // The drone's own map already counted an invalid scan.
                    let _ = map.insert(core.drone_id(), scan);
                }
            }
            if let Some(ex) = self.executors.get_mut(i) {
                ex.update(now, core, &out.events);
            }
            let status = feedback.status;
            if let Some(log) = self.log.as_mut() {
                let state = core.vehicle_state();
                let active = core.server().active();
                let motion = active
                    .iter()
                    .find(|a| a.state == RunState::Running || a.state == RunState::Paused)
                    .map(|a| a.behavior.as_str());
                log.pose(now, &state, motion);
                for e in &out.events {
                    log.behavior(now, core.drone_id(), e);
                }
            }
            for e in out.events {
                self.event(i, EventBody::Behavior(e));
            }
            if self.links.get(i) != Some(&status.link) {
                if let Some(l) = self.links.get_mut(i) {
                    *l = status.link;
                }
                self.event(
                    i,
                    EventBody::Alert {
                        message: format!("link {}", link_word(status.link)),
                    },
                );
            }
            if status.last_error.is_some() && self.errors.get(i) != Some(&status.last_error) {
                if let Some(text) = status.last_error.clone() {
                    self.event(i, EventBody::Autopilot { text });
                }
                if let Some(e) = self.errors.get_mut(i) {
                    e.clone_from(&status.last_error);
                }
            }
        }
        self.fleet.advance(now, self.tick);
        for (i, message) in self.fleet.take_alerts() {
            if let (Some(log), Some(core)) = (self.log.as_mut(), self.cores.get(i)) {
                log.event(now, core.drone_id(), "collision", &message);
            }
            self.event(i, EventBody::Alert { message });
        }
    }

    pub fn flush_log(&mut self) {
        if let Some(log) = self.log.as_mut() {
            log.flush();
        }
    }

    fn ids(&self) -> String {
        self.drone_ids().join(", ")
    }

    /// The drone a command is for: by name, or the only one when absent.
    fn route(&self, drone: Option<&str>) -> Result<usize, HostError> {
        match drone {
            Some(d) => self
                .cores
                .iter()
                .position(|c| c.drone_id() == d)
                .ok_or_else(|| HostError::UnknownDrone(d.to_string(), self.ids())),
            None if self.cores.len() == 1 => Ok(0),
            None => Err(HostError::DroneNeeded(self.ids())),
        }
    }

    fn validation_context(&self, i: usize) -> Option<ValidationContext<'_>> {
        let core = self.cores.get(i)?;
        let state = core.vehicle_state();
        let home = core
            .home_enu_m()
            .unwrap_or(if state.estimate.valid.position {
                state.estimate.pose.position_m
            } else {
                Vec3::zeros()
            });
        Some(ValidationContext {
            drone_id: core.drone_id(),
            registry: core.server().registry(),
            limits: &self.limits,
            frames: core.frames(),
            now: self.now,
            home_enu_m: home,
            geo_origin: core.geo_origin(),
        })
    }

    /// Validates a mission for drone `i`.
    pub fn validate(
        &self,
        i: usize,
        mission: &Value,
    ) -> Result<crate::mission::ValidMission, HostError> {
        let ctx = self
            .validation_context(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), self.ids()))?;
        crate::mission::validate::validate_value(mission, &ctx).map_err(HostError::Invalid)
    }

    /// Loads a mission for the drone its target names.
    pub fn upload(
        &mut self,
        mission: &Value,
        mission_id: Option<u32>,
    ) -> Result<Uploaded, HostError> {
        let target = match mission.get("target") {
            Some(Value::String(t)) => t.clone(),
            _ => {
                // Validation of any drone lists every problem, target included.
                return Err(match self.validate(0, mission) {
                    Err(e) => e,
                    Ok(_) => HostError::Invalid(vec![ValidationError {
                        pointer: "/target".into(),
                        message: "missing target".into(),
                    }]),
                });
            }
        };
        let i = self.route(Some(&target)).map_err(|e| {
            HostError::Invalid(vec![ValidationError {
                pointer: "/target".into(),
                message: e.to_string(),
            }])
        })?;
        let valid = self.validate(i, mission)?;
        let warnings = valid.warnings.clone();
        let now = self.now;
        let (Some(ex), Some(core)) = (self.executors.get_mut(i), self.cores.get_mut(i)) else {
            return Err(HostError::UnknownDrone(target, String::new()));
        };
        let id = match mission_id {
            None => ex.load_new(valid),
            Some(id) => {
                let req = Request {
                    action: crate::mission::Action::Load,
                    mission_id: Some(id),
                    item_id: None,
                    mission: Some(valid),
                };
                ex.apply(req, core, now)?;
                id
            }
        };
        self.log_command(i, "upload", json!({ "mission_id": id }));
        Ok(Uploaded {
            drone: target,
            mission_id: id,
            warnings,
        })
    }

    /// Applies a MissionUpdate to the drone it names.
    pub fn update(&mut self, update: &MissionUpdate) -> Result<Updated, HostError> {
        let i = self.route(update.drone_id.as_deref())?;
        let result = self.update_drone(i, update);
        let (accepted, reason) = match &result {
            Ok(_) => (true, None),
            Err(e) => (false, Some(e.to_string())),
        };
        self.log_command(
            i,
            "mission_update",
            json!({ "action": update.action, "mission_id": update.mission_id, "item_id": update.item_id, "accepted": accepted, "reason": reason }),
        );
        self.event(
            i,
            EventBody::MissionUpdate {
                action: update.action,
                mission_id: update.mission_id.and_then(|m| u32::try_from(m).ok()),
                accepted,
                reason,
            },
        );
        result
    }

    fn update_drone(&mut self, i: usize, update: &MissionUpdate) -> Result<Updated, HostError> {
        let req = {
            let ctx = self
                .validation_context(i)
                .ok_or_else(|| HostError::UnknownDrone(i.to_string(), self.ids()))?;
            Request::prepare(update, &ctx)?
        };
        let now = self.now;
        let (Some(ex), Some(core)) = (self.executors.get_mut(i), self.cores.get_mut(i)) else {
            return Err(HostError::UnknownDrone(i.to_string(), String::new()));
        };
        let status = ex.apply(req, core, now)?;
        Ok(Updated {
            drone: core.drone_id().to_string(),
            status,
        })
    }

    fn log_command(&mut self, i: usize, command: &str, fields: Value) {
        if let (Some(log), Some(core)) = (self.log.as_mut(), self.cores.get(i)) {
            log.command(self.now, core.drone_id(), command, fields);
        }
    }

    fn views(&self, drone: Option<&str>, with_plan: bool) -> Result<Vec<MissionView>, HostError> {
        let indices: Vec<usize> = match drone {
            Some(d) => vec![self.route(Some(d))?],
            None => (0..self.cores.len()).collect(),
        };
        let mut out = Vec::new();
        for i in indices {
            let (Some(core), Some(ex)) = (self.cores.get(i), self.executors.get(i)) else {
                continue;
            };
            for (id, loaded) in ex.missions() {
                let state = if ex.running_id() == Some(*id) {
                    ex.state()
                } else {
                    ExecState::Idle
                };
                out.push(MissionView {
                    mission_id: *id,
                    drone: core.drone_id().to_string(),
                    target: loaded.mission.target.clone(),
                    items: loaded.mission.items.len(),
                    state,
                    cursor: loaded.progress.cursor,
                    finished: loaded.progress.finished,
                    warnings: loaded.mission.warnings.clone(),
                    plan: with_plan.then(|| loaded.mission.as_written()),
                    progress: with_plan.then(|| progress_json(&loaded.progress)),
                });
            }
        }
        Ok(out)
    }

    fn mission_view(&self, drone: Option<&str>, id: u32) -> Result<MissionView, HostError> {
        let views = self.views(drone, true)?;
        let mut matching: Vec<MissionView> =
            views.into_iter().filter(|v| v.mission_id == id).collect();
        match matching.len() {
            0 => Err(ActionError::UnknownMission(id).into()),
            1 => Ok(matching.remove(0)),
            _ => Err(HostError::DroneNeeded(self.ids())),
        }
    }

    fn delete(&mut self, drone: Option<&str>, id: u32) -> Result<(), HostError> {
        let i = match drone {
            Some(d) => self.route(Some(d))?,
            None => {
                let owners: Vec<usize> = (0..self.executors.len())
                    .filter(|i| {
                        self.executors
                            .get(*i)
                            .is_some_and(|e| e.missions().contains_key(&id))
                    })
                    .collect();
                match owners.as_slice() {
                    [] => return Err(ActionError::UnknownMission(id).into()),
                    [one] => *one,
                    _ => return Err(HostError::DroneNeeded(self.ids())),
                }
            }
        };
        let ex = self
            .executors
            .get_mut(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), String::new()))?;
        ex.unload(id)?;
        Ok(())
    }

    /// Registers or updates a frame in every drone (or the one it names); all or none.
    pub fn set_frame(&mut self, frame: FrameRegistration) -> Result<(), HostError> {
        frame.check()?;
        let targets: Vec<usize> = match &frame.drone_id {
            Some(d) => vec![self.route(Some(d))?],
            None => (0..self.cores.len()).collect(),
        };
        let motion = frame.motion(self.now);
        for &i in &targets {
            if let Some(core) = self.cores.get(i) {
                let mut trial = core.frames().clone();
                trial.set(&frame.frame_id, &frame.parent, motion)?;
            }
        }
        for &i in &targets {
            if let Some(core) = self.cores.get_mut(i) {
                core.set_frame(&frame.frame_id, &frame.parent, motion)?;
            }
        }
        self.frames
            .retain(|f| !(f.frame_id == frame.frame_id && f.drone_id == frame.drone_id));
        self.frames.push(frame);
        self.revision += 1;
        Ok(())
    }

    /// A copy of the map `drone` plans on, or of the merged map.
    pub fn map_view(&self, drone: Option<&str>) -> Result<MapView, HostError> {
        let off = || HostError::NotSupported("mapping is off ([map] plugin = \"none\")".into());
        match drone {
            Some(d) => {
                let i = self.route(Some(d))?;
                let map = self.cores.get(i).and_then(|c| c.map()).ok_or_else(off)?;
                Ok(MapView::of_drone(d, map))
            }
            None => {
                let map = self.map.as_ref().ok_or_else(off)?;
                Ok(MapView::merged(map))
            }
        }
    }

    fn queue_scans(
        &mut self,
        drone: Option<&str>,
        scans: Vec<RangeScan>,
    ) -> Result<usize, HostError> {
        let i = self.route(drone)?;
        if self.cores.get(i).and_then(|c| c.map()).is_none() {
            return Err(HostError::NotSupported(
                "mapping is off ([map] plugin = \"none\")".into(),
            ));
        }
        let queue = self
            .api_scans
            .get_mut(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), String::new()))?;
        if queue.len() + scans.len() > MAX_QUEUED_SCANS {
            return Err(HostError::Unavailable(format!(
                "more than {MAX_QUEUED_SCANS} scans wait for the next tick; send fewer"
            )));
        }
        let n = scans.len();
        queue.extend(scans);
        Ok(n)
    }

    /// Carries out one command and answers it.
    pub fn handle(&mut self, command: Command) {
        // A client that gave up waiting dropped its receiver; nothing to answer then.
        match command {
            Command::Upload {
                mission,
                mission_id,
                reply,
            } => {
                let _ = reply.send(self.upload(&mission, mission_id));
            }
            Command::Update { update, reply } => {
                let _ = reply.send(self.update(&update));
            }
            Command::Delete {
                drone,
                mission_id,
                reply,
            } => {
                let _ = reply.send(self.delete(drone.as_deref(), mission_id));
            }
            Command::Missions { drone, reply } => {
                let _ = reply.send(self.views(drone.as_deref(), false));
            }
            Command::Mission {
                drone,
                mission_id,
                reply,
            } => {
                let _ = reply.send(self.mission_view(drone.as_deref(), mission_id));
            }
            Command::SetFrame { frame, reply } => {
                let _ = reply.send(self.set_frame(frame));
            }
            Command::Frames { reply } => {
                let _ = reply.send(Ok(self.frames.clone()));
            }
            Command::Fault {
                drone_id,
                link_lost,
                reply,
            } => {
                let result = self.route(Some(&drone_id)).and_then(|i| {
                    self.fleet
                        .set_link_lost(i, link_lost)
                        .map_err(HostError::NotSupported)
                });
                let _ = reply.send(result);
            }
            Command::FlushLog { reply } => {
                self.flush_log();
                let _ = reply.send(Ok(()));
            }
            Command::Map { drone, reply } => {
                let _ = reply.send(self.map_view(drone.as_deref()));
            }
            Command::Scans {
                drone,
                scans,
                reply,
            } => {
                let _ = reply.send(self.queue_scans(drone.as_deref(), scans));
            }
        }
    }
}

fn progress_json(p: &Progress) -> Value {
    json!({ "cursor": p.cursor, "done_results": p.done, "finished": p.finished })
}
