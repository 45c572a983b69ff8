//! Coverage for the fleet: a polygon swept by several drones, one boustrophedon piece each, with
//! the ends of neighbouring pieces pulled apart so that no two drones finish (or start) at the
//! same spot. The API reaches the coverage planner through here.
//!
//! In: the polygon (ENU m), street spacing (m), sweep angle (rad, `None` = across the narrowest
//! direction), each drone's start (ENU m) and the flight height (m). Out: a [`FleetCoverage`].

use crate::planning::coverage::plan_coverage_until;
use crate::planning::coverage_ends::{length_m, separate_piece_ends};
pub use crate::planning::CoverageError;
use crate::types::Vec3;
use nalgebra::Vector2;
use std::sync::atomic::AtomicBool;

/// Pieces of one sweep meet at their cuts; their ends are kept this far apart (m).
pub const PIECE_END_SEPARATION_M: f64 = 2.0;

/// One piece per drone, in the order of the starts.
#[derive(Debug, Clone, PartialEq)]
pub struct FleetCoverage {
    pub angle_rad: f64,
    pub pieces: Vec<Vec<Vec3>>,
    pub lengths_m: Vec<f64>,
    /// Flight from each drone's start to its first point (m).
    pub transit_m: Vec<f64>,
    /// Spacing actually used (streets spread evenly over the polygon), m.
    pub street_spacing_m: f64,
}

/// Plans the sweep; synchronous and CPU-bound (run it off the control loop and the API's
/// threads). Gives up with `CoverageError::Cancelled` soon after `cancel` is set.
pub fn plan(
    polygon: &[Vector2<f64>],
    spacing_m: f64,
    angle_rad: Option<f64>,
    starts: &[Vector2<f64>],
    height_m: f64,
    cancel: &AtomicBool,
) -> Result<FleetCoverage, CoverageError> {
    let plan = plan_coverage_until(polygon, spacing_m, angle_rad, starts, height_m, cancel)?;
    let mut pieces = plan.per_drone;
    separate_piece_ends(&mut pieces, PIECE_END_SEPARATION_M);
    Ok(FleetCoverage {
        angle_rad: plan.angle_rad,
        lengths_m: pieces.iter().map(|p| length_m(p)).collect(),
        transit_m: (0..pieces.len())
            .map(|i| plan.transit_m.get(i).copied().unwrap_or(0.0))
            .collect(),
        pieces,
        street_spacing_m: plan.street_spacing_m,
    })
}
