//! The mission executor: several missions loaded, one running, changed while it flies.
//!
//! In: [`Request`]s (MissionUpdate actions with their mission already validated) and, each
//! tick, the core's behavior events. Out: behavior commands to the [`DroneCore`], the
//! [`MissionStatus`], and an [`ExecutorSnapshot`] to persist. Synchronous and deterministic: time
//! comes in as an argument, so tests tick it in simulated time.
//!
//! The rules each action follows in each state are in `docs/API.md` ("Mission actions") and
//! in `tests/mission_actions.rs`, one test per rule.

mod actions;
mod in_flight;
mod link;
mod loaded;
mod peer_lost;
mod takeover;

pub use actions::{ActionError, Request};
use in_flight::InFlightFailed;
pub use in_flight::InFlightFailure;
use link::LinkWait;
pub use link::{ExecutorConfig, LinkRegained};
pub use loaded::{ExecutorMeta, ExecutorSnapshot, Loaded, Progress, MAX_MISSIONS};

use super::model::{DoneResult, ExecState, ItemResult, MissionStatus, OnFailure};
use crate::behavior::{
    BehaviorEvent, BehaviorId, BehaviorResult, Failure, FailureCode, ServerError,
};
use crate::core::{BehaviorCommand, DroneCore};
use std::collections::{BTreeMap, BTreeSet};
use std::time::Duration;

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
    /// The link to the autopilot was lost during an item: what to do when it is back.
    link_wait: Option<LinkWait>,
}

pub struct MissionExecutor {
    missions: BTreeMap<u32, Loaded>,
    run: Option<Run>,
    /// The mission whose status is shown while idle: the last one run or loaded.
    shown: Option<u32>,
    last_error: Option<String>,
    /// The stable code of the behavior failure behind `last_error`, if one was.
    last_error_code: Option<FailureCode>,
    next_id: u32,
    revision: u64,
    /// Missions changed (or unloaded) since the last [`MissionExecutor::take_changed`].
    changed: BTreeSet<u32>,
    /// What the host should tell operators (what a vehicle does after a failure).
    alerts: Vec<String>,
    /// A mission failed: `[mission] on_failure` is applied at the end of the next update (a
    /// refused START forgets it: a refusal changes nothing).
    failed_in_flight: Option<InFlightFailed>,
    /// A `land` item (mission, item) failed because the link stayed lost past `link_wait`:
    /// whether the vehicle did land is known once the link is back (`link.rs`).
    unconfirmed_landing: Option<(u32, usize)>,
    config: ExecutorConfig,
}

impl MissionExecutor {
    pub fn new(config: ExecutorConfig) -> Self {
        Self {
            missions: BTreeMap::new(),
            run: None,
            shown: None,
            last_error: None,
            last_error_code: None,
            next_id: 1,
            revision: 0,
            changed: BTreeSet::new(),
            alerts: Vec::new(),
            failed_in_flight: None,
            unconfirmed_landing: None,
            config,
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

    fn with_progress(&mut self, id: u32, f: impl FnOnce(&mut Progress)) {
        if let Some(l) = self.missions.get_mut(&id) {
            f(&mut l.progress);
        }
        self.mark(id);
    }

    /// Alerts since the last call, for the host to send to operators.
    pub fn take_alerts(&mut self) -> Vec<String> {
        std::mem::take(&mut self.alerts)
    }

    /// Every change passes here: the running mission's progress may have moved with it.
    fn touch(&mut self) {
        self.revision += 1;
        if let Some(id) = self.running_id() {
            self.mark(id);
        }
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
            loaded
                .mission
                .items
                .get(cursor)
                .and_then(|i| i.written().ok())
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
            last_error_code: self.last_error_code,
        }
    }

    fn behavior_ids(run: &Run) -> Vec<BehaviorId> {
        run.current
            .iter()
            .map(|c| c.id)
            .chain(run.parallel.iter().map(|p| p.id))
            .collect()
    }

    /// Stops the current item's behavior (NEXT_ITEM, JUMP_TO) and records why.
    fn leave_current(&mut self, core: &mut DroneCore, reason: &str) {
        self.end_current(core, ItemResult::Stopped, reason);
    }

    /// Ends the current item's behavior as `Stopped` (left) or `Succeeded` (its `run_for_s`
    /// is over: the behavior finishes succeeded too) and records why.
    fn end_current(&mut self, core: &mut DroneCore, result: ItemResult, reason: &str) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        let Some(current) = run.current.take() else {
            return;
        };
        let command = if result == ItemResult::Succeeded {
            BehaviorCommand::Complete(current.id)
        } else {
            BehaviorCommand::Stop(current.id)
        };
        let _ = core.command(command);
        let id = run.mission_id;
        self.record(id, current.index, result, Some(reason.into()), None);
    }

    fn record(
        &mut self,
        id: u32,
        index: usize,
        result: ItemResult,
        reason: Option<String>,
        code: Option<FailureCode>,
    ) {
        if let Some(l) = self.missions.get_mut(&id) {
            let behavior = l
                .mission
                .items
                .get(index)
                .map(|i| i.behavior().to_string())
                .unwrap_or_default();
            l.progress.done.push(DoneResult {
                item: index,
                behavior,
                result,
                reason,
                code,
            });
        }
        self.mark(id);
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
                None,
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
        self.mark(run.mission_id);
        if let Some(l) = self.missions.get_mut(&run.mission_id) {
            for p in &run.parallel {
                if let Some(d) = l.progress.done.get_mut(p.slot) {
                    d.result = ItemResult::Stopped;
                    d.reason = Some(reason.to_string());
                }
            }
        }
    }

