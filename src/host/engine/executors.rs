//! The host's missions service: one mission executor per drone (in the cores' order), the
//! settings executors are built and restored with, the limits missions are validated against,
//! and which executors changed since their status was last published.
//!
//! In: a drone's index, a snapshot kept by a previous run. Out: its executor; the drones whose
//! mission status is due ([`Executors::take_unpublished`]); the drones that hold a mission.

use crate::mission::executor::{ExecutorConfig, ExecutorSnapshot};
use crate::mission::{Limits, MissionExecutor};

pub(super) struct Executors {
    executors: Vec<MissionExecutor>,
    config: ExecutorConfig,
    limits: Limits,
    /// Each executor's revision when its status was last published (`u64::MAX`: never, so
    /// every drone's first status is due).
    published: Vec<u64>,
}

impl Executors {
    /// For `drones` drones, each with an empty executor.
    pub(super) fn new(drones: usize, config: ExecutorConfig, limits: Limits) -> Self {
        Self {
            executors: (0..drones).map(|_| MissionExecutor::new(config)).collect(),
            config,
            limits,
            published: vec![u64::MAX; drones],
        }
    }

    pub(super) fn list(&self) -> &[MissionExecutor] {
        &self.executors
    }

    pub(super) fn get(&self, i: usize) -> Option<&MissionExecutor> {
        self.executors.get(i)
    }

    pub(super) fn get_mut(&mut self, i: usize) -> Option<&mut MissionExecutor> {
        self.executors.get_mut(i)
    }

    pub(super) fn iter_mut(&mut self) -> impl Iterator<Item = &mut MissionExecutor> {
        self.executors.iter_mut()
    }

    /// What missions are checked against (speed limit, geofence).
    pub(super) fn limits(&self) -> &Limits {
        &self.limits
    }

    /// No mission runs or is paused on any drone.
    pub(super) fn all_idle(&self) -> bool {
        self.executors.iter().all(|e| e.running_id().is_none())
    }

    /// Whether drone `i` runs (or has paused) mission `mission_id`.
    pub(super) fn is_running(&self, i: usize, mission_id: u32) -> bool {
        self.get(i)
            .is_some_and(|e| e.running_id() == Some(mission_id))
    }

    /// Rebuilds drone `i`'s executor from a previous run's snapshot (missions loaded, nothing
    /// running).
    pub(super) fn restore(&mut self, i: usize, snapshot: &ExecutorSnapshot) {
        if let Some(ex) = self.executors.get_mut(i) {
            *ex = MissionExecutor::restore(snapshot.clone(), self.config);
        }
    }

    /// The drones that hold mission `mission_id`, in order.
    pub(super) fn holders(&self, mission_id: u32) -> Vec<usize> {
        (0..self.executors.len())
            .filter(|i| {
                self.executors
                    .get(*i)
                    .is_some_and(|e| e.missions().contains_key(&mission_id))
            })
            .collect()
    }

    /// The drones whose executor changed since this was last asked (every drone the first
    /// time), in order: each is counted as published.
    pub(super) fn take_unpublished(&mut self) -> Vec<usize> {
        let mut due = Vec::new();
        for (i, (ex, published)) in self
            .executors
            .iter()
            .zip(self.published.iter_mut())
            .enumerate()
        {
            if *published != ex.revision() {
                *published = ex.revision();
                due.push(i);
            }
        }
        due
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::mission::ValidMission;

    fn executors(drones: usize) -> Executors {
        let config = Config::default();
        Executors::new(drones, config.executor_config(), config.mission_limits())
    }

    fn mission(target: &str) -> ValidMission {
        ValidMission {
            target: target.into(),
            items: Vec::new(),
            warnings: Vec::new(),
        }
    }

    /// Every drone's status is due once at first; then only a drone whose executor changed.
    #[test]
    fn a_status_is_due_once_per_change() {
        let mut e = executors(3);
        assert_eq!(e.take_unpublished(), [0, 1, 2]);
        assert!(e.take_unpublished().is_empty());
        e.get_mut(1).unwrap().load_new(mission("drone_1")).unwrap();
        assert_eq!(e.take_unpublished(), [1]);
        assert!(e.take_unpublished().is_empty());
    }

    /// Mission ids are per drone: the holders of an id are every drone that loaded one under it.
    #[test]
    fn holders_are_the_drones_with_that_mission() {
        let mut e = executors(3);
        let id = e.get_mut(0).unwrap().load_new(mission("drone_0")).unwrap();
        assert_eq!(e.holders(id), [0]);
        e.get_mut(2).unwrap().load_new(mission("drone_2")).unwrap();
        assert_eq!(e.holders(id), [0, 2]);
        assert!(e.holders(id + 1).is_empty());
        assert!(e.all_idle());
        assert!(!e.is_running(0, id));
    }

    /// A restored executor keeps the missions of its snapshot and runs none of them; an index
    /// beyond the drones changes nothing.
    #[test]
    fn restore_keeps_the_missions_and_runs_none() {
        let mut e = executors(2);
        let id = e.get_mut(0).unwrap().load_new(mission("drone_0")).unwrap();
        let mut snapshot = e.get(0).unwrap().snapshot();
        snapshot.running = Some(id);
        e.restore(1, &snapshot);
        e.restore(5, &snapshot);
        let restored = e.get(1).unwrap();
        assert_eq!(restored.missions().keys().collect::<Vec<_>>(), [&id]);
        assert_eq!(restored.running_id(), None);
        assert_eq!(e.list().len(), 2);
        assert!(e.all_idle());
    }
}
