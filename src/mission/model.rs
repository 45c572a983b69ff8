//! Mission data: the JSON mission (Aerostack2's format), validated plan items, the
//! MissionUpdate message and the mission status.

pub use super::item::PlanItem;
use crate::behavior::FailureCode;
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize, Serializer};
use serde_json::{Map, Value};

/// Name of the default method of every behavior (Aerostack2's `__call__`).
pub const CALL: &str = "__call__";

fn default_method() -> String {
    CALL.to_string()
}

/// A mission as written: `{"target": "drone_0", "plan": [{"behavior", "method", "args"}]}`.
/// Other top-level fields (Aerostack2's old `verbose`) are ignored with a warning.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, utoipa::ToSchema)]
pub struct Mission {
    /// Drone that flies it: `drone_0` ... (`[drone] id` on a vehicle).
    pub target: String,
    /// Items run in order.
    pub plan: Vec<MissionItem>,
}

/// One plan item: a behavior, how to call it, and its arguments.
///
/// Besides the behavior's own arguments, `args` may carry item options: `wait` (bool; false =
/// start it and move on, so it runs in parallel), `on_failure` (`"abort"` the mission, the
/// default, or `"continue"` with the next item) and `run_for_s` (stop the behavior after this
/// many seconds and count the item done, for behaviors that never end, like follow_reference).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, JsonSchema, utoipa::ToSchema)]
pub struct MissionItem {
    /// A registered behavior (`GET /api/behaviors`).
    pub behavior: String,
    /// One of the behavior's methods; `__call__` when absent.
    #[serde(default = "default_method")]
    pub method: String,
    /// Keyword arguments of the method, plus the item options.
    #[serde(default)]
    #[schema(value_type = Object)]
    pub args: Map<String, Value>,
}

/// What a failed item does to its mission.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum OnFailure {
    /// Stop the mission, hold the vehicle, report why.
    #[default]
    Abort,
    /// Record the failure and go on with the next item.
    Continue,
}

/// Item options, taken out of `args` before the behavior sees them.
#[derive(Debug, Clone, Copy, PartialEq, Default, Serialize, Deserialize)]
pub struct ItemOptions {
    pub wait: bool,
    pub on_failure: OnFailure,
    pub run_for_s: Option<f64>,
}

/// A mission that passed validation; nothing in it can be rejected for its form any more.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ValidMission {
    pub target: String,
    pub items: Vec<PlanItem>,
    pub warnings: Vec<String>,
}

impl ValidMission {
    /// The mission as written (method defaults filled in).
    pub fn as_written(&self) -> Result<Mission, serde_json::Error> {
        Ok(Mission {
            target: self.target.clone(),
            plan: self
                .items
                .iter()
                .map(PlanItem::written)
                .collect::<Result<_, _>>()?,
        })
    }
}

/// MissionUpdate actions, numbered as in the thesis (Table 4.2).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum Action {
    Execute = 0,
    Load = 1,
    Start = 2,
    Pause = 3,
    Resume = 4,
    Stop = 5,
    NextItem = 6,
    JumpTo = 7,
    Insert = 8,
    Modify = 9,
    Remove = 10,
    Reset = 11,
}

impl Action {
    pub const ALL: [Action; 12] = [
        Action::Execute,
        Action::Load,
        Action::Start,
        Action::Pause,
        Action::Resume,
        Action::Stop,
        Action::NextItem,
        Action::JumpTo,
        Action::Insert,
        Action::Modify,
        Action::Remove,
        Action::Reset,
    ];

    pub fn name(self) -> &'static str {
        match self {
            Action::Execute => "EXECUTE",
            Action::Load => "LOAD",
            Action::Start => "START",
            Action::Pause => "PAUSE",
            Action::Resume => "RESUME",
            Action::Stop => "STOP",
            Action::NextItem => "NEXT_ITEM",
            Action::JumpTo => "JUMP_TO",
            Action::Insert => "INSERT",
            Action::Modify => "MODIFY",
            Action::Remove => "REMOVE",
            Action::Reset => "RESET",
        }
    }

    pub fn from_number(n: u64) -> Option<Self> {
        Self::ALL.into_iter().find(|a| *a as u64 == n)
    }

    pub fn from_name(s: &str) -> Option<Self> {
        Self::ALL
            .into_iter()
            .find(|a| a.name().eq_ignore_ascii_case(s))
    }
}

impl std::fmt::Display for Action {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{} ({})", self.name(), *self as u8)
    }
}

impl Serialize for Action {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(*self as u8)
    }
}

impl<'de> Deserialize<'de> for Action {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let bad = || {
            serde::de::Error::custom(
                "unknown action: use 0 EXECUTE, 1 LOAD, 2 START, 3 PAUSE, 4 RESUME, 5 STOP, \
                 6 NEXT_ITEM, 7 JUMP_TO, 8 INSERT, 9 MODIFY, 10 REMOVE, 11 RESET",
            )
        };
        match Value::deserialize(d)? {
            Value::Number(n) => n.as_u64().and_then(Self::from_number).ok_or_else(bad),
            Value::String(s) => Self::from_name(&s).ok_or_else(bad),
            _ => Err(bad()),
        }
    }
}

