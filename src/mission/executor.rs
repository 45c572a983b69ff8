//! The mission executor: several missions loaded, one running, changed while it flies.
//!
//! In: [`Request`]s (MissionUpdate actions with their mission already validated) and, each
//! tick, the core's behavior events. Out: behavior commands to the [`DroneCore`], the
//! [`MissionStatus`], and an [`ExecutorSnapshot`] to persist. Synchronous and deterministic: time
//! comes in as an argument, so tests tick it in simulated time.
//!
//! The rules each action follows in each state are in `docs/API.md` ("Mission actions") and
//! in `tests/mission_actions.rs`, one test per rule.

use super::model::{
    Action, DoneResult, ExecState, ItemResult, MissionStatus, OnFailure, ValidMission,
};
use super::validate::{validate_value, ValidationContext, ValidationError};
use super::MissionUpdate;
use crate::behavior::{BehaviorEvent, BehaviorId, BehaviorResult};
use crate::core::{BehaviorCommand, DroneCore};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
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

fn refused(reason: impl Into<String>) -> ActionError {
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

/// A loaded mission and how far it got.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Loaded {
    pub mission: ValidMission,
    pub progress: Progress,
}

#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Progress {
    /// Index of the current item, or of the next one to start.
    pub cursor: usize,
    pub done: Vec<DoneResult>,
    /// Ran to its end.
    pub finished: bool,
}

/// What survives a restart: loaded missions and progress, never a running state.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ExecutorSnapshot {
    pub missions: BTreeMap<u32, Loaded>,
    /// The mission that was running or paused when the snapshot was taken.
    pub running: Option<u32>,
    pub shown: Option<u32>,
    pub next_id: u32,
    pub last_error: Option<String>,
}

#[derive(Debug, Clone, PartialEq)]
struct Current {
    index: usize,
    id: BehaviorId,
    started_at: Duration,
}

#[derive(Debug, Clone, PartialEq)]
struct Parallel {
    id: BehaviorId,
    /// Index in `Progress::done` of its entry.
    slot: usize,
    on_failure: OnFailure,
}

#[derive(Debug, Clone, PartialEq)]
struct Run {
    mission_id: u32,
    paused: bool,
    current: Option<Current>,
    parallel: Vec<Parallel>,
    /// After a plan switch: hold until then before the first item starts.
    start_at: Option<Duration>,
}

pub struct MissionExecutor {
    missions: BTreeMap<u32, Loaded>,
    run: Option<Run>,
    /// The mission whose status is shown while idle: the last one run or loaded.
    shown: Option<u32>,
    last_error: Option<String>,
    next_id: u32,
    revision: u64,
    switch_hold: Duration,
}

impl MissionExecutor {
    /// `switch_hold`: how long the vehicle holds between two plans when START switches.
    pub fn new(switch_hold: Duration) -> Self {
        Self {
            missions: BTreeMap::new(),
            run: None,
            shown: None,
            last_error: None,
            next_id: 1,
            revision: 0,
            switch_hold,
        }
    }

    /// Rebuilds an executor from a snapshot: missions loaded, nothing running.
    pub fn restore(snapshot: ExecutorSnapshot, switch_hold: Duration) -> Self {
        let last_error = match snapshot.running {
            Some(id) => Some(format!(
                "Kestrel restarted while mission {id} was running; it was not resumed"
            )),
            None => snapshot.last_error,
        };
        Self {
            missions: snapshot.missions,
            run: None,
            shown: snapshot.shown,
            last_error,
            next_id: snapshot.next_id.max(1),
            revision: 1,
            switch_hold,
        }
    }

    pub fn snapshot(&self) -> ExecutorSnapshot {
        ExecutorSnapshot {
            missions: self.missions.clone(),
            running: self.run.as_ref().map(|r| r.mission_id),
            shown: self.shown,
            next_id: self.next_id,
            last_error: self.last_error.clone(),
        }
    }

    /// Changes whenever the status or a loaded mission changes (not on feedback alone).
    pub fn revision(&self) -> u64 {
        self.revision
    }

    pub fn missions(&self) -> &BTreeMap<u32, Loaded> {
        &self.missions
    }

    pub fn running_id(&self) -> Option<u32> {
        self.run.as_ref().map(|r| r.mission_id)
    }

