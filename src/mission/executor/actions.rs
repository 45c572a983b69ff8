//! The MissionUpdate actions: what each does in each executor state (the table in
//! `docs/API.md`, "Mission actions"). Every refusal leaves the executor as it was.

use super::{Loaded, MissionExecutor, Progress, Run};
use crate::core::{BehaviorCommand, DroneCore};
use crate::mission::model::{Action, MissionStatus, ValidMission};
use crate::mission::validate::{validate_value, ValidationContext, ValidationError};
use crate::mission::MissionUpdate;
use std::time::Duration;

/// Why an action was not applied. Nothing changed when one of these is returned.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum ActionError {
    #[error("mission is invalid: {}", summary(.0))]
    Invalid(Vec<ValidationError>),
    #[error("unknown mission {0}")]
    UnknownMission(u32),
    #[error("{0}")]
    Refused(String),
}

fn summary(errors: &[ValidationError]) -> String {
    let first: Vec<String> = errors.iter().take(3).map(ToString::to_string).collect();
    let more = errors.len().saturating_sub(3);
    if more > 0 {
        format!("{} (and {more} more)", first.join("; "))
    } else {
        first.join("; ")
    }
}

pub(super) fn refused(reason: impl Into<String>) -> ActionError {
    ActionError::Refused(reason.into())
}

/// A MissionUpdate whose mission (if any) passed validation.
#[derive(Debug, Clone, PartialEq)]
pub struct Request {
    pub action: Action,
    pub mission_id: Option<u32>,
    pub item_id: Option<i64>,
    pub mission: Option<ValidMission>,
}

impl Request {
    /// Checks the fields an action needs and validates its mission.
    pub fn prepare(update: &MissionUpdate, ctx: &ValidationContext) -> Result<Self, ActionError> {
        let mission_id = match update.mission_id {
            None => None,
            Some(n) => Some(u32::try_from(n).map_err(|_| {
                refused(format!(
                    "mission_id must be between 0 and {}, got {n}",
                    u32::MAX
                ))
            })?),
        };
        let needs_mission = matches!(
            update.action,
            Action::Execute | Action::Load | Action::Insert | Action::Modify
        );
        let mission = match (&update.mission, needs_mission) {
            (None, true) => {
                return Err(refused(format!(
                    "{} needs a mission (its items)",
                    update.action
                )))
            }
            (Some(m), true) => Some(validate_value(m, ctx).map_err(ActionError::Invalid)?),
            (_, false) => None,
        };
        if update.action == Action::Modify {
            let n = mission.as_ref().map_or(0, |m| m.items.len());
            if n != 1 {
                return Err(refused(format!(
                    "MODIFY takes a mission with exactly one item (the new item), got {n}"
                )));
            }
        }
        Ok(Self {
            action: update.action,
            mission_id,
            item_id: update.item_id,
            mission,
        })
    }
}

impl MissionExecutor {
    /// Applies one action. On `Err` nothing changed, with one exception: when START or
    /// EXECUTE is refused because the first item's behavior refused its goal, that failure is
    /// recorded in the status (and EXECUTE's mission stays loaded).
    pub fn apply(
        &mut self,
        req: Request,
        core: &mut DroneCore,
        now: Duration,
    ) -> Result<MissionStatus, ActionError> {
        if matches!(req.action, Action::Execute | Action::Load) {
            self.check_room(req.mission_id)?;
        }
        let id = match (req.action, req.mission_id) {
            (_, Some(id)) => id,
            (Action::Execute | Action::Load, None) => self.fresh_id(),
            (_, None) => self
                .running_id()
                .or(self.shown)
                .ok_or_else(|| refused("no mission is loaded"))?,
        };
        match req.action {
            Action::Execute => {
                let mission = req
                    .mission
                    .ok_or_else(|| refused("EXECUTE needs a mission"))?;
                self.check_replaceable(id)?;
                self.check_startable(id, 0, Some(mission.items.len()))?;
                self.store(id, mission);
                self.start(id, 0, core, now)?;
            }
            Action::Load => {
                let mission = req.mission.ok_or_else(|| refused("LOAD needs a mission"))?;
                self.check_replaceable(id)?;
                self.store(id, mission);
            }
            Action::Start => {
                let index = self.index_in(id, req.item_id.unwrap_or(0))?;
                self.check_startable(id, index, None)?;
                self.start(id, index, core, now)?;
            }
            Action::Pause => self.pause(id, core)?,
            Action::Resume => self.resume(id, core, now)?,
            Action::Stop => self.stop(id, core)?,
            Action::NextItem => {
                self.active_run(id)?;
                self.leave_current(core, "skipped by NEXT_ITEM");
                self.with_progress(id, |p| p.cursor += 1);
                self.advance(core, now);
            }
            Action::JumpTo => {
                self.active_run(id)?;
                let raw = req
                    .item_id
                    .ok_or_else(|| refused("JUMP_TO needs item_id"))?;
                let index = self.index_in(id, raw)?;
                self.leave_current(core, &format!("left by JUMP_TO {index}"));
                self.with_progress(id, |p| p.cursor = index);
                self.advance(core, now);
            }
            Action::Insert => {
                let mission = req.mission.ok_or_else(|| refused("INSERT needs items"))?;
                self.insert(id, req.item_id, mission)?;
            }
            Action::Modify => {
                let mission = req.mission.ok_or_else(|| refused("MODIFY needs an item"))?;
                self.modify(id, req.item_id, mission, core)?;
            }
            Action::Remove => self.remove(id, req.item_id)?,
            Action::Reset => {
                if !self.missions.contains_key(&id) {
                    return Err(ActionError::UnknownMission(id));
                }
                if self.running_id() == Some(id) {
                    self.end_run(core, "unloaded by RESET", None);
                }
                self.missions.remove(&id);
                if self.shown == Some(id) {
                    self.shown = None;
                }
            }
        }
        // Whatever the action did, it did it to mission `id`.
        self.mark(id);
        self.touch();
        Ok(self.status(core))
    }

