//! Path planning on the occupancy grid and the topological graph.
//!
//! In: a [`PlanRequest`] (start, goal, flight height, safety distance, unknown-cell policy,
//! planner kind), a [`PlanningMap`] (grid + distance field + Voronoi diagram + optional graph,
//! built once per map update) and a [`PlanBudget`] (expansion limit, cancel and deadline flags set
//! by the caller). Out: a [`PlannedPath`] (a short list of smoothed waypoints at the flight height
//! with length, cost and minimum clearance) or a typed [`PlanError`].
//!
//! Planners never read the clock: a deadline reaches them as a flag the caller's timer sets.
//! [`coverage`] is separate: it sweeps a polygon for area inspection and splits it among drones.
//!
//! Grid search is 8-connected (no corner cutting past a blocked side cell) with costs in metres
//! (orthogonal step = resolution, diagonal = resolution * sqrt 2). A cell is blocked when it is
//! occupied (`>= occupied_threshold`), unknown under [`UnknownPolicy::Blocked`], or within
//! `safety_distance_m` of an occupied cell (round inflation from the exact distance transform).
//! A start inside the inflated zone may climb out along strictly increasing clearance. Unknown
//! cells are not obstacles for the distance field (an exploring drone must be able to approach a
//! frontier); the unknown policy only decides whether they may be entered.
//!
//! Planners keep their search buffers between calls behind a `Mutex`; a call that finds them
//! busy (another thread planning with the same planner) uses fresh buffers instead of waiting.

pub mod coverage;
pub mod coverage_ends;
pub mod distance;
mod graph_planner;
mod grid_planners;
mod map;
mod search;
mod simplify;
pub mod worker;

use std::sync::atomic::{AtomicBool, Ordering};

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

pub use coverage::{plan_coverage, CoverageError, CoveragePlan};
pub use distance::DistanceField;
pub use graph_planner::GraphAStarPlanner;
pub use grid_planners::{
    AStarPlanner, DijkstraPlanner, VoronoiPlanner, VORONOI_OFF_DIAGRAM_PENALTY,
};
pub use map::{PlanningMap, DEFAULT_OCCUPIED_THRESHOLD};

/// One planner plugin. Contract: `plan` is synchronous, reads no clock, does no I/O, and returns
/// either a path whose waypoints avoid blocked cells or exactly one [`PlanError`]. It checks
/// `budget.cancel` / `budget.deadline_passed` periodically and stops with `Cancelled` /
/// `Timeout`. A planner asked for a kind it does not implement still plans with its own method
/// (use [`Planners`] to dispatch on `request.kind`).
pub trait PathPlanner {
    fn plan(
        &self,
        request: &PlanRequest,
        map: &PlanningMap,
        budget: &PlanBudget<'_>,
    ) -> Result<PlannedPath, PlanError>;
}

/// Which planner to use.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum PlannerKind {
    /// A* on the grid, octile heuristic: shortest path.
    #[default]
    AStar,
    /// Dijkstra on the grid: same optimal cost as A*, explores more.
    Dijkstra,
    /// Follows the generalised Voronoi diagram: maximises clearance.
    Voronoi,
    /// A* on the topological graph.
    GraphAStar,
}

/// Largest `extra` of [`UnknownPolicy::AllowedWithCost`] (keeps fixed-point costs in range).
pub const MAX_UNKNOWN_EXTRA_COST: f64 = 1000.0;

/// How unknown (`-1`) cells are treated.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum UnknownPolicy {
    Blocked,
    /// Traversable; entering one costs `1 + extra` times a known free cell
    /// (`0 <= extra <= MAX_UNKNOWN_EXTRA_COST`).
    AllowedWithCost(f64),
}

/// A path request.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PlanRequest {
    pub start_enu_m: Vector3<f64>,
    pub goal_enu_m: Vector3<f64>,
    /// Height (ENU z, metres) of every waypoint of grid plans.
    pub flight_height_m: f64,
    /// Cells this close (centre to centre, metres) to an obstacle are blocked.
    pub safety_distance_m: f64,
    pub unknown: UnknownPolicy,
    pub kind: PlannerKind,
    /// Refuse maps older than this (seconds), checked against `PlanBudget::now_s`.
    #[serde(default)]
    pub max_map_age_s: Option<f64>,
    /// Unknown cells this close (m) to an obstacle count as obstacle: the hidden side of an
    /// obstacle seen from one side only. 0 leaves unknown cells as they are.
    #[serde(default)]
    pub shadow_m: f64,
}

/// Limits of one planning call. The caller measures time; planners only read these.
/// `Default` is unlimited: no expansion limit, no flags, no staleness check.
#[derive(Debug, Clone, Copy)]
pub struct PlanBudget<'a> {
    /// Node expansions before giving up with [`PlanError::Timeout`].
    pub max_expansions: usize,
    /// Set by whoever cancels the request.
    pub cancel: Option<&'a AtomicBool>,
    /// Set by the caller's timer when the wall-clock deadline passes.
    pub deadline_passed: Option<&'a AtomicBool>,
    /// Current time (seconds, same clock as [`PlanningMap::stamp_s`]) for the staleness check.
    pub now_s: Option<f64>,
}

