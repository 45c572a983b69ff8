//! The host's missions: what a mission is validated against, loading, MissionUpdates, the list
//! and one mission as the API shows them, deleting.
//!
//! Every mission is loaded one way, [`Host::load_mission`] (validated on the loop) or, through
//! the handle, `HostHandle::load_mission` (validated off the loop, then
//! [`Host::load_validated`]): both end in the same checks and the same load. The API's upload,
//! the CLI's mission files and scenarios, the demo flight and exploration starts all use it.
//!
//! In: a mission (JSON) or a MissionUpdate for a drone, by name. Out: the executors changed, the
//! answer ([`Uploaded`], [`Updated`], [`MissionView`]s) or a [`HostError`], and a flight-log
//! record of each command.

use super::{Host, HostError};
use crate::host::status::EventBody;
use crate::mission::executor::Progress;
use crate::mission::{
    Action, ActionError, ContextSnapshot, ExecState, Mission, MissionStatus, MissionUpdate,
    Request, ValidMission, ValidationContext, ValidationError,
};
use crate::types::LinkHealth;
use crate::types::Vec3;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

/// How a mission is loaded.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct LoadOptions {
    /// Under this id, replacing the idle mission that has it; `None`: under a new id.
    pub mission_id: Option<u32>,
    /// Started at once, as EXECUTE does (with EXECUTE's refusals and its one exception: a
    /// first item whose behavior refuses its goal leaves the mission loaded, the failure in
    /// its status); `false`: only loaded, as LOAD does.
    pub start: bool,
}

impl LoadOptions {
    /// Loaded under a new id and started at once.
    pub fn start() -> Self {
        Self {
            mission_id: None,
            start: true,
        }
    }
}

/// A mission validated off the control loop, with what it was validated against.
#[derive(Debug)]
pub struct ValidatedUpload {
    pub drone: usize,
    pub mission: Value,
    pub valid: crate::mission::ValidMission,
    pub snapshot: ContextSnapshot,
    pub options: LoadOptions,
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

    pub(super) fn validation_context(&self, i: usize) -> Option<ValidationContext<'_>> {
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
            limits: self.executors.limits(),
            frames: core.frames(),
            now: self.now,
            home_enu_m: home,
            geo_origin: core.geo_origin(),
            lowest_height: core.lowest_flight_height_m(),
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

    /// Validates a mission and loads it for the drone its target names: the one way a mission
    /// is loaded on the loop (the handle's way validates off it and ends in
    /// [`Host::load_validated`]).
    pub fn load_mission(
        &mut self,
        mission: &Value,
        options: LoadOptions,
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
        let i = self.route_target(&target)?;
        let valid = self.validate(i, mission)?;
        self.load_valid(i, target, mission.clone(), valid, options)
    }

    /// The drone a mission's `target` names. A drone this Kestrel does not know is an error of
    /// the mission (`/target`); one that another Kestrel of the fleet flies is not: the mission
    /// may be fine, it is only sent to the wrong Kestrel (`remote_drone`, naming its node).
    fn route_target(&self, target: &str) -> Result<usize, HostError> {
        self.route(Some(target)).map_err(|e| match e {
            HostError::RemoteDrone { .. } => e,
            other => HostError::Invalid(vec![ValidationError {
                pointer: "/target".into(),
                message: other.to_string(),
            }]),
        })
    }