    fn loaded(&self, id: u32) -> Result<&Loaded, ActionError> {
        self.missions
            .get(&id)
            .ok_or(ActionError::UnknownMission(id))
    }

    /// `raw` as an index of an existing item of mission `id`.
    fn index_in(&self, id: u32, raw: i64) -> Result<usize, ActionError> {
        let len = self.loaded(id)?.mission.items.len();
        usize::try_from(raw)
            .ok()
            .filter(|i| *i < len)
            .ok_or_else(|| {
                refused(format!(
                    "item_id {raw} is out of range: mission {id} has items 0..={}",
                    len.saturating_sub(1)
                ))
            })
    }

    fn check_replaceable(&self, id: u32) -> Result<(), ActionError> {
        if self.running_id() == Some(id) {
            return Err(refused(format!(
                "mission {id} is running: STOP it before replacing it (or use INSERT, MODIFY, REMOVE)"
            )));
        }
        Ok(())
    }

    /// START is refused for the mission already running or paused.
    fn check_startable(
        &self,
        id: u32,
        index: usize,
        len: Option<usize>,
    ) -> Result<(), ActionError> {
        if let Some(run) = &self.run {
            if run.mission_id == id {
                return Err(refused(if run.paused {
                    format!("mission {id} is paused: RESUME it, or STOP it and START again")
                } else {
                    format!("mission {id} is already running: use JUMP_TO to move within it")
                }));
            }
        }
        if let Some(len) = len {
            if index >= len {
                return Err(refused(format!("item_id {index} is out of range")));
            }
        }
        Ok(())
    }

    /// Starts mission `id` at `index`; a running mission is stopped first and the vehicle
    /// holds for the switch time.
    fn start(
        &mut self,
        id: u32,
        index: usize,
        core: &mut DroneCore,
        now: Duration,
    ) -> Result<(), ActionError> {
        let start_at = match self.run.as_ref().map(|r| r.mission_id) {
            Some(old) => {
                self.end_run(core, &format!("switched to mission {id}"), None);
                tracing::info!("mission {old} stopped: switching to mission {id}");
                Some(now + self.config.switch_hold)
            }
            None => None,
        };
        self.with_progress(id, |p| {
            *p = Progress {
                cursor: index,
                ..Progress::default()
            }
        });
        self.last_error = None;
        self.last_error_code = None;
        self.shown = Some(id);
        self.run = Some(Run {
            mission_id: id,
            paused: false,
            current: None,
            parallel: Vec::new(),
            start_at,
            link_wait: None,
        });
        self.advance(core, now);
        if self.run.is_none() {
            if let Some(e) = &self.last_error {
                self.failed_in_flight = None;
                return Err(refused(e.clone()));
            }
        }
        Ok(())
    }

    /// The running or paused run of mission `id`, or why there is none.
    fn active_run(&self, id: u32) -> Result<&Run, ActionError> {
        self.loaded(id)?;
        match &self.run {
            None => Err(refused(format!(
                "no mission is running (mission {id} is idle)"
            ))),
            Some(r) if r.mission_id != id => Err(refused(format!(
                "mission {id} is not running; mission {} is",
                r.mission_id
            ))),
            Some(r) => Ok(r),
        }
    }

    fn pause(&mut self, id: u32, core: &mut DroneCore) -> Result<(), ActionError> {
        let run = self.active_run(id)?;
        if run.paused {
            return Err(refused(format!("mission {id} is already paused")));
        }
        for b in Self::behavior_ids(run) {
            // A behavior that ended this tick cannot pause; its result arrives next tick.
            let _ = core.command(BehaviorCommand::Pause(b));
        }
        if let Some(r) = self.run.as_mut() {
            r.paused = true;
        }
        Ok(())
    }

