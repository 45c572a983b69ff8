//! The host's persistence: what changed since it was last handed to the store, and the store.
//!
//! In: after every command and tick, each drone's mission executor and the registered frames.
//! Out: the [`Change`]s since the last call (the missions that changed, copied one by one and
//! never all of them; an executor's small state when its revision moved; the frames when theirs
//! did), pushed to the state directory's writer (`host::store::Sink`, off the loop). Without a
//! store the changes are still taken, so nothing piles up.

use super::frames::FrameRegistry;
use crate::host::store::{Change, Sink};
use crate::mission::MissionExecutor;

pub(super) struct Persistence {
    /// Where changes go (`None`: nothing is kept).
    store: Option<Sink>,
    /// Each executor's revision when its state was last handed to the store.
    committed: Vec<u64>,
    /// The frames' revision when last handed to the store.
    frames_committed: u64,
}

impl Persistence {
    /// For `drones` executors, none handed to a store yet.
    pub(super) fn new(drones: usize) -> Self {
        Self {
            store: None,
            committed: vec![0; drones],
            frames_committed: 0,
        }
    }

    pub(super) fn set_store(&mut self, store: Sink) {
        self.store = Some(store);
    }

    pub(super) fn store(&self) -> Option<&Sink> {
        self.store.as_ref()
    }

    /// Hands what changed since the last call to the store. No I/O here.
    pub(super) fn commit<'a>(
        &mut self,
        executors: impl Iterator<Item = (&'a str, &'a mut MissionExecutor)>,
        frames: &FrameRegistry,
    ) {
        let changes = self.changes(executors, frames);
        if let Some(store) = &self.store {
            store.push(changes);
        }
    }

    /// What changed since the last call: each drone's (named) executor, and the frames.
    fn changes<'a>(
        &mut self,
        executors: impl Iterator<Item = (&'a str, &'a mut MissionExecutor)>,
        frames: &FrameRegistry,
    ) -> Vec<Change> {
        let mut changes = Vec::new();
        for ((drone, ex), committed) in executors.zip(self.committed.iter_mut()) {
            for (id, loaded) in ex.take_changed() {
                changes.push(Change::Mission {
                    drone: drone.to_string(),
                    id,
                    loaded: loaded.map(Box::new),
                });
            }
            if *committed != ex.revision() {
                *committed = ex.revision();
                changes.push(Change::Meta {
                    drone: drone.to_string(),
                    meta: ex.meta(),
                });
            }
        }
        if self.frames_committed != frames.revision() {
            self.frames_committed = frames.revision();
            changes.push(Change::Frames(frames.list().to_vec()));
        }
        changes
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::config::Config;
    use crate::host::engine::FrameRegistration;
    use crate::mission::ValidMission;

    fn frame(id: &str) -> FrameRegistration {
        serde_json::from_value(serde_json::json!({ "frame_id": id })).unwrap()
    }

    fn kinds(changes: &[Change]) -> Vec<String> {
        changes
            .iter()
            .map(|c| match c {
                Change::Mission { drone, id, loaded } => {
                    format!("{drone} mission {id} {}", loaded.is_some())
                }
                Change::Meta { drone, .. } => format!("{drone} meta"),
                Change::Frames(f) => format!("frames {}", f.len()),
            })
            .collect()
    }

    /// Each change is handed over once: a mission loaded, its executor's state, the frames; a
    /// second call with nothing new hands over nothing.
    #[test]
    fn each_change_is_handed_over_once() {
        let mut persistence = Persistence::new(2);
        let config = Config::default().executor_config();
        let mut executors = vec![MissionExecutor::new(config), MissionExecutor::new(config)];
        let mut frames = FrameRegistry::default();
        let changes = |p: &mut Persistence, ex: &mut [MissionExecutor], f: &FrameRegistry| {
            let named = ["drone_0", "drone_1"].into_iter().zip(ex.iter_mut());
            kinds(&p.changes(named, f))
        };
        assert!(changes(&mut persistence, &mut executors, &frames).is_empty());
        let mission = ValidMission {
            target: "drone_1".into(),
            items: Vec::new(),
            warnings: Vec::new(),
        };
        let id = executors[1].load_new(mission).unwrap();
        frames.insert(frame("nacelle"));
        assert_eq!(
            changes(&mut persistence, &mut executors, &frames),
            [
                format!("drone_1 mission {id} true"),
                "drone_1 meta".into(),
                "frames 1".into()
            ]
        );
        assert!(changes(&mut persistence, &mut executors, &frames).is_empty());
        executors[1].unload(id).unwrap();
        assert_eq!(
            changes(&mut persistence, &mut executors, &frames),
            [format!("drone_1 mission {id} false"), "drone_1 meta".into()]
        );
    }
}
