//! A simulated host ticked by hand, for mission tests (shared by tests/mission_*.rs).
#![allow(dead_code)]

use kestrel::behavior::BehaviorEvent;
use kestrel::config::Config;
use kestrel::host::engine::{HostError, Updated};
use kestrel::host::status::EventBody;
use kestrel::host::{Host, HostEvent};
use kestrel::mission::{Action, MissionStatus, MissionUpdate};
use kestrel::scenario::simulated_host;
use kestrel::sim::world::World;
use serde_json::{json, Value};

pub struct Rig {
    pub host: Host,
    pub events: Vec<HostEvent>,
}

/// Thesis snippet 4.1.
pub fn takeoff_go_land() -> Value {
    json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
        {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 0.0, "y": 5.0, "z": 3.0, "speed": 1.0}},
        {"behavior": "land", "args": {"speed": 0.5}}]})
}

/// A longer flight: takeoff, three legs, land.
pub fn square() -> Value {
    json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 0.0, "y": 8.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "go_to", "args": {"x": 8.0, "y": 8.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "go_to", "args": {"x": 8.0, "y": 0.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]})
}

pub fn item(behavior: &str, args: Value) -> Value {
    json!({"target": "drone_0", "plan": [{"behavior": behavior, "args": args}]})
}

impl Rig {
    pub fn new() -> Self {
        Self::with_config(Config::default(), 1)
    }

    /// A host that already ran 0.1 s, so the vehicles have a position estimate.
    pub fn with_config(config: Config, drones: usize) -> Self {
        let mut rig = Self {
            host: simulated_host(World::empty(), drones, 0, &config),
            events: Vec::new(),
        };
        rig.run_for(0.1);
        rig.events.clear();
        rig
    }

    pub fn send(
        &mut self,
        action: Action,
        mission_id: Option<i64>,
        item_id: Option<i64>,
        mission: Option<Value>,
    ) -> Result<Updated, HostError> {
        let r = self.host.update(&MissionUpdate {
            drone_id: Some("drone_0".into()),
            mission_id,
            item_id,
            action,
            mission,
        });
        self.events.extend(self.host.drain_events());
        r
    }

    pub fn t(&self) -> f64 {
        self.host.now().as_secs_f64()
    }

    pub fn step(&mut self) {
        self.host.step();
        self.events.extend(self.host.drain_events());
    }

    /// Steps until `done` holds or `max_s` simulated seconds pass; true if it held.
    pub fn run_until(&mut self, max_s: f64, done: impl Fn(&Rig) -> bool) -> bool {
        let end = self.t() + max_s;
        while self.t() < end {
            self.step();
            if done(self) {
                return true;
            }
        }
        false
    }

    pub fn run_for(&mut self, s: f64) {
        self.run_until(s, |_| false);
    }

    pub fn status(&self) -> MissionStatus {
        let core = &self.host.cores()[0];
        self.host.executors()[0].status(core)
    }

    pub fn position(&self) -> [f64; 3] {
        let p = self.host.cores()[0]
            .vehicle_state()
            .estimate
            .pose
            .position_m;
        [p.x, p.y, p.z]
    }

    pub fn near(&self, x: f64, y: f64, z: f64, tol: f64) -> bool {
        let [px, py, pz] = self.position();
        ((px - x).powi(2) + (py - y).powi(2) + (pz - z).powi(2)).sqrt() < tol
    }

    pub fn speed(&self) -> f64 {
        self.host.cores()[0]
            .vehicle_state()
            .estimate
            .velocity_enu_mps
            .norm()
    }

    pub fn active(&self) -> Vec<String> {
        self.host.cores()[0]
            .server()
            .active()
            .into_iter()
            .map(|a| a.behavior)
            .collect()
    }

    /// Behaviors started so far, in order.
    pub fn started(&self) -> Vec<String> {
        self.behavior_events()
            .into_iter()
            .filter_map(|e| match e {
                BehaviorEvent::Started { behavior, .. } => Some(behavior),
                _ => None,
            })
            .collect()
    }

    pub fn behavior_events(&self) -> Vec<BehaviorEvent> {
        self.events
            .iter()
            .filter_map(|e| match e {
                HostEvent::Event {
                    event: EventBody::Behavior(b),
                    ..
                } => Some(b.clone()),
                _ => None,
            })
            .collect()
    }

    pub fn statuses(&self) -> Vec<MissionStatus> {
        self.events
            .iter()
            .filter_map(|e| match e {
                HostEvent::MissionStatus { status, .. } => Some(status.clone()),
                _ => None,
            })
            .collect()
    }

    /// Loads `mission` as `id` and starts it.
    pub fn execute(&mut self, id: i64, mission: Value) -> MissionStatus {
        self.send(Action::Execute, Some(id), None, Some(mission))
            .expect("EXECUTE accepted")
            .status
    }

    pub fn is_idle(&self) -> bool {
        self.status().state == kestrel::mission::ExecState::Idle
    }

    /// Airborne at the current item `index` of the running mission.
    pub fn at_item(&self, index: usize) -> bool {
        self.status().item_index == Some(index)
    }
}