    pub fn state(&self) -> ExecState {
        match &self.run {
            None => ExecState::Idle,
            Some(r) if r.paused => ExecState::Paused,
            Some(_) => ExecState::Running,
        }
    }

    fn touch(&mut self) {
        self.revision += 1;
    }

    /// Loads a mission under a new id, as `POST /api/missions` does.
    pub fn load_new(&mut self, mission: ValidMission) -> u32 {
        let id = self.fresh_id();
        self.store(id, mission);
        id
    }

    fn fresh_id(&mut self) -> u32 {
        while self.missions.contains_key(&self.next_id) {
            self.next_id += 1;
        }
        let id = self.next_id;
        self.next_id += 1;
        id
    }

    fn store(&mut self, id: u32, mission: ValidMission) {
        self.missions.insert(
            id,
            Loaded {
                mission,
                progress: Progress::default(),
            },
        );
        if self.run.is_none() {
            self.shown = Some(id);
        }
        self.touch();
    }

    /// Unloads a mission that is not running (`DELETE /api/missions/{id}`).
    pub fn unload(&mut self, id: u32) -> Result<(), ActionError> {
        if !self.missions.contains_key(&id) {
            return Err(ActionError::UnknownMission(id));
        }
        if self.running_id() == Some(id) {
            return Err(refused(format!(
                "mission {id} is running: STOP it before deleting it"
            )));
        }
        self.missions.remove(&id);
        if self.shown == Some(id) {
            self.shown = None;
        }
        self.touch();
        Ok(())
    }

    /// The status the thesis publishes, plus Kestrel's fields.
    pub fn status(&self, core: &DroneCore) -> MissionStatus {
        let id = self.running_id().or(self.shown);
        let Some((id, loaded)) = id.and_then(|id| self.missions.get(&id).map(|l| (id, l))) else {
            return MissionStatus {
                last_error: self.last_error.clone(),
                ..MissionStatus::default()
            };
        };
        let len = loaded.mission.items.len();
        let cursor = loaded.progress.cursor.min(len);
        let active = self.run.is_some();
        let current_item = if active {
            loaded.mission.items.get(cursor).map(|i| i.item.clone())
        } else {
            None
        };
        let feedback_current = self
            .run
            .as_ref()
            .and_then(|r| r.current.as_ref())
            .and_then(|c| core.server().info(c.id))
            .map(|info| info.feedback.clone());
        MissionStatus {
            state: self.state(),
            pending_items: len - cursor - usize::from(current_item.is_some()),
            done_items: cursor,
            current_item,
            feedback_current,
            mission_id: Some(id),
            item_index: if active { Some(cursor) } else { None },
            done_results: loaded.progress.done.clone(),
            last_error: self.last_error.clone(),
        }
    }

    /// Applies one action. On `Err` nothing changed, with one exception: when START or
    /// EXECUTE is refused because the first item's behavior refused its goal, that failure is
    /// recorded in the status (and EXECUTE's mission stays loaded).
    pub fn apply(
        &mut self,
        req: Request,
        core: &mut DroneCore,
        now: Duration,
    ) -> Result<MissionStatus, ActionError> {
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
        self.touch();
        Ok(self.status(core))
    }

    fn loaded(&self, id: u32) -> Result<&Loaded, ActionError> {
        self.missions
            .get(&id)
            .ok_or(ActionError::UnknownMission(id))
    }