impl Default for PlanBudget<'_> {
    fn default() -> Self {
        PlanBudget {
            max_expansions: usize::MAX,
            cancel: None,
            deadline_passed: None,
            now_s: None,
        }
    }
}

impl<'a> PlanBudget<'a> {
    /// Only an expansion limit.
    pub fn expansions(max_expansions: usize) -> Self {
        PlanBudget {
            max_expansions,
            ..PlanBudget::default()
        }
    }

    /// `Err` if cancelled or past the deadline.
    pub(crate) fn check_flags(&self, expansions: usize) -> Result<(), PlanError> {
        if self.cancel.is_some_and(|c| c.load(Ordering::Relaxed)) {
            return Err(PlanError::Cancelled);
        }
        if self
            .deadline_passed
            .is_some_and(|c| c.load(Ordering::Relaxed))
        {
            return Err(PlanError::Timeout { expansions });
        }
        Ok(())
    }
}

/// A planned path.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlannedPath {
    /// Waypoints after the start (the start is not repeated), the last one being the goal.
    pub waypoints_enu_m: Vec<Vector3<f64>>,
    /// Cells (or graph nodes) of the raw search path, start and goal included.
    pub raw_cells: usize,
    /// Length of the polyline start -> waypoints, metres.
    pub length_m: f64,
    /// Search cost of the raw path (metres weighted by the planner's cell costs).
    pub cost: f64,
    /// Smallest obstacle distance along the waypoint polyline, metres (the grid's diagonal
    /// when the map has no obstacle).
    pub min_clearance_m: f64,
}

/// Why a plan failed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum PlanError {
    #[error("start is in an occupied cell")]
    StartOccupied,
    #[error("goal is occupied, unknown-and-blocked, or within the safety distance of an obstacle")]
    GoalOccupied,
    #[error("start is outside the map")]
    StartOutsideMap,
    #[error("goal is outside the map")]
    GoalOutsideMap,
    #[error("no path between start and goal")]
    NoPath,
    #[error("planning budget exhausted after {expansions} expansions")]
    Timeout { expansions: usize },
    #[error("planning cancelled")]
    Cancelled,
    #[error("map is {age_s:.1} s old, limit {max_age_s:.1} s")]
    StaleMap { age_s: f64, max_age_s: f64 },
    #[error("no topological graph loaded")]
    NoGraph,
    #[error("invalid request: {0}")]
    InvalidRequest(String),
    #[error("planner unavailable: {0}")]
    Unavailable(String),
}

impl PlanRequest {
    /// Checks numbers and the map's age.
    pub(crate) fn validate(
        &self,
        map: &PlanningMap,
        budget: &PlanBudget<'_>,
    ) -> Result<(), PlanError> {
        let finite3 = |v: &Vector3<f64>| v.iter().all(|c| c.is_finite());
        if !finite3(&self.start_enu_m)
            || !finite3(&self.goal_enu_m)
            || !self.flight_height_m.is_finite()
        {
            return Err(PlanError::InvalidRequest(
                "start, goal and height must be finite".into(),
            ));
        }
        if !(self.safety_distance_m.is_finite() && self.safety_distance_m >= 0.0) {
            return Err(PlanError::InvalidRequest(
                "safety_distance_m must be >= 0".into(),
            ));
        }
        if let UnknownPolicy::AllowedWithCost(c) = self.unknown {
            if !(c.is_finite() && (0.0..=MAX_UNKNOWN_EXTRA_COST).contains(&c)) {
                return Err(PlanError::InvalidRequest(format!(
                    "unknown cell cost must be in 0..={MAX_UNKNOWN_EXTRA_COST}"
                )));
            }
        }
        if let (Some(max_age_s), Some(now), Some(stamp)) =
            (self.max_map_age_s, budget.now_s, map.stamp_s())
        {
            let age_s = now - stamp;
            if age_s > max_age_s {
                return Err(PlanError::StaleMap { age_s, max_age_s });
            }
        }
        Ok(())
    }
}

/// All planners behind one [`PathPlanner`], dispatching on `request.kind`.
#[derive(Debug, Default)]
pub struct Planners {
    pub a_star: AStarPlanner,
    pub dijkstra: DijkstraPlanner,
    pub voronoi: VoronoiPlanner,
    pub graph: GraphAStarPlanner,
}

impl PathPlanner for Planners {
    fn plan(
        &self,
        request: &PlanRequest,
        map: &PlanningMap,
        budget: &PlanBudget<'_>,
    ) -> Result<PlannedPath, PlanError> {
        match request.kind {
            PlannerKind::AStar => self.a_star.plan(request, map, budget),
            PlannerKind::Dijkstra => self.dijkstra.plan(request, map, budget),
            PlannerKind::Voronoi => self.voronoi.plan(request, map, budget),
            PlannerKind::GraphAStar => self.graph.plan(request, map, budget),
        }
    }
}
