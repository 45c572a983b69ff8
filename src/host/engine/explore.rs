//! Explorations for chosen drones in one command: each drone gets a one-item mission running the
//! `explore` behavior, loaded as every mission is ([`Host::load_mission`]) and started by a
//! START MissionUpdate (same validation, same errors), and joins the host's exploration run;
//! stop sends STOP to those missions. The run's progress and report are read from here.
//!
//! In: drone ids and the `explore` goal's arguments; ticks (poses, the merged map). Out: the
//! missions started or stopped, [`ProgressView`], [`ReportInput`]. All or nothing: every drone
//! and the goal are checked before anything is loaded, and a drone that fails to start takes
//! back the ones started before it.

use super::{Host, HostError, LoadOptions};
use crate::exploration::offline::evaluate::{PoseSample, TrueWorld};
use crate::exploration::online::progress::{
    DronePose, LiveReport, ProgressView, RunDrone, RunDroneView,
};
use crate::mission::{Action, ActionError, ExecState, MissionUpdate, ValidationError};
use serde::Serialize;
use serde_json::{json, Value};
use std::sync::Arc;
use std::time::Duration;

/// One drone an exploration started.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct StartedDrone {
    pub drone: String,
    /// Its exploration mission (`GET /api/missions/{id}`).
    pub mission_id: u32,
}

/// The answer to an exploration start.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ExplorationStarted {
    /// Host time the run started (s); an earlier one when the drones joined a running one.
    pub started_at_s: f64,
    pub drones: Vec<StartedDrone>,
}

/// What the report is made of, handed to the API (the evaluator runs there, off the loop).
#[derive(Debug, Clone)]
pub struct ReportInput {
    pub live: LiveReport,
    /// The simulator's true world, or the virtual world of real vehicles; `None` on real
    /// vehicles in the real world.
    pub world: Option<TrueWorld>,
    /// The run's pose samples in order, in shared chunks.
    pub samples: Vec<Arc<[PoseSample]>>,
}

/// Mission validation points into `/plan/0/args/..`; the request has them at `/args/..`.
fn request_pointer(pointer: &str) -> String {
    match pointer.strip_prefix("/plan/0") {
        Some(rest) if rest.starts_with("/args") => rest.to_string(),
        Some(_) => "/args".to_string(),
        None => pointer.to_string(),
    }
}

fn invalid(pointer: &str, message: String) -> HostError {
    HostError::Invalid(vec![ValidationError {
        pointer: pointer.into(),
        message,
    }])
}

impl Host {
    /// Indices of `drones`, each known, named once, at least one.
    fn explore_targets(&self, drones: &[String]) -> Result<Vec<usize>, HostError> {
        if drones.is_empty() {
            return Err(invalid("/drones", "name at least one drone".into()));
        }
        let mut out = Vec::new();
        for (k, d) in drones.iter().enumerate() {
            if drones.iter().take(k).any(|x| x == d) {
                return Err(invalid(
                    &format!("/drones/{k}"),
                    format!("{d} is named twice"),
                ));
            }
            out.push(self.route(Some(d))?);
        }
        Ok(out)
    }

    /// The run's mission of drone `drone` while it runs or is paused.
    fn exploring(&self, i: usize, drone: &str) -> Option<u32> {
        let mission_id = self.exploration.mission_of(drone)?;
        self.executors
            .is_running(i, mission_id)
            .then_some(mission_id)
    }

    /// Starts the `explore` behavior with `args` on every drone of `drones`.
    pub fn start_exploration(
        &mut self,
        drones: &[String],
        args: &Value,
    ) -> Result<ExplorationStarted, HostError> {
        if !args.is_object() {
            return Err(invalid("/args", "args must be a JSON object".into()));
        }
        let targets = self.explore_targets(drones)?;
        for &i in &targets {
            self.refuse_before_joining(i)?;
        }
        let mut missions = Vec::new();
        let mut errors: Vec<ValidationError> = Vec::new();
        for (&i, d) in targets.iter().zip(drones) {
            if self.exploring(i, d).is_some() {
                return Err(ActionError::Refused(format!(
                    "{d} is exploring already; stop it first"
                ))
                .into());
            }
            let mission = json!({ "target": d, "plan": [{ "behavior": "explore", "args": args }] });
            match self.validate(i, &mission) {
                Ok(_) => {}
                Err(HostError::Invalid(found)) => {
                    for e in found {
                        let e = ValidationError {
                            pointer: request_pointer(&e.pointer),
                            message: e.message,
                        };
                        if !errors.contains(&e) {
                            errors.push(e);
                        }
                    }
                }
                Err(other) => return Err(other),
            }
            missions.push(mission);
        }
        if !errors.is_empty() {
            return Err(HostError::Invalid(errors));
        }
        let mut started: Vec<(String, u32)> = Vec::new();
        for (mission, d) in missions.iter().zip(drones) {
            if let Err(e) = self.start_one(mission, d, &mut started) {
                for (d, id) in &started {
                    self.mission_action(d, *id, Action::Reset);
                }
                return Err(e);
            }
        }
        let run = self.exploration.start(self.now, started.clone());
        Ok(ExplorationStarted {
            started_at_s: run.started_at().as_secs_f64(),
            drones: started
                .into_iter()
                .map(|(drone, mission_id)| StartedDrone { drone, mission_id })
                .collect(),
        })
    }

