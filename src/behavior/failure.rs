//! Why a behavior refused a goal or ended without success: a stable machine-readable code
//! (clients, mission status, events and the API's error bodies switch on it) and a message for
//! people.
//!
//! In: the errors of frames, planning and the platform, and each behavior's own reasons.
//! Out: [`Failure`], carried unchanged by behavior results, mission status and HTTP errors.

use super::goal::GoalError;
use crate::estimator::frames::FrameError;
use crate::planning::PlanError;
use serde::{Deserialize, Serialize};

/// Stable codes; never renamed (scripts and the ground station depend on them).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(rename_all = "snake_case")]
pub enum FailureCode {
    /// The goal's arguments cannot be parsed or are out of range.
    InvalidGoal,
    /// A motion behavior needs the vehicle airborne and armed.
    NotFlying,
    /// The vehicle is not ready to fly (no position estimate, autopilot not ready).
    NotReady,
    /// A frame the goal names is unknown or cannot be resolved now.
    FrameUnresolved,
    /// Mapping is off: nothing to plan on.
    NoMap,
    GoalOutsideMap,
    /// The goal is in, or within the safety distance of, an obstacle (or unknown when unknown
    /// space is not to be flown).
    GoalInObstacle,
    StartOutsideMap,
    StartInObstacle,
    PlannerNoPath,
    PlannerTimeout,
    PlannerUnavailable,
    /// No topological graph is loaded for the graph planner.
    NoGraph,
    /// The vehicle got no closer to its goal for the configured time.
    NoProgress,
    /// The vehicle got no closer to its goal for the configured time because the safety stage
    /// holds it for a fleet-bus peer's drone that fell silent while flying (no majority of the
    /// fleet heard, as with two Kestrels): the mission pauses, holding, until the peer is heard
    /// again or an operator lands the vehicle.
    FleetPeerLost,
    /// The autopilot refused a command (arming, mode, gimbal, camera).
    AutopilotRefused,
    /// The autopilot did not answer a command in time.
    AutopilotSilent,
    /// The link to the autopilot was lost.
    LinkLost,
    /// The vehicle touched an obstacle or another vehicle.
    Crashed,
    /// The vehicle came within its radius of an obstacle of the virtual world it flies in
    /// (`kestrel run --virtual-world`); it is unharmed and holds where it is.
    VirtualCollision,
    /// The goal or the flight would leave the geofence.
    Geofence,
    /// Another behavior took the same resource.
    Preempted,
    /// Stopped by an operator or a mission action.
    Stopped,
    /// Someone else took the vehicle: the autopilot left the mode Kestrel flies it in without
    /// Kestrel asking (a pilot's mode switch, a ground station, a disarm in flight).
    PilotTakeover,
    /// Anything else (a bug if seen).
    Internal,
}

impl FailureCode {
    pub const ALL: [FailureCode; 25] = [
        FailureCode::InvalidGoal,
        FailureCode::NotFlying,
        FailureCode::NotReady,
        FailureCode::FrameUnresolved,
        FailureCode::NoMap,
        FailureCode::GoalOutsideMap,
        FailureCode::GoalInObstacle,
        FailureCode::StartOutsideMap,
        FailureCode::StartInObstacle,
        FailureCode::PlannerNoPath,
        FailureCode::PlannerTimeout,
        FailureCode::PlannerUnavailable,
        FailureCode::NoGraph,
        FailureCode::NoProgress,
        FailureCode::FleetPeerLost,
        FailureCode::AutopilotRefused,
        FailureCode::AutopilotSilent,
        FailureCode::LinkLost,
        FailureCode::Crashed,
        FailureCode::VirtualCollision,
        FailureCode::Geofence,
        FailureCode::Preempted,
        FailureCode::Stopped,
        FailureCode::PilotTakeover,
        FailureCode::Internal,
    ];

