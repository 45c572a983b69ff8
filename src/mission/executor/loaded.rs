//! The missions an executor keeps and what of it is saved: loading under a new id (within
//! [`MAX_MISSIONS`]), unloading one that is not running, the missions changed since the last
//! save, the small state beside them ([`ExecutorMeta`]) and the whole of it after a restart
//! ([`ExecutorSnapshot`]).
//!
//! In: validated missions, DELETEs, a snapshot from the state directory. Out: ids, refusals
//! ([`ActionError`]), the changed missions and snapshots for the store.

use super::actions::refused;
use super::{ActionError, ExecutorConfig, MissionExecutor};
use crate::mission::model::{DoneResult, ValidMission};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, BTreeSet};

/// Most missions loaded on one drone at once; one more is refused (delete one, or load under
/// the id of an idle one to replace it).
pub const MAX_MISSIONS: usize = 64;

/// What the executor keeps besides its missions: small, saved whole on every change.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct ExecutorMeta {
    /// The mission that was running or paused when it was taken.
    pub running: Option<u32>,
    pub shown: Option<u32>,
    pub next_id: u32,
    pub last_error: Option<String>,
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

impl MissionExecutor {
    /// Rebuilds an executor from a snapshot: missions loaded, nothing running.
    pub fn restore(snapshot: ExecutorSnapshot, config: ExecutorConfig) -> Self {
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
            last_error_code: None,
            next_id: snapshot.next_id.max(1),
            revision: 1,
            changed: BTreeSet::new(),
            alerts: Vec::new(),
            failed_in_flight: None,
            unconfirmed_landing: None,
            config,
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

    /// Everything but the missions, as [`ExecutorSnapshot`] has it.
    pub fn meta(&self) -> ExecutorMeta {
        ExecutorMeta {
            running: self.running_id(),
            shown: self.shown,
            next_id: self.next_id,
            last_error: self.last_error.clone(),
        }
    }

    /// The missions changed since the last call: a copy of each (`None`: unloaded). Only those
    /// are copied, so saving after a change costs one mission, not all of them.
    pub fn take_changed(&mut self) -> Vec<(u32, Option<Loaded>)> {
        std::mem::take(&mut self.changed)
            .into_iter()
            .map(|id| (id, self.missions.get(&id).cloned()))
            .collect()
    }

    /// Notes that mission `id` changed (or went), for [`MissionExecutor::take_changed`].
    pub(super) fn mark(&mut self, id: u32) {
        self.changed.insert(id);
    }

    /// Loads a mission under a new id, as `POST /api/missions` does.
    pub fn load_new(&mut self, mission: ValidMission) -> Result<u32, ActionError> {
        self.check_room(None)?;
        let id = self.fresh_id();
        self.store(id, mission);
        Ok(id)
    }

    /// Refuses a mission that would be one more than [`MAX_MISSIONS`] (`id`: the one it
    /// would replace, if any).
    pub(super) fn check_room(&self, id: Option<u32>) -> Result<(), ActionError> {
        let replaces = id.is_some_and(|id| self.missions.contains_key(&id));
        if replaces || self.missions.len() < MAX_MISSIONS {
            return Ok(());
        }
        Err(refused(format!(
            "mission_id: {} missions are loaded on this drone, the most it keeps \
             ({MAX_MISSIONS}); delete one (DELETE /api/missions/{{id}}) or load under the id of \
             an idle one to replace it",
            self.missions.len()
        )))
    }

    pub(super) fn fresh_id(&mut self) -> u32 {
        // At most MAX_MISSIONS ids are taken, so this ends; 0 is never handed out.
        while self.next_id == 0 || self.missions.contains_key(&self.next_id) {
            self.next_id = self.next_id.wrapping_add(1);
        }
        let id = self.next_id;
        self.next_id = self.next_id.wrapping_add(1);
        id
    }

    pub(super) fn store(&mut self, id: u32, mission: ValidMission) {
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
        self.mark(id);
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
        self.mark(id);
        self.touch();
        Ok(())
    }
}