    /// Loads and starts one drone's mission; on success it is added to `started`.
    fn start_one(
        &mut self,
        mission: &Value,
        drone: &str,
        started: &mut Vec<(String, u32)>,
    ) -> Result<(), HostError> {
        let up = self.load_mission(mission, LoadOptions::default())?;
        let update = MissionUpdate {
            drone_id: Some(drone.to_string()),
            mission_id: Some(i64::from(up.mission_id)),
            item_id: None,
            action: Action::Start,
            mission: None,
        };
        if let Err(e) = self.update(&update) {
            self.mission_action(drone, up.mission_id, Action::Reset);
            return Err(e);
        }
        started.push((drone.to_string(), up.mission_id));
        Ok(())
    }

    /// A MissionUpdate without a mission, whose refusal is already logged and evented.
    fn mission_action(&mut self, drone: &str, mission_id: u32, action: Action) {
        let update = MissionUpdate {
            drone_id: Some(drone.to_string()),
            mission_id: Some(i64::from(mission_id)),
            item_id: None,
            action,
            mission: None,
        };
        if let Err(e) = self.update(&update) {
            tracing::warn!(
                "{drone}: {} of exploration mission {mission_id}: {e}",
                action.name()
            );
        }
    }

    /// Stops the exploration missions of `drones` (the vehicles hold where they are); every
    /// drone must be exploring, or nothing is stopped.
    pub fn stop_exploration(&mut self, drones: &[String]) -> Result<Vec<String>, HostError> {
        let targets = self.explore_targets(drones)?;
        let mut missions = Vec::new();
        for (&i, d) in targets.iter().zip(drones) {
            let id = self
                .exploring(i, d)
                .ok_or_else(|| ActionError::Refused(format!("{d} is not exploring")))?;
            missions.push(id);
        }
        for (d, id) in drones.iter().zip(missions) {
            self.mission_action(d, id, Action::Stop);
            self.exploration.stop(d);
        }
        Ok(drones.to_vec())
    }

    /// One tick of the run: poses and the known area recorded; finished once no drone of it
    /// runs its mission any more.
    pub(super) fn record_exploration(&mut self, now: Duration) {
        let (cores, executors, map) = (&self.cores, &self.executors, self.map.as_ref());
        let poses = || {
            cores
                .iter()
                .map(|c| DronePose {
                    drone: c.drone_id(),
                    position_enu_m: c.estimate().pose.position_m,
                    yaw_rad: c.estimate().pose.yaw_rad(),
                    airborne: c.platform_status().armed && c.platform_status().flight.is_airborne(),
                })
                .collect()
        };
        let running = |d: &RunDrone| {
            cores
                .iter()
                .enumerate()
                .any(|(i, c)| c.drone_id() == d.drone && executors.is_running(i, d.mission_id))
        };
        let known_pct = || map.map(|m| super::known_pct(m.merged()));
        self.exploration.record(now, known_pct, poses, running);
    }

    /// How one drone of the run is doing.
    fn run_drone_view(&self, d: &RunDrone) -> RunDroneView {
        let i = self.cores.iter().position(|c| c.drone_id() == d.drone);
        let pair = i.and_then(|i| Some((self.cores.get(i)?, self.executors.get(i)?)));
        let running = pair.is_some_and(|(_, ex)| ex.running_id() == Some(d.mission_id));
        let phase = match pair {
            Some((_, ex)) if running && ex.state() == ExecState::Paused => "paused".to_string(),
            Some((core, _)) if running => core
                .server()
                .active()
                .iter()
                .find(|a| a.behavior == "explore")
                .and_then(|a| a.feedback.get("phase").and_then(Value::as_str))
                .unwrap_or("starting")
                .to_string(),
            Some((_, ex)) => ex
                .missions()
                .get(&d.mission_id)
                .and_then(|m| m.progress.done.last())
                .and_then(|r| serde_json::to_value(r.result).ok())
                .and_then(|v| v.as_str().map(str::to_string))
                .unwrap_or_else(|| "stopped".to_string()),
            None => "stopped".to_string(),
        };
        let goal_enu_m = running
            .then(|| self.exploration.claim_of(&d.drone))
            .flatten();
        RunDroneView {
            drone: d.drone.clone(),
            mission_id: d.mission_id,
            phase,
            goal_enu_m,
            path_m: d.path_m,
        }
    }

    /// The run's progress, `None` before any exploration was started.
    pub fn exploration_progress(&self) -> Option<ProgressView> {
        let run = self.exploration.run()?;
        let drones = run
            .drones()
            .iter()
            .map(|d| self.run_drone_view(d))
            .collect();
        Some(ProgressView::of(run, self.now, drones))
    }

    /// Judges explorations against `world`: the simulator's, or the virtual world real vehicles
    /// fly in with virtual range sensors. Their reports get the evaluator's metrics.
    pub fn set_true_world(&mut self, world: TrueWorld) {
        self.exploration.set_truth(world);
    }

    /// What the report needs; `not_found`-like `NotSupported` before any exploration.
    pub fn exploration_report(&self) -> Result<ReportInput, HostError> {
        let known_pct = || self.map.as_ref().map(|m| super::known_pct(m.merged()));
        self.exploration_progress()
            .and_then(|progress| self.exploration.report(progress, known_pct))
            .ok_or_else(|| {
                HostError::NotSupported(
                    "no exploration was started: POST /api/exploration/start first".into(),
                )
            })
    }
}

#[cfg(test)]
mod tests {
    use super::request_pointer;

    #[test]
    fn goal_errors_point_into_the_request() {
        assert_eq!(request_pointer("/plan/0/args/speed"), "/args/speed");
        assert_eq!(request_pointer("/plan/0"), "/args");
        assert_eq!(request_pointer("/target"), "/target");
    }
}