    fn fail(
        &mut self,
        core: &mut DroneCore,
        index: usize,
        behavior: &str,
        reason: &str,
        code: Option<FailureCode>,
    ) {
        let id = self.running_id().unwrap_or_default();
        let message = format!("mission {id} item {index} ({behavior}) failed: {reason}");
        tracing::warn!("{message}");
        self.end_run(core, "mission failed", Some(message));
        self.last_error_code = code;
        self.failed_in_flight = Some(InFlightFailed {
            index,
            behavior: behavior.to_string(),
            code,
        });
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
                self.on_finished(*id, behavior, result, core, now);
            }
        }
        self.confirm_landing(core);
        self.follow_link(core, now);
        self.follow_fleet(core);
        self.end_timed_item(core, now);
        self.advance(core, now);
        if let Some(failed) = self.failed_in_flight.take() {
            self.after_failure(core, &failed);
        }
    }

    fn on_finished(
        &mut self,
        behavior_id: BehaviorId,
        behavior: &str,
        result: &BehaviorResult,
        core: &mut DroneCore,
        now: Duration,
    ) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        let id = run.mission_id;
        let item_result = match result {
            BehaviorResult::Succeeded => ItemResult::Succeeded,
            BehaviorResult::Failed { .. } => ItemResult::Failed,
            BehaviorResult::Aborted { .. } => ItemResult::Aborted,
        };
        let reason = result.reason().map(str::to_string);
        let code = result.code();
        if let Some(current) = run.current.as_ref().filter(|c| c.id == behavior_id) {
            let index = current.index;
            run.current = None;
            if code == Some(FailureCode::LinkLost) {
                self.record(id, index, item_result, reason, code);
                self.wait_for_link(index, now);
                return;
            }
            if code == Some(FailureCode::PilotTakeover) {
                // The mission is paused (`takeover.rs`); RESUME starts this item again.
                self.record(id, index, item_result, reason, code);
                return;
            }
            if code == Some(FailureCode::FleetPeerLost) {
                // Paused, holding, until the peer is back (`peer_lost.rs`).
                self.record(id, index, item_result, reason.clone(), code);
                self.peer_lost(core, reason.as_deref().unwrap_or("fleet peer lost"));
                return;
            }
            let on_failure = self
                .missions
                .get(&id)
                .and_then(|l| l.mission.items.get(index))
                .map(|i| i.options.on_failure)
                .unwrap_or_default();
            self.record(id, index, item_result, reason.clone(), code);
            match (item_result, on_failure) {
                (ItemResult::Succeeded, _) | (_, OnFailure::Continue) => {
                    self.with_progress(id, |p| p.cursor = index + 1);
                }
                (_, OnFailure::Abort) => {
                    let reason = reason.as_deref().unwrap_or("failed");
                    self.fail(core, index, behavior, reason, code);
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
        let interrupted = matches!(
            code,
            Some(FailureCode::LinkLost | FailureCode::PilotTakeover | FailureCode::FleetPeerLost)
        );
        if item_result == ItemResult::Failed && p.on_failure == OnFailure::Abort && !interrupted {
            let reason = reason.as_deref().unwrap_or("failed");
            self.fail(core, index, behavior, reason, code);
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
                let reason = format!("ran for {s} s (run_for_s)");
                self.end_current(core, ItemResult::Succeeded, &reason);
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
            if run.paused || run.current.is_some() || run.link_wait.is_some() {
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
            // The goal is parsed again from the item as written, as the behavior starts.
            let started = match item.goal() {
                Ok(goal) => core.command(BehaviorCommand::Start {
                    behavior: item.behavior().to_string(),
                    goal,
                }),
                Err(e) => Err(ServerError::Rejected {
                    behavior: item.behavior().to_string(),
                    reason: Failure::invalid(e.to_string()),
                }),
            };
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
                    self.record(id, index, ItemResult::Started, None, None);
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
                    let (reason, code) = match started {
                        Err(e) => (e.to_string(), Some(e.code())),
                        _ => ("the behavior server gave no id".into(), None),
                    };
                    self.record(id, index, ItemResult::Failed, Some(reason.clone()), code);
                    if item.options.on_failure == OnFailure::Abort {
                        self.fail(core, index, item.behavior(), &reason, code);
                        return;
                    }
                    self.with_progress(id, |p| p.cursor = index + 1);
                }
            }
        }
    }

    /// The plan ran to its end: parallel behaviors still running are ended; they did their
    /// part, so they finish succeeded.
    fn complete(&mut self, core: &mut DroneCore) {
        let Some(run) = self.run.take() else {
            return;
        };
        for p in &run.parallel {
            let _ = core.command(BehaviorCommand::Complete(p.id));
        }
        self.close_parallel(&run, "mission ended");
        self.with_progress(run.mission_id, |p| p.finished = true);
        self.shown = Some(run.mission_id);
        tracing::info!("mission {} completed", run.mission_id);
        self.touch();
    }
}
