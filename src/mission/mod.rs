//! Missions: the JSON plan format, its validation, and the executor that flies it.
//!
//! In: missions (Aerostack2's `{"target", "plan": [{"behavior", "method", "args"}]}`) and
//! MissionUpdate messages (EXECUTE ... RESET), each tick the drone core's behavior events.
//! Out: behavior commands to the core, the mission status, and a snapshot to persist.

pub mod executor;
mod item;
pub mod methods;
pub mod model;
pub mod schema;
pub mod validate;

pub use executor::{ActionError, MissionExecutor, Request};
pub use model::{
    Action, DoneResult, ExecState, ItemOptions, ItemResult, Mission, MissionEnded, MissionItem,
    MissionStatus, MissionUpdate, OnFailure, PlanItem, ValidMission,
};
pub use validate::{ContextSnapshot, Limits, ValidationContext, ValidationError};