    fn resume(&mut self, id: u32, core: &mut DroneCore, now: Duration) -> Result<(), ActionError> {
        let run = self.active_run(id)?;
        if !run.paused {
            return Err(refused(format!("mission {id} is not paused")));
        }
        for b in Self::behavior_ids(run) {
            let _ = core.command(BehaviorCommand::Resume(b));
        }
        if let Some(r) = self.run.as_mut() {
            r.paused = false;
        }
        self.clear_takeover();
        self.advance(core, now);
        Ok(())
    }

    fn stop(&mut self, id: u32, core: &mut DroneCore) -> Result<(), ActionError> {
        self.loaded(id)?;
        match self.running_id() {
            Some(running) if running == id => {
                self.end_run(core, "stopped by STOP", None);
                Ok(())
            }
            Some(running) => Err(refused(format!(
                "mission {id} is not running; mission {running} is"
            ))),
            None => Ok(()),
        }
    }

    fn insert(
        &mut self,
        id: u32,
        item_id: Option<i64>,
        mission: ValidMission,
    ) -> Result<(), ActionError> {
        let len = self.loaded(id)?.mission.items.len();
        let after = item_id.unwrap_or(len as i64 - 1);
        if after < -1 || after >= len as i64 {
            return Err(refused(format!(
                "item_id {after} is out of range: INSERT goes after an item of 0..={} (or -1 for the start)",
                len as i64 - 1
            )));
        }
        let at = usize::try_from(after + 1).unwrap_or(0);
        if let Some(run) = self.run.as_ref().filter(|r| r.mission_id == id) {
            let cursor = self.loaded(id)?.progress.cursor;
            let first_free = cursor + usize::from(run.current.is_some());
            if at < first_free {
                return Err(refused(format!(
                    "cannot insert after item {after}: items up to {} are done or running; insert after item {} or later",
                    first_free.saturating_sub(1),
                    first_free as i64 - 1
                )));
            }
        }
        if let Some(l) = self.missions.get_mut(&id) {
            let tail = l.mission.items.split_off(at);
            l.mission.items.extend(mission.items);
            l.mission.items.extend(tail);
            l.mission.warnings.extend(mission.warnings);
        }
        Ok(())
    }

    fn modify(
        &mut self,
        id: u32,
        item_id: Option<i64>,
        mission: ValidMission,
        core: &mut DroneCore,
    ) -> Result<(), ActionError> {
        let raw = item_id.ok_or_else(|| refused("MODIFY needs item_id"))?;
        let index = self.index_in(id, raw)?;
        let new = mission
            .items
            .into_iter()
            .next()
            .ok_or_else(|| refused("MODIFY needs one item"))?;
        let cursor = self.loaded(id)?.progress.cursor;
        if let Some(run) = self.run.as_ref().filter(|r| r.mission_id == id) {
            if index < cursor {
                return Err(refused(format!("item {index} is done: it cannot change")));
            }
            if let Some(current) = run.current.as_ref().filter(|c| c.index == index) {
                let old = &self.loaded(id)?.mission.items[index];
                if old.behavior() != new.behavior() {
                    return Err(refused(format!(
                        "item {index} is running {}; MODIFY in flight keeps the behavior (INSERT a new item and use NEXT_ITEM to change it)",
                        old.behavior()
                    )));
                }
                let goal = new.goal().map_err(|e| refused(e.to_string()))?;
                core.command(BehaviorCommand::Modify {
                    id: current.id,
                    goal,
                })
                .map_err(|e| refused(e.to_string()))?;
            }
        }
        if let Some(slot) = self
            .missions
            .get_mut(&id)
            .and_then(|l| l.mission.items.get_mut(index))
        {
            *slot = new;
        }
        Ok(())
    }

    fn remove(&mut self, id: u32, item_id: Option<i64>) -> Result<(), ActionError> {
        let raw = item_id.ok_or_else(|| refused("REMOVE needs item_id"))?;
        let index = self.index_in(id, raw)?;
        let loaded = self.loaded(id)?;
        if loaded.mission.items.len() == 1 {
            return Err(refused(format!(
                "item {index} is the last item of mission {id}: DELETE or RESET the mission instead"
            )));
        }
        if let Some(run) = self.run.as_ref().filter(|r| r.mission_id == id) {
            let cursor = loaded.progress.cursor;
            if index < cursor {
                return Err(refused(format!(
                    "item {index} is done: it cannot be removed"
                )));
            }
            if index == cursor && run.current.is_some() {
                return Err(refused(format!(
                    "item {index} is running: use NEXT_ITEM to skip it"
                )));
            }
        }
        if let Some(l) = self.missions.get_mut(&id) {
            l.mission.items.remove(index);
        }
        Ok(())
    }
}
