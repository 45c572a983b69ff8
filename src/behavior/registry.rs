//! Behavior registry: every behavior registers once here and becomes available to the
//! behavior server, missions and the API's behavior list (with its argument schema).

use super::goal::{parse_args, FramedPoint, GoalError};
use super::{Behavior, Failure, FailureCode};
use schemars::JsonSchema;
use serde::de::DeserializeOwned;
use serde::{Deserialize, Serialize};
use std::any::Any;
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
pub trait Goal: DeserializeOwned + JsonSchema + Clone + Send + Sync + 'static {
    /// Static checks (ranges, required combinations); the error names field, rule and unit, and
    /// refuses the goal as [`FailureCode::InvalidGoal`].
    fn check(&self) -> Result<(), GoalError>;
    /// Points the goal flies to, for frame and geofence validation.
    fn targets(&self) -> Vec<FramedPoint> {
        Vec::new()
    }
    /// Speeds the goal asks for (m/s), for the vehicle speed limit.
    fn speeds_mps(&self) -> Vec<f64> {
        Vec::new()
    }
    /// Heights above the takeoff point the goal flies at (m), for the vehicle's lowest flight
    /// height (its `height` argument, given or the default).
    fn heights_m(&self) -> Vec<f64> {
        Vec::new()
    }
}

/// What validation learns from a goal without starting it.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct GoalSummary {
    pub targets: Vec<FramedPoint>,
    pub speeds_mps: Vec<f64>,
    pub heights_m: Vec<f64>,
}

/// A goal parsed and checked once (by mission validation, or when the API starts a behavior),
/// then carried typed to the behavior: nothing parses it again.
#[derive(Clone)]
pub struct ParsedGoal {
    behavior: &'static str,
    /// The arguments as given, for events, logs and persistence.
    args: serde_json::Value,
    typed: Arc<dyn Any + Send + Sync>,
    summary: GoalSummary,
}

impl std::fmt::Debug for ParsedGoal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "ParsedGoal({} {})", self.behavior, self.args)
    }
}

impl PartialEq for ParsedGoal {
    fn eq(&self, other: &Self) -> bool {
        self.behavior == other.behavior && self.args == other.args
    }
}

impl ParsedGoal {
    pub fn behavior(&self) -> &'static str {
        self.behavior
    }

    pub fn args(&self) -> &serde_json::Value {
        &self.args
    }

    /// Where the goal flies and how fast, for frame and geofence checks.
    pub fn summary(&self) -> &GoalSummary {
        &self.summary
    }

    /// The typed goal; a goal of another behavior's type is refused.
    pub fn typed<G: Clone + 'static>(&self) -> Result<G, Failure> {
        self.typed.downcast_ref::<G>().cloned().ok_or_else(|| {
            Failure::new(
                FailureCode::Internal,
                format!("a goal of {} given to another behavior", self.behavior),
            )
        })
    }
}

type ParseFn = dyn Fn(&serde_json::Value) -> Result<ParsedGoal, Failure> + Send + Sync;
type CreateFn = dyn Fn(&ParsedGoal) -> Result<Box<dyn Behavior>, Failure> + Send + Sync;

#[derive(Clone)]
pub struct BehaviorSpec {
    pub name: &'static str,
    pub description: &'static str,
    pub resource: Resource,
    /// JSON Schema of the goal arguments.
    pub args_schema: serde_json::Value,
    /// Parses and checks arguments into a [`ParsedGoal`] of this behavior.
    pub parse: Arc<ParseFn>,
    /// Builds the behavior for a goal this spec parsed.
    pub create: Arc<CreateFn>,
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
            parse: Arc::new(move |args| {
                let goal: G = parse_args(args).map_err(|e| Failure::invalid(e.to_string()))?;
                goal.check()?;
                Ok(ParsedGoal {
                    behavior: name,
                    args: args.clone(),
                    summary: GoalSummary {
                        targets: goal.targets(),
                        speeds_mps: goal.speeds_mps(),
                        heights_m: goal.heights_m(),
                    },
                    typed: Arc::new(goal),
                })
            }),
            create: Arc::new(move |goal| {
                Ok(Box::new(make(goal.typed::<G>()?)) as Box<dyn Behavior>)
            }),
        }
    }

    /// Parses and builds in one go (children of composite behaviors, tests).
    pub fn build(&self, args: &serde_json::Value) -> Result<Box<dyn Behavior>, Failure> {
        (self.create)(&(self.parse)(args)?)
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
        r.register(super::explore::spec());
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