    fn with_progress(&mut self, id: u32, f: impl FnOnce(&mut Progress)) {
        if let Some(l) = self.missions.get_mut(&id) {
            f(&mut l.progress);
        }
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
                Some(now + self.switch_hold)
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
        self.shown = Some(id);
        self.run = Some(Run {
            mission_id: id,
            paused: false,
            current: None,
            parallel: Vec::new(),
            start_at,
        });
        self.advance(core, now);
        if self.run.is_none() {
            if let Some(e) = &self.last_error {
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

    fn behavior_ids(run: &Run) -> Vec<BehaviorId> {
        run.current
            .iter()
            .map(|c| c.id)
            .chain(run.parallel.iter().map(|p| p.id))
            .collect()
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
                if old.item.behavior != new.item.behavior {
                    return Err(refused(format!(
                        "item {index} is running {}; MODIFY in flight keeps the behavior (INSERT a new item and use NEXT_ITEM to change it)",
                        old.item.behavior
                    )));
                }
                core.command(BehaviorCommand::Modify {
                    id: current.id,
                    goal: new.goal.clone(),
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

    /// Stops the current item's behavior (NEXT_ITEM, JUMP_TO) and records why.
    fn leave_current(&mut self, core: &mut DroneCore, reason: &str) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        let Some(current) = run.current.take() else {
            return;
        };
        let _ = core.command(BehaviorCommand::Stop(current.id));
        let id = run.mission_id;
        self.record(id, current.index, ItemResult::Stopped, Some(reason.into()));
    }

    fn record(&mut self, id: u32, index: usize, result: ItemResult, reason: Option<String>) {
        if let Some(l) = self.missions.get_mut(&id) {
            let behavior = l
                .mission
                .items
                .get(index)
                .map(|i| i.item.behavior.clone())
                .unwrap_or_default();
            l.progress.done.push(DoneResult {
                item: index,
                behavior,
                result,
                reason,
            });
        }
        self.touch();
    }

    /// Ends the run: every behavior it started is stopped (the vehicle holds), each recorded
    /// with `reason`; `error` becomes the last error when given.
    fn end_run(&mut self, core: &mut DroneCore, reason: &str, error: Option<String>) {
        let Some(run) = self.run.take() else {
            return;
        };
        for b in Self::behavior_ids(&run) {
            let _ = core.command(BehaviorCommand::Stop(b));
        }
        if let Some(c) = &run.current {
            self.record(
                run.mission_id,
                c.index,
                ItemResult::Stopped,
                Some(reason.to_string()),
            );
        }
        self.close_parallel(&run, reason);
        if error.is_some() {
            self.last_error = error;
        }
        self.shown = Some(run.mission_id);
        self.touch();
    }

    /// Marks still-running parallel items as stopped.
    fn close_parallel(&mut self, run: &Run, reason: &str) {
        if let Some(l) = self.missions.get_mut(&run.mission_id) {
            for p in &run.parallel {
                if let Some(d) = l.progress.done.get_mut(p.slot) {
                    d.result = ItemResult::Stopped;
                    d.reason = Some(reason.to_string());
                }
            }
        }
    }

    fn fail(&mut self, core: &mut DroneCore, index: usize, behavior: &str, reason: &str) {
        let id = self.running_id().unwrap_or_default();
        let message = format!("mission {id} item {index} ({behavior}) failed: {reason}");
        tracing::warn!("{message}");
        self.end_run(core, "mission failed", Some(message));
    }

    /// One tick: reacts to behaviors that ended, ends `run_for_s` items, starts what is due.
    pub fn update(&mut self, now: Duration, core: &mut DroneCore, events: &[BehaviorEvent]) {
        for e in events {
            if let BehaviorEvent::Finished {
                id,
                behavior,
                result,
            } = e
            {
                self.on_finished(*id, behavior, result, core);
            }
        }
        self.end_timed_item(core, now);
        self.advance(core, now);
    }

    fn on_finished(
        &mut self,
        behavior_id: BehaviorId,
        behavior: &str,
        result: &BehaviorResult,
        core: &mut DroneCore,
    ) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        let id = run.mission_id;
        let (item_result, reason) = match result {
            BehaviorResult::Succeeded => (ItemResult::Succeeded, None),
            BehaviorResult::Failed(r) => (ItemResult::Failed, Some(r.clone())),
            BehaviorResult::Aborted(r) => (ItemResult::Aborted, Some(r.clone())),
        };
        if let Some(current) = run.current.as_ref().filter(|c| c.id == behavior_id) {
            let index = current.index;
            run.current = None;
            let on_failure = self
                .missions
                .get(&id)
                .and_then(|l| l.mission.items.get(index))
                .map(|i| i.options.on_failure)
                .unwrap_or_default();
            self.record(id, index, item_result, reason.clone());
            match (item_result, on_failure) {
                (ItemResult::Succeeded, _) | (_, OnFailure::Continue) => {
                    self.with_progress(id, |p| p.cursor = index + 1);
                }
                (_, OnFailure::Abort) => {
                    self.fail(core, index, behavior, reason.as_deref().unwrap_or("failed"));
                }
            }
            return;
        }
        let Some(pos) = run.parallel.iter().position(|p| p.id == behavior_id) else {
            return;
        };
        let p = run.parallel.remove(pos);
        let mut index = 0;
        if let Some(d) = self
            .missions
            .get_mut(&id)
            .and_then(|l| l.progress.done.get_mut(p.slot))
        {
            d.result = item_result;
            d.reason = reason.clone();
            index = d.item;
        }
        self.touch();
        if item_result == ItemResult::Failed && p.on_failure == OnFailure::Abort {
            self.fail(core, index, behavior, reason.as_deref().unwrap_or("failed"));
        }
    }

    /// Stops the current item when its `run_for_s` is over; the item counts as done.
    fn end_timed_item(&mut self, core: &mut DroneCore, now: Duration) {
        let Some(run) = self.run.as_ref().filter(|r| !r.paused) else {
            return;
        };
        let Some(current) = &run.current else {
            return;
        };
        let run_for = self
            .missions
            .get(&run.mission_id)
            .and_then(|l| l.mission.items.get(current.index))
            .and_then(|i| i.options.run_for_s);
        if let Some(s) = run_for {
            if now.saturating_sub(current.started_at) >= Duration::from_secs_f64(s) {
                let index = current.index;
                self.leave_current(core, &format!("ran for {s} s (run_for_s)"));
                let id = self.running_id().unwrap_or_default();
                self.with_progress(id, |p| p.cursor = index + 1);
            }
        }
    }

    /// Starts items from the cursor until one must be waited for, the plan ends, or one fails.
    fn advance(&mut self, core: &mut DroneCore, now: Duration) {
        loop {
            let Some(run) = self.run.as_mut() else {
                return;
            };
            if run.paused || run.current.is_some() {
                return;
            }
            if let Some(t) = run.start_at {
                if now < t {
                    return;
                }
                run.start_at = None;
            }
            let id = run.mission_id;
            let Some(loaded) = self.missions.get(&id) else {
                self.run = None;
                return;
            };
            let index = loaded.progress.cursor;
            let Some(item) = loaded.mission.items.get(index).cloned() else {
                self.complete(core);
                return;
            };
            let started = core.command(BehaviorCommand::Start {
                behavior: item.item.behavior.clone(),
                goal: item.goal.clone(),
            });
            match started {
                Ok(Some(behavior_id)) if item.options.wait => {
                    if let Some(run) = self.run.as_mut() {
                        run.current = Some(Current {
                            index,
                            id: behavior_id,
                            started_at: now,
                        });
                    }
                    self.touch();
                    return;
                }
                Ok(Some(behavior_id)) => {
                    let slot = self.missions.get(&id).map_or(0, |l| l.progress.done.len());
                    self.record(id, index, ItemResult::Started, None);
                    if let Some(run) = self.run.as_mut() {
                        run.parallel.push(Parallel {
                            id: behavior_id,
                            slot,
                            on_failure: item.options.on_failure,
                        });
                    }
                    self.with_progress(id, |p| p.cursor = index + 1);
                }
                Ok(None) | Err(_) => {
                    let reason = match started {
                        Err(e) => e.to_string(),
                        _ => "the behavior server gave no id".into(),
                    };
                    self.record(id, index, ItemResult::Failed, Some(reason.clone()));
                    if item.options.on_failure == OnFailure::Abort {
                        self.fail(core, index, &item.item.behavior, &reason);
                        return;
                    }
                    self.with_progress(id, |p| p.cursor = index + 1);
                }
            }
        }
    }

    /// The plan ran to its end: parallel behaviors still running are stopped.
    fn complete(&mut self, core: &mut DroneCore) {
        let Some(run) = self.run.take() else {
            return;
        };
        for p in &run.parallel {
            let _ = core.command(BehaviorCommand::Stop(p.id));
        }
        self.close_parallel(&run, "mission ended");
        self.with_progress(run.mission_id, |p| p.finished = true);
        self.shown = Some(run.mission_id);
        tracing::info!("mission {} completed", run.mission_id);
        self.touch();
    }
}
