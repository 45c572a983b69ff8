//! Behavior registry: every behavior registers once here and becomes available to the
//! behavior server, missions and the API's behavior list (with its argument schema).

use super::goal::{parse_args, FramedPoint};
use super::Behavior;
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::Arc;

/// What a behavior occupies; one behavior per resource runs at a time.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Resource {
    Motion,
    Gimbal,
    Camera,
}

/// A goal type: parsed from JSON, checked without flying, and able to say where it goes.
pub trait Goal: DeserializeOwned + JsonSchema + Send + 'static {
    /// Static checks (ranges, required combinations); the message names field and unit.
    fn check(&self) -> Result<(), String>;
    /// Points the goal flies to, for frame and geofence validation.
    fn targets(&self) -> Vec<FramedPoint> {
        Vec::new()
    }
    /// Speeds the goal asks for (m/s), for the vehicle speed limit.
    fn speeds_mps(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// What validation learns from a goal without starting it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GoalSummary {
    pub targets: Vec<FramedPoint>,
    pub speeds_mps: Vec<f64>,
}

type CreateFn = dyn Fn(&serde_json::Value) -> Result<Box<dyn Behavior>, String> + Send + Sync;
type ValidateFn = dyn Fn(&serde_json::Value) -> Result<GoalSummary, String> + Send + Sync;

#[derive(Clone)]
pub struct BehaviorSpec {
    pub name: &'static str,
    pub description: &'static str,
    pub resource: Resource,
    /// JSON Schema of the goal arguments.
    pub args_schema: serde_json::Value,
    pub create: Arc<CreateFn>,
    pub validate: Arc<ValidateFn>,
}

impl BehaviorSpec {
    /// A spec for goal type `G` whose behavior is built by `make`.
    pub fn new<G: Goal, B: Behavior + 'static>(
        name: &'static str,
        description: &'static str,
        resource: Resource,
        make: fn(G) -> B,
    ) -> Self {
        let args_schema = serde_json::to_value(schemars::schema_for!(G)).unwrap_or_default();
        Self {
            name,
            description,
            resource,
            args_schema,
            create: Arc::new(move |args| {
                let goal: G = parse_args(args)?;
                goal.check()?;
                Ok(Box::new(make(goal)) as Box<dyn Behavior>)
            }),
            validate: Arc::new(|args| {
                let goal: G = parse_args(args)?;
                goal.check()?;
                Ok(GoalSummary {
                    targets: goal.targets(),
                    speeds_mps: goal.speeds_mps(),
                })
            }),
        }
    }
}

/// All behaviors known to this build, by name.
#[derive(Clone, Default)]
pub struct Registry {
    specs: BTreeMap<&'static str, BehaviorSpec>,
}

impl Registry {
    pub fn empty() -> Self {
        Self::default()
    }

    /// The motion behaviors every platform has.
    pub fn with_motion_behaviors() -> Self {
        let mut r = Self::empty();
        r.register(super::takeoff::spec());
        r.register(super::land::spec());
        r.register(super::go_to::spec());
        r.register(super::go_to::gps_spec());
        r.register(super::follow_path::spec());
        r.register(super::follow_reference::spec());
        r.register(super::hover::spec());
        r.register(super::rotate::spec());
        r.register(super::sequence::rtl_spec());
        r.register(super::navigate_to::spec());
        r
    }

    pub fn register(&mut self, spec: BehaviorSpec) {
        self.specs.insert(spec.name, spec);
    }

    pub fn get(&self, name: &str) -> Option<&BehaviorSpec> {
        self.specs.get(name)
    }

    pub fn iter(&self) -> impl Iterator<Item = &BehaviorSpec> {
        self.specs.values()
    }
}