/// The MissionUpdate message (`as2_msgs/MissionUpdate`), accepted as is.
///
/// `drone_id` may be a string (`drone_0`) or, as in older Aerostack2, a number `n` meaning
/// `drone_n`; absent = the only drone. `mission_id` absent = for LOAD/EXECUTE a new id, for other
/// actions the current mission. `item_id` absent = 0 for START, the end of the plan for INSERT.
/// `mission` is a JSON string (as in the ROS message) or a JSON object. `type` is taken for
/// `action` (its name before Aerostack2 renamed it). Any other key is refused: a misspelt
/// `mision_id` must not act on the current mission.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct MissionUpdate {
    #[serde(default, deserialize_with = "drone_id_of")]
    pub drone_id: Option<String>,
    #[serde(default)]
    pub mission_id: Option<i64>,
    #[serde(default)]
    pub item_id: Option<i64>,
    /// 0 EXECUTE ... 11 RESET, or the action's name.
    #[schema(value_type = u8)]
    #[serde(alias = "type")]
    pub action: Action,
    #[serde(default, deserialize_with = "mission_of")]
    #[schema(value_type = Object)]
    pub mission: Option<Value>,
}

fn drone_id_of<'de, D: Deserializer<'de>>(d: D) -> Result<Option<String>, D::Error> {
    match Option::<Value>::deserialize(d)? {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) if s.is_empty() => Ok(None),
        Some(Value::String(s)) => Ok(Some(s)),
        Some(Value::Number(n)) if n.is_u64() => Ok(Some(format!("drone_{n}"))),
        Some(other) => Err(serde::de::Error::custom(format!(
            "drone_id must be a string like \"drone_0\" or a number, got {other}"
        ))),
    }
}

fn mission_of<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Value>, D::Error> {
    match Option::<Value>::deserialize(d)? {
        None | Some(Value::Null) => Ok(None),
        Some(Value::String(s)) if s.trim().is_empty() => Ok(None),
        Some(Value::String(s)) => serde_json::from_str(&s)
            .map(Some)
            .map_err(|e| serde::de::Error::custom(format!("mission is not valid JSON: {e}"))),
        Some(v) => Ok(Some(v)),
    }
}

/// Executor state as the thesis numbers it: 0 idle, 1 running, 2 paused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum ExecState {
    #[default]
    Idle = 0,
    Running = 1,
    Paused = 2,
}

impl Serialize for ExecState {
    fn serialize<S: Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.serialize_u8(*self as u8)
    }
}

impl<'de> Deserialize<'de> for ExecState {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        match u8::deserialize(d)? {
            0 => Ok(Self::Idle),
            1 => Ok(Self::Running),
            2 => Ok(Self::Paused),
            n => Err(serde::de::Error::custom(format!("unknown state {n}"))),
        }
    }
}

/// How a plan item ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum ItemResult {
    /// Done, or ran its `run_for_s`.
    Succeeded,
    Failed,
    Aborted,
    /// Left by NEXT_ITEM or JUMP_TO.
    Stopped,
    /// A `wait: false` item whose behavior is still running in parallel.
    Started,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct DoneResult {
    /// Index of the item in the plan when it ran.
    pub item: usize,
    pub behavior: String,
    pub result: ItemResult,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub reason: Option<String>,
    /// The behavior's stable failure code (`planner_no_path`, `link_lost`, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub code: Option<FailureCode>,
}

/// Mission status: the thesis's fields first, then Kestrel's additions.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize, utoipa::ToSchema)]
pub struct MissionStatus {
    /// 0 idle, 1 running, 2 paused.
    #[schema(value_type = u8)]
    pub state: ExecState,
    pub pending_items: usize,
    pub done_items: usize,
    pub current_item: Option<MissionItem>,
    #[schema(value_type = Object)]
    pub feedback_current: Option<Value>,
    /// The running mission, or the last one run or loaded.
    pub mission_id: Option<u32>,
    /// Index of the current item while running or paused.
    pub item_index: Option<usize>,
    pub done_results: Vec<DoneResult>,
    pub last_error: Option<String>,
    /// The stable code of `last_error` when a behavior's failure caused it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    #[schema(value_type = Option<String>)]
    pub last_error_code: Option<FailureCode>,
}

impl MissionStatus {
    /// How mission `id` ended, once it has: `Ok` when it ran to its end without error.
    pub fn outcome(&self, id: u32) -> Option<Result<(), MissionEnded>> {
        if self.mission_id != Some(id) || self.state != ExecState::Idle {
            return None;
        }
        if let Some(e) = &self.last_error {
            return Some(Err(MissionEnded::Failed(e.clone())));
        }
        if self.pending_items == 0 && self.done_items > 0 {
            Some(Ok(()))
        } else {
            Some(Err(MissionEnded::Stopped(id)))
        }
    }
}

/// How a mission that did not run to its end ended.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum MissionEnded {
    /// The error that ended it (the executor's last error), in its words.
    #[error("{0}")]
    Failed(String),
    /// It was stopped before its end.
    #[error("mission {0} was stopped")]
    Stopped(u32),
}
