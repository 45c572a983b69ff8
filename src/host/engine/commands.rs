//! Commands from the API to the host and their answers: missions (upload, MissionUpdate,
//! list, get, delete), frames, simulator faults, the flight log, maps and explorations.
//!
//! In: a [`Command`] with its one-shot reply. Out: the answer, and the changes in the host.

use super::{Host, HostError};
use crate::estimator::frames::{FrameMotion, BASE_LINK, EARTH, MAP, ODOM};
use crate::host::status::EventBody;
use crate::mission::executor::Progress;
use crate::mission::{
    Action, ActionError, ContextSnapshot, ExecState, Mission, MissionStatus, MissionUpdate,
    Request, ValidMission, ValidationContext, ValidationError,
};
use crate::types::LinkHealth;
use crate::types::{Pose, Vec3};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};
use std::time::Duration;
use tokio::sync::oneshot;

pub type Reply<T> = oneshot::Sender<Result<T, HostError>>;

/// A mission validated off the control loop, with what it was validated against.
#[derive(Debug)]
pub struct ValidatedUpload {
    pub drone: usize,
    pub mission: Value,
    pub valid: crate::mission::ValidMission,
    pub snapshot: ContextSnapshot,
    pub mission_id: Option<u32>,
}

/// A request from the API (or the CLI) to the host.
#[derive(Debug)]
pub enum Command {
    /// What an upload for `target` is validated against (see [`Host::upload_context`]).
    UploadContext {
        target: Option<String>,
        reply: Reply<(usize, ContextSnapshot)>,
    },
    /// Load a mission validated off the loop.
    UploadValidated {
        upload: Box<ValidatedUpload>,
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
        reply: Reply<super::MapView>,
    },
    /// The exploration as the frontier allocator last saw it: frontiers and the goal each
    /// drone holds.
    Exploration {
        reply: Reply<crate::exploration::service::ExplorationView>,
    },
    /// Start the `explore` behavior with `args` on `drones` (all or none).
    ExplorationStart {
        drones: Vec<String>,
        args: Value,
        reply: Reply<super::ExplorationStarted>,
    },
    /// Stop the exploration missions of `drones` (all or none); replies with the drones.
    ExplorationStop {
        drones: Vec<String>,
        reply: Reply<Vec<String>>,
    },
    /// What the exploration report is made of.
    ExplorationReport { reply: Reply<super::ReportInput> },
    /// Scans from outside (API) for a drone's next tick; replies with the number queued.
    Scans {
        drone: Option<String>,
        scans: Vec<crate::mapping::scan::RangeScan>,
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

/// Largest translation of a registered frame from its parent (m): 100 km.
pub const MAX_FRAME_OFFSET_M: f64 = 1e5;
/// Fastest a registered frame may move (m/s) and turn (rad/s).
pub const MAX_FRAME_SPEED_MPS: f64 = 50.0;
pub const MAX_FRAME_YAW_RATE_RADPS: f64 = 10.0;
/// Most frames registered over the API (all drones together, so also per drone); replacing a
/// registered one is always allowed.
pub const MAX_FRAMES: usize = 256;

impl FrameRegistration {
    /// Names and numbers: built-ins are not redefined, every number is finite and bounded.
    fn check(&self) -> Result<(), HostError> {
        let bad = |what: String| Err(HostError::Frame(format!("{}: {what}", self.frame_id)));
        if [EARTH, MAP, ODOM, BASE_LINK].contains(&self.frame_id.as_str()) {
            return bad("a built-in frame cannot be redefined".into());
        }
        let vector = |field: &str, v: &[f64; 3], unit: &str| {
            v.iter()
                .enumerate()
                .find(|(_, c)| !c.is_finite())
                .map(|(k, c)| format!("{field}[{k}] is {c}, not a finite number ({unit})"))
        };
        let scalar = |field: &str, v: f64, unit: &str| {
            (!v.is_finite()).then(|| format!("{field} is {v}, not a finite number ({unit})"))
        };
        let not_finite = vector("translation_m", &self.translation_m, "m")
            .or_else(|| vector("velocity_mps", &self.velocity_mps, "m/s"))
            .or_else(|| scalar("yaw_rad", self.yaw_rad, "rad"))
            .or_else(|| scalar("yaw_rate_radps", self.yaw_rate_radps, "rad/s"));
        if let Some(message) = not_finite {
            return bad(message);
        }
        let norm = |v: &[f64; 3]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm(&self.translation_m) > MAX_FRAME_OFFSET_M {
            return bad(format!(
                "translation_m is more than {MAX_FRAME_OFFSET_M} m from the parent"
            ));
        }
        if norm(&self.velocity_mps) > MAX_FRAME_SPEED_MPS {
            return bad(format!(
                "velocity_mps is faster than {MAX_FRAME_SPEED_MPS} m/s"
            ));
        }
        if self.yaw_rate_radps.abs() > MAX_FRAME_YAW_RATE_RADPS {
            return bad(format!(
                "yaw_rate_radps is faster than {MAX_FRAME_YAW_RATE_RADPS} rad/s"
            ));
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

impl Host {
    fn ids(&self) -> String {
        self.drone_ids().join(", ")
    }

    /// The drone a command is for: by name, or the only one when absent.
    pub(super) fn route(&self, drone: Option<&str>) -> Result<usize, HostError> {
        match drone {
            Some(d) => self
                .cores
                .iter()
                .position(|c| c.drone_id() == d)
                .ok_or_else(|| match self.remote_node_of(d) {
                    Some(node) => HostError::RemoteDrone {
                        drone: d.to_string(),
                        node: node.to_string(),
                    },
                    None => HostError::UnknownDrone(d.to_string(), self.ids()),
                }),
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
        self.load_valid(i, target, mission.clone(), valid, mission_id)
    }

    /// The validation context of drone `target` (the first drone when the mission names none:
    /// the API then reports every problem along with the missing target), so that an upload
    /// is validated off the control loop.
    pub fn upload_context(
        &self,
        target: Option<&str>,
    ) -> Result<(usize, ContextSnapshot), HostError> {
        let i = match target {
            None => 0,
            Some(t) => self.route(Some(t)).map_err(|e| {
                HostError::Invalid(vec![ValidationError {
                    pointer: "/target".into(),
                    message: e.to_string(),
                }])
            })?,
        };
        let ctx = self
            .validation_context(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), self.ids()))?;
        Ok((i, ContextSnapshot::of(&ctx)))
    }

    /// Loads a mission validated off the loop with `snapshot`; validated again here only if
    /// the drone's frames, home or limits changed since.
    pub fn upload_validated(&mut self, upload: ValidatedUpload) -> Result<Uploaded, HostError> {
        let ValidatedUpload {
            drone: i,
            mission,
            valid,
            snapshot,
            mission_id,
        } = upload;
        let holds = self
            .validation_context(i)
            .is_some_and(|ctx| snapshot.still_holds(&ctx));
        let valid = if holds {
            valid
        } else {
            self.validate(i, &mission)?
        };
        self.load_valid(i, snapshot.drone_id, mission, valid, mission_id)
    }

    /// Loads a validated mission for drone `i` (named `target`).
    fn load_valid(
        &mut self,
        i: usize,
        target: String,
        mission: Value,
        valid: crate::mission::ValidMission,
        mission_id: Option<u32>,
    ) -> Result<Uploaded, HostError> {
        let warnings = valid.warnings.clone();
        for w in &warnings {
            tracing::warn!("mission for {target}: {w}");
        }
        let now = self.now;
        let (Some(ex), Some(core)) = (self.executors.get_mut(i), self.cores.get_mut(i)) else {
            return Err(HostError::UnknownDrone(target, String::new()));
        };
        let id = match mission_id {
            None => ex.load_new(valid)?,
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
        self.log_command(i, "upload", json!({ "mission_id": id, "mission": mission }));
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
            json!({ "action": update.action, "mission_id": update.mission_id, "item_id": update.item_id, "accepted": accepted, "reason": reason, "mission": update.mission }),
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
        // EXECUTE only: a landing mission LOADed for later is not a landing now.
        if let (Action::Execute, Some(m)) = (req.action, &req.mission) {
            self.refuse_landing_on_ground(i, m)?;
        }
        for w in req.mission.iter().flat_map(|m| &m.warnings) {
            let drone = self.cores.get(i).map(|c| c.drone_id()).unwrap_or_default();
            tracing::warn!("{} for {drone}: {w}", update.action);
        }
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

    /// Refuses to EXECUTE a mission whose first item is `land` (the page's LAND) on drone `i`
    /// when it is on the ground and disarmed (with its link up: otherwise its state is not
    /// known). It could not start, and EXECUTE would have stored it all the same.
    fn refuse_landing_on_ground(&self, i: usize, mission: &ValidMission) -> Result<(), HostError> {
        let Some(core) = self.cores.get(i) else {
            return Ok(());
        };
        let platform = core.platform_status();
        let lands_first = mission
            .items
            .first()
            .is_some_and(|p| p.item.behavior == "land");
        let on_ground =
            platform.link == LinkHealth::Ok && !platform.armed && !platform.flight.is_airborne();
        if lands_first && on_ground {
            return Err(HostError::AlreadyLanded(core.drone_id().to_string()));
        }
        Ok(())
    }

    fn log_command(&mut self, i: usize, command: &str, fields: Value) {
        if let (Some(log), Some(core)) = (self.log.as_mut(), self.cores.get(i)) {
            log.command(self.now, core.drone_id(), command, fields);
        }
    }

    /// The missions of `drone` (or of all drones), only mission `only` when given; the plan
    /// (a copy of every item) only with `with_plan`, so a list stays cheap on the loop.
    fn views(
        &self,
        drone: Option<&str>,
        only: Option<u32>,
        with_plan: bool,
    ) -> Result<Vec<MissionView>, HostError> {
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
                if only.is_some_and(|o| o != *id) {
                    continue;
                }
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
        let mut matching = self.views(drone, Some(id), true)?;
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

    /// Registers or updates a frame in every drone (or the one it names); all or none. A loaded
    /// mission that the new frame would make invalid (a goal beyond the geofence, a frame cycle)
    /// refuses the change, with that mission's errors.
    pub fn set_frame(&mut self, frame: FrameRegistration) -> Result<(), HostError> {
        frame.check()?;
        let known = self
            .frames
            .iter()
            .any(|f| f.frame_id == frame.frame_id && f.drone_id == frame.drone_id);
        if !known && self.frames.len() >= MAX_FRAMES {
            return Err(HostError::Frame(format!(
                "{}: {MAX_FRAMES} frames are registered already; replace one",
                frame.frame_id
            )));
        }
        let targets: Vec<usize> = match &frame.drone_id {
            Some(d) => vec![self.route(Some(d))?],
            None => (0..self.cores.len()).collect(),
        };
        let motion = frame.motion(self.now);
        for &i in &targets {
            if let Some(core) = self.cores.get(i) {
                let mut trial = core.frames().clone();
                trial.set(&frame.frame_id, &frame.parent, motion)?;
                self.recheck_missions(i, &frame.frame_id, &trial)?;
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

    /// Validates again, against `frames`, every mission of drone `i` with a goal in `frame_id`.
    fn recheck_missions(
        &self,
        i: usize,
        frame_id: &str,
        frames: &crate::estimator::frames::FrameTree,
    ) -> Result<(), HostError> {
        let (Some(ctx), Some(ex)) = (self.validation_context(i), self.executors.get(i)) else {
            return Ok(());
        };
        let ctx = ValidationContext { frames, ..ctx };
        for (id, loaded) in ex.missions() {
            let uses = loaded.mission.items.iter().any(|item| {
                item.parsed
                    .as_ref()
                    .is_some_and(|g| g.summary().targets.iter().any(|t| t.frame_id == frame_id))
                    || item.goal.get("frame_id").and_then(Value::as_str) == Some(frame_id)
            });
            if !uses {
                continue;
            }
            let written = serde_json::to_value(loaded.mission.as_written()).unwrap_or_default();
            if let Err(errors) = crate::mission::validate::validate_value(&written, &ctx) {
                let first: Vec<String> = errors.iter().take(3).map(ToString::to_string).collect();
                return Err(HostError::Frame(format!(
                    "{frame_id}: loaded mission {id} would no longer be valid: {}",
                    first.join("; ")
                )));
            }
        }
        Ok(())
    }

    /// Simulator fault injection: cut (`true`) or restore drone `i`'s link.
    pub fn set_link_lost(&mut self, i: usize, lost: bool) -> Result<(), HostError> {
        self.fleet
            .set_link_lost(i, lost)
            .map_err(HostError::NotSupported)
    }

    /// Answers a command that may have changed what is saved: the change is handed to the
    /// store first, so by the time the API has the answer, `Sink::saved` covers it.
    fn answer<T>(&mut self, reply: Reply<T>, answer: Result<T, HostError>) {
        self.commit();
        let _ = reply.send(answer);
    }

    /// Carries out one command and answers it.
    pub fn handle(&mut self, command: Command) {
        // A client that gave up waiting dropped its receiver; nothing to answer then.
        match command {
            Command::UploadContext { target, reply } => {
                let _ = reply.send(self.upload_context(target.as_deref()));
            }
            Command::UploadValidated { upload, reply } => {
                let answer = self.upload_validated(*upload);
                self.answer(reply, answer);
            }
            Command::Update { update, reply } => {
                let answer = self.update(&update);
                self.answer(reply, answer);
            }
            Command::Delete {
                drone,
                mission_id,
                reply,
            } => {
                let answer = self.delete(drone.as_deref(), mission_id);
                self.answer(reply, answer);
            }
            Command::Missions { drone, reply } => {
                let _ = reply.send(self.views(drone.as_deref(), None, false));
            }
            Command::Mission {
                drone,
                mission_id,
                reply,
            } => {
                let _ = reply.send(self.mission_view(drone.as_deref(), mission_id));
            }
            Command::SetFrame { frame, reply } => {
                let answer = self.set_frame(frame);
                self.answer(reply, answer);
            }
            Command::Frames { reply } => {
                let _ = reply.send(Ok(self.frames.clone()));
            }
            Command::Fault {
                drone_id,
                link_lost,
                reply,
            } => {
                let result = self
                    .route(Some(&drone_id))
                    .and_then(|i| self.set_link_lost(i, link_lost));
                let _ = reply.send(result);
            }
            Command::FlushLog { reply } => {
                self.flush_log();
                let _ = reply.send(Ok(()));
            }
            Command::Map { drone, reply } => {
                let _ = reply.send(self.map_view(drone.as_deref()));
            }
            Command::Exploration { reply } => {
                let _ = reply.send(Ok(self.exploration_view()));
            }
            Command::ExplorationStart {
                drones,
                args,
                reply,
            } => {
                let answer = self.start_exploration(&drones, &args);
                self.answer(reply, answer);
            }
            Command::ExplorationStop { drones, reply } => {
                let answer = self.stop_exploration(&drones);
                self.answer(reply, answer);
            }
            Command::ExplorationReport { reply } => {
                let _ = reply.send(self.exploration_report());
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
