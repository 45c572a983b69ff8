//! A fixed list of behaviors flown one after another: the built-in demo flight.
//!
//! In: the behavior events of one drone. Out: the next behavior to start, or the end result.

use crate::behavior::{BehaviorEvent, BehaviorResult};
use crate::core::{BehaviorCommand, DroneCore};
use serde_json::{json, Value};

/// The demo: take off to 3 m, go to (0, 5, 3), follow a short path, land.
pub fn demo_plan() -> Vec<(String, Value)> {
    vec![
        ("takeoff".into(), json!({ "height": 3.0, "speed": 1.0 })),
        (
            "go_to".into(),
            json!({ "x": 0.0, "y": 5.0, "z": 3.0, "speed": 1.5 }),
        ),
        (
            "follow_path".into(),
            json!({ "path": [[3.0, 5.0, 3.5], [3.0, 8.0, 3.5], [0.0, 8.0, 3.0]], "speed": 1.0, "yaw_mode": 1 }),
        ),
        ("land".into(), json!({ "speed": 0.5 })),
    ]
}

#[derive(Debug, Clone, PartialEq)]
pub enum ScriptState {
    Running { index: usize },
    Succeeded,
    Failed(String),
}

pub struct Script {
    plan: Vec<(String, Value)>,
    pub state: ScriptState,
    started: bool,
}

impl Script {
    pub fn new(plan: Vec<(String, Value)>) -> Self {
        Self {
            plan,
            state: ScriptState::Running { index: 0 },
            started: false,
        }
    }

    pub fn finished(&self) -> bool {
        !matches!(self.state, ScriptState::Running { .. })
    }

    /// Starts the first item on the first call, then advances on each finished behavior.
    pub fn update(&mut self, core: &mut DroneCore, events: &[BehaviorEvent]) {
        let ScriptState::Running { index } = self.state else {
            return;
        };
        if !self.started {
            self.started = true;
            self.start(core, index);
            return;
        }
        for e in events {
            if let BehaviorEvent::Finished {
                behavior, result, ..
            } = e
            {
                match result {
                    BehaviorResult::Succeeded => {
                        let next = index + 1;
                        if next >= self.plan.len() {
                            self.state = ScriptState::Succeeded;
                        } else {
                            self.start(core, next);
                        }
                    }
                    BehaviorResult::Failed(r) | BehaviorResult::Aborted(r) => {
                        self.state = ScriptState::Failed(format!("{behavior}: {r}"))
                    }
                }
                return;
            }
        }
    }

    fn start(&mut self, core: &mut DroneCore, index: usize) {
        let Some((behavior, goal)) = self.plan.get(index).cloned() else {
            return;
        };
        self.state = match core.command(BehaviorCommand::Start { behavior, goal }) {
            Ok(_) => ScriptState::Running { index },
            Err(e) => ScriptState::Failed(e.to_string()),
        };
    }
}