    /// The code as clients see it (the same as its JSON form).
    pub fn as_str(self) -> &'static str {
        match self {
            FailureCode::InvalidGoal => "invalid_goal",
            FailureCode::NotFlying => "not_flying",
            FailureCode::NotReady => "not_ready",
            FailureCode::FrameUnresolved => "frame_unresolved",
            FailureCode::NoMap => "no_map",
            FailureCode::GoalOutsideMap => "goal_outside_map",
            FailureCode::GoalInObstacle => "goal_in_obstacle",
            FailureCode::StartOutsideMap => "start_outside_map",
            FailureCode::StartInObstacle => "start_in_obstacle",
            FailureCode::PlannerNoPath => "planner_no_path",
            FailureCode::PlannerTimeout => "planner_timeout",
            FailureCode::PlannerUnavailable => "planner_unavailable",
            FailureCode::NoGraph => "no_graph",
            FailureCode::NoProgress => "no_progress",
            FailureCode::FleetPeerLost => "fleet_peer_lost",
            FailureCode::AutopilotRefused => "autopilot_refused",
            FailureCode::AutopilotSilent => "autopilot_silent",
            FailureCode::LinkLost => "link_lost",
            FailureCode::Crashed => "crashed",
            FailureCode::VirtualCollision => "virtual_collision",
            FailureCode::Geofence => "geofence",
            FailureCode::Preempted => "preempted",
            FailureCode::Stopped => "stopped",
            FailureCode::PilotTakeover => "pilot_takeover",
            FailureCode::Internal => "internal",
        }
    }
}

/// A refusal or an unsuccessful end.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize, thiserror::Error)]
#[error("{message}")]
pub struct Failure {
    pub code: FailureCode,
    pub message: String,
}

impl Failure {
    pub fn new(code: FailureCode, message: impl Into<String>) -> Self {
        Failure {
            code,
            message: message.into(),
        }
    }

    pub fn invalid(message: impl Into<String>) -> Self {
        Self::new(FailureCode::InvalidGoal, message)
    }

    pub fn not_flying() -> Self {
        Self::new(FailureCode::NotFlying, "platform is not flying")
    }

    /// The same failure with `context` before its message (a composite naming its child).
    pub fn within(self, context: &str) -> Self {
        Failure {
            code: self.code,
            message: format!("{context}: {}", self.message),
        }
    }
}

/// A goal refused by its own checks, with the goal's words (they name the argument first).
impl From<GoalError> for Failure {
    fn from(e: GoalError) -> Self {
        Self::invalid(e.to_string())
    }
}

impl From<FrameError> for Failure {
    fn from(e: FrameError) -> Self {
        Self::new(FailureCode::FrameUnresolved, e.to_string())
    }
}

impl From<PlanError> for Failure {
    fn from(e: PlanError) -> Self {
        let code = match &e {
            PlanError::StartOccupied => FailureCode::StartInObstacle,
            PlanError::GoalOccupied => FailureCode::GoalInObstacle,
            PlanError::StartOutsideMap => FailureCode::StartOutsideMap,
            PlanError::GoalOutsideMap => FailureCode::GoalOutsideMap,
            PlanError::NoPath => FailureCode::PlannerNoPath,
            PlanError::Timeout { .. } | PlanError::StaleMap { .. } => FailureCode::PlannerTimeout,
            PlanError::Cancelled | PlanError::Unavailable(_) => FailureCode::PlannerUnavailable,
            PlanError::NoGraph => FailureCode::NoGraph,
            PlanError::InvalidRequest(_) => FailureCode::InvalidGoal,
        };
        Self::new(code, format!("no path to the goal: {e}"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn codes_serialise_as_stable_snake_case_names() {
        let f: Failure = PlanError::GoalOccupied.into();
        let json = serde_json::to_value(&f).unwrap_or_default();
        assert_eq!(json["code"], "goal_in_obstacle");
        assert_eq!(
            serde_json::to_value(FailureCode::PlannerNoPath).unwrap_or_default(),
            "planner_no_path"
        );
        assert_eq!(f.within("navigate_to").code, FailureCode::GoalInObstacle);
    }

    #[test]
    fn as_str_is_the_json_name_of_every_code() {
        for code in FailureCode::ALL {
            assert_eq!(
                serde_json::to_value(code).unwrap_or_default(),
                code.as_str(),
                "{code:?}"
            );
        }
    }
}
