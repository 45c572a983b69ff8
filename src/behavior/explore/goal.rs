//! The `explore` goal: its arguments, their defaults (the thesis's simulation values) and
//! their checks.

use super::super::goal::{check_positive, check_within, GoalError};
use super::super::registry::Goal;
use crate::exploration::online::allocation::AllocatorKind;
use crate::exploration::online::settings::SettingsOverride;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Every field has the thesis's simulation value as its default (Table 5.3).
#[derive(Debug, Clone, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct ExploreGoal {
    /// Flight height above the takeoff point (m).
    pub height: f64,
    /// Cruise speed (m/s). While the position estimate drifts, at most what lets the turning
    /// beams see ahead before the drone gets there ([`ExploreGoal::cruise_mps`]).
    pub speed: f64,
    /// Steady turn while exploring (rad/s, 0..=2), so the beams sweep all around; 0 keeps the
    /// heading (then only a 360-beam sensor sees sideways).
    pub spin_rate: f64,
    /// How far the range beams see (m; the multiranger's 4 m). Sets the cruise speed while
    /// the estimate drifts.
    pub beam_range: f64,
    /// Least distance from obstacles and from unobserved space (m).
    pub safety_distance: f64,
    /// Closer than this to another drone at the same height, one of the two gives way (m).
    pub drone_safety_distance: f64,
    /// Which frontier to take next.
    pub allocator: AllocatorKind,
    /// Ask the allocator again this often while flying to a frontier (s).
    pub retarget_period: f64,
    /// Land when no frontier is left.
    pub land_when_done: bool,
    /// How the heading moves: `spin` (a steady turn) or `align` (a beam axis along the travel).
    pub heading: HeadingMode,
    /// Frontiers shorter than this (m) are not flown to while longer ones are left (the
    /// thesis drops them: 1.5 m).
    pub min_frontier_length: f64,
    /// Frontiers shorter than this (m) are never flown to, unless at least half as long and
    /// leading on to a large unknown region (a gap between obstacles); between this and
    /// `min_frontier_length` they are explored last. Lower it (to 0.5 m) for a more thorough
    /// end at the cost of time.
    pub end_frontier_length: f64,
    /// Fly along frontiers of 2 m or more from end to end, turning the way that sweeps the
    /// unknown side best (the beams clear them on the way), instead of to their middle and
    /// waiting there for the turn to sweep them.
    pub sweep_along: bool,
    /// The exploration's weights for this drone (`edge_bonus_m`, `others_penalty_m`, ...):
    /// each field given replaces the config's `[exploration]` value; those left out keep it.
    pub settings: SettingsOverride,
}

/// How the explorer turns its beams.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum HeadingMode {
    /// A steady turn at `spin_rate`: the four beams sweep all around, all the time.
    #[default]
    Spin,
    /// A beam axis along the direction of travel (the side beams sweep the widest band); a
    /// steady turn while hovering.
    Align,
}

impl Default for ExploreGoal {
    fn default() -> Self {
        ExploreGoal {
            height: 1.0,
            speed: 0.75,
            spin_rate: 0.15,
            beam_range: 4.0,
            safety_distance: 0.4,
            drone_safety_distance: 2.0,
            allocator: AllocatorKind::default(),
            retarget_period: 2.0,
            land_when_done: true,
            heading: HeadingMode::default(),
            min_frontier_length: 1.5,
            end_frontier_length: 1.0,
            sweep_along: true,
            settings: SettingsOverride::default(),
        }
    }
}

/// Room kept between where the beams see an obstacle and where the drone must have stopped
/// (m): the safety stage's 0.3 m from a hit and the braking from a sighted speed.
pub const SIGHT_STOP_M: f64 = 0.5;

impl ExploreGoal {
    /// The cruise speed (m/s). Where the estimate drifts (`estimate_drift_mps` > 0) the map
    /// can hold a pole metres from where it stands in the drone's present frame, and only what
    /// the beams hit lately is placed right: four beams turning at `spin_rate` cross every
    /// bearing once a quarter turn, so the drone flies no faster than covers `beam_range` less
    /// [`SIGHT_STOP_M`] in a quarter turn, and an obstacle ahead is hit by a beam before the
    /// drone is within its stopping room (0.33 m/s at the defaults). Otherwise `speed`, and
    /// `speed` too without a steady turn (`align`, or `spin_rate` 0) to pace.
    pub fn cruise_mps(&self, estimate_drift_mps: f64) -> f64 {
        let turning = self.heading == HeadingMode::Spin && self.spin_rate > 0.0;
        if !(estimate_drift_mps > 0.0 && turning) {
            return self.speed;
        }
        let quarter_turn_s = std::f64::consts::FRAC_PI_2 / self.spin_rate;
        let sighted = (self.beam_range - SIGHT_STOP_M).max(0.0) / quarter_turn_s;
        self.speed.min(sighted.max(0.05))
    }
}

impl Goal for ExploreGoal {
    fn check(&self) -> Result<(), GoalError> {
        check_within("height", self.height, 0.2, 100.0, "m")?;
        check_positive("speed", self.speed, "m/s")?;
        check_within("spin_rate", self.spin_rate, 0.0, 2.0, "rad/s")?;
        check_within("beam_range", self.beam_range, 0.5, 50.0, "m")?;
        check_within("safety_distance", self.safety_distance, 0.1, 5.0, "m")?;
        check_within(
            "drone_safety_distance",
            self.drone_safety_distance,
            0.5,
            50.0,
            "m",
        )?;
        check_within("retarget_period", self.retarget_period, 0.2, 60.0, "s")?;
        check_within(
            "min_frontier_length",
            self.min_frontier_length,
            0.1,
            20.0,
            "m",
        )?;
        check_within(
            "end_frontier_length",
            self.end_frontier_length,
            0.1,
            self.min_frontier_length,
            "m (at most min_frontier_length)",
        )?;
        self.settings.validate().map_err(|e| GoalError::OutOfRange {
            name: format!("settings.{}", e.field),
            value: e.value,
            lo: e.min,
            hi: e.max,
            unit: e.unit.to_string(),
        })
    }
    fn speeds_mps(&self) -> Vec<f64> {
        vec![self.speed]
    }
    fn heights_m(&self) -> Vec<f64> {
        vec![self.height]
    }
}