    /// The validation context of drone `target` (the first drone when the mission names none:
    /// validation then reports every problem along with the missing target), so that a
    /// mission is validated off the control loop.
    pub fn load_context(
        &self,
        target: Option<&str>,
    ) -> Result<(usize, ContextSnapshot), HostError> {
        let i = match target {
            None => 0,
            Some(t) => self.route_target(t)?,
        };
        let ctx = self
            .validation_context(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), self.ids()))?;
        Ok((i, ContextSnapshot::of(&ctx)))
    }

    /// Loads a mission validated off the loop with `snapshot`; validated again here only if
    /// the drone's frames, home or limits changed since.
    pub fn load_validated(&mut self, upload: ValidatedUpload) -> Result<Uploaded, HostError> {
        let ValidatedUpload {
            drone: i,
            mission,
            valid,
            snapshot,
            options,
        } = upload;
        let holds = self
            .validation_context(i)
            .is_some_and(|ctx| snapshot.still_holds(&ctx));
        let valid = if holds {
            valid
        } else {
            self.validate(i, &mission)?
        };
        self.load_valid(i, snapshot.drone_id, mission, valid, options)
    }

    /// Loads a validated mission for drone `i` (named `target`), and starts it with
    /// `options.start` (as EXECUTE, with its checks: the fleet joined, not a landing on the
    /// ground).
    fn load_valid(
        &mut self,
        i: usize,
        target: String,
        mission: Value,
        valid: crate::mission::ValidMission,
        options: LoadOptions,
    ) -> Result<Uploaded, HostError> {
        if options.start {
            self.refuse_before_joining(i)?;
            self.refuse_landing_on_ground(i, &valid)?;
        }
        let warnings = valid.warnings.clone();
        for w in &warnings {
            tracing::warn!("mission for {target}: {w}");
        }
        let now = self.now;
        let (Some(ex), Some(core)) = (self.executors.get_mut(i), self.cores.get_mut(i)) else {
            return Err(HostError::UnknownDrone(target, String::new()));
        };
        let id = match (options.mission_id, options.start) {
            (None, false) => ex.load_new(valid)?,
            (mission_id, start) => {
                let req = Request {
                    action: if start { Action::Execute } else { Action::Load },
                    mission_id,
                    item_id: None,
                    mission: Some(valid),
                };
                let status = ex.apply(req, core, now)?;
                // EXECUTE under a new id: the mission it started is the one running.
                match mission_id.or(status.mission_id) {
                    Some(id) => id,
                    None => return Err(ActionError::Refused("the mission got no id".into()).into()),
                }
            }
        };
        self.log_command(
            i,
            "upload",
            json!({ "mission_id": id, "start": options.start, "mission": mission }),
        );
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
        if matches!(req.action, Action::Execute | Action::Start | Action::Resume) {
            self.refuse_before_joining(i)?;
        }
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
            .is_some_and(|p| p.behavior() == "land");
        let on_ground =
            platform.link == LinkHealth::Ok && !platform.armed && !platform.flight.is_airborne();
        if lands_first && on_ground {
            return Err(HostError::AlreadyLanded(core.drone_id().to_string()));
        }
        Ok(())
    }

    fn log_command(&mut self, i: usize, command: &str, fields: Value) {
        if let Some(core) = self.cores.get(i) {
            self.log.command(self.now, core.drone_id(), command, fields);
        }
    }

    /// The missions of `drone` (or of all drones), only mission `only` when given; the plan
    /// (a copy of every item) only with `with_plan`, so a list stays cheap on the loop.
    pub(super) fn views(
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
                    plan: with_plan
                        .then(|| loaded.mission.as_written())
                        .transpose()
                        .map_err(|e| HostError::Unavailable(format!("mission {id}: {e}")))?,
                    progress: with_plan.then(|| progress_json(&loaded.progress)),
                });
            }
        }
        Ok(out)
    }

    pub(super) fn mission_view(
        &self,
        drone: Option<&str>,
        id: u32,
    ) -> Result<MissionView, HostError> {
        let mut matching = self.views(drone, Some(id), true)?;
        match matching.len() {
            0 => Err(ActionError::UnknownMission(id).into()),
            1 => Ok(matching.remove(0)),
            _ => Err(HostError::DroneNeeded(self.ids())),
        }
    }

    pub(super) fn delete(&mut self, drone: Option<&str>, id: u32) -> Result<(), HostError> {
        let i = match drone {
            Some(d) => self.route(Some(d))?,
            None => match self.executors.holders(id).as_slice() {
                [] => return Err(ActionError::UnknownMission(id).into()),
                [one] => *one,
                _ => return Err(HostError::DroneNeeded(self.ids())),
            },
        };
        let ex = self
            .executors
            .get_mut(i)
            .ok_or_else(|| HostError::UnknownDrone(i.to_string(), String::new()))?;
        ex.unload(id)?;
        Ok(())
    }
}

fn progress_json(p: &Progress) -> Value {
    json!({ "cursor": p.cursor, "done_results": p.done, "finished": p.finished })
}
