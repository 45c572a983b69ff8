//! The goal of `navigate_to`: the point, its frame and speed, the planner and the rules for
//! obstacles and unknown space, checked before anything flies.
//!
//! In: the JSON arguments of a mission item or an API call. Out: a checked [`NavigateToGoal`],
//! or the field and rule it breaks; its target and speed for mission validation.

use crate::behavior::goal::{
    check_finite, check_non_negative, check_positive, frame_or_earth, FramedPoint, GoalError,
    YawArgs,
};
use crate::behavior::registry::Goal;
use crate::planning::{PlannerKind, MAX_UNKNOWN_EXTRA_COST};
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// The planner, by Aerostack2's plugin names.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum PlannerArg {
    /// Shortest path (A* on the grid).
    #[default]
    AStar,
    /// Shortest path, exhaustive search.
    Dijkstra,
    /// Largest clearance (along the Voronoi diagram).
    Voronoi,
    /// A* on the topological graph (`[map] graph`).
    GraphAStar,
}

impl From<PlannerArg> for PlannerKind {
    fn from(p: PlannerArg) -> Self {
        match p {
            PlannerArg::AStar => PlannerKind::AStar,
            PlannerArg::Dijkstra => PlannerKind::Dijkstra,
            PlannerArg::Voronoi => PlannerKind::Voronoi,
            PlannerArg::GraphAStar => PlannerKind::GraphAStar,
        }
    }
}

/// What unknown (never observed) cells are to the planner and to the flight.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum UnknownArg {
    /// Planned through at `unknown_cost` extra, flown only once seen: the vehicle never goes
    /// farther than it can stop inside space its sensors observed free (with the safety
    /// distance), turning at `sense_rate` to look where it must go, and replans as obstacles
    /// appear. Safe with any range sensor, however sparse.
    #[default]
    #[serde(alias = "allowed")]
    Sensed,
    /// Obstacles: only mapped free space is flown.
    Blocked,
    /// Planned through at `unknown_cost` extra and flown at full speed without looking first:
    /// only for space known to be clear (a vehicle without range sensors). Unsafe otherwise.
    Blind,
}

#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NavigateToGoal {
    /// Goal (m) in `frame_id`; `z` is the height of the whole path.
    pub x: f64,
    pub y: f64,
    pub z: f64,
    /// Cruise speed (m/s).
    pub speed: f64,
    #[serde(flatten)]
    pub yaw: YawArgs,
    /// Frame of the goal, resolved once when the behavior starts; `earth` when absent.
    #[serde(default)]
    pub frame_id: Option<String>,
    #[serde(default)]
    pub planner: PlannerArg,
    /// Least distance (m) between the vehicle's centre and mapped obstacles. Paths are planned
    /// one map cell wider; the path ahead is replanned when an obstacle appears within it.
    #[serde(default = "default_safety_distance")]
    pub safety_distance: f64,
    #[serde(default)]
    pub unknown: UnknownArg,
    /// Extra cost of crossing an unknown cell, relative to a free one (0..=1000).
    #[serde(default = "default_unknown_cost")]
    pub unknown_cost: f64,
    /// Turn continuously at this rate (rad/s, CCW positive) while flying, so that sparse range
    /// sensors (a four-beam multi-ranger) sweep all around; overrides `yaw_mode`.
    #[serde(default)]
    pub spin_rate: Option<f64>,
    /// Turn rate (rad/s, > 0) while waiting to see the path ahead (`unknown: sensed`).
    #[serde(default = "default_sense_rate")]
    pub sense_rate: f64,
}

fn default_sense_rate() -> f64 {
    0.6
}

fn default_safety_distance() -> f64 {
    0.5
}

fn default_unknown_cost() -> f64 {
    1.0
}

impl Goal for NavigateToGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_finite("x, y, z", &[self.x, self.y, self.z])?;
        check_positive("speed", self.speed, "m/s")?;
        check_non_negative("safety_distance", self.safety_distance, "metres")?;
        if !(0.0..=MAX_UNKNOWN_EXTRA_COST).contains(&self.unknown_cost) {
            return Err(GoalError::UnknownCost {
                value: self.unknown_cost,
                max: MAX_UNKNOWN_EXTRA_COST,
            });
        }
        if let Some(rate) = self.spin_rate {
            check_finite("spin_rate", &[rate])?;
        }
        check_positive("sense_rate", self.sense_rate, "rad/s")?;
        self.yaw.check()
    }
    fn targets(&self) -> Vec<FramedPoint> {
        vec![FramedPoint {
            position_m: Vec3::new(self.x, self.y, self.z),
            frame_id: frame_or_earth(&self.frame_id),
        }]
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
}
