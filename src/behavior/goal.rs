//! Goal pieces shared by behaviors: framed points and yaw modes, parsed from JSON arguments.

use super::registry::ParsedGoal;
use super::{Behavior, BehaviorContext, Failure, Step};
use crate::estimator::frames::EARTH;
use crate::types::GeoError;
use crate::types::PlatformRequest;
use crate::types::Vec3;
use schemars::JsonSchema;
use serde::{Deserialize, Deserializer, Serialize};

/// How the heading is chosen while moving. Accepts Aerostack2's numbers (0 keep, 1 path
/// facing, 2 fixed yaw) or names (`keep`, `path_facing`, `fixed`, `face_point`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum YawMode {
    #[default]
    Keep,
    PathFacing,
    Fixed,
    FacePoint,
}

impl<'de> Deserialize<'de> for YawMode {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        #[derive(Deserialize)]
        #[serde(untagged)]
        enum Raw {
            Number(u64),
            Name(String),
        }
        let bad = |what: String| {
            serde::de::Error::custom(format!(
                "unknown yaw_mode {what}: use 0 keep, 1 path_facing, 2 fixed, or face_point"
            ))
        };
        match Raw::deserialize(d)? {
            Raw::Number(0) => Ok(Self::Keep),
            Raw::Number(1) => Ok(Self::PathFacing),
            Raw::Number(2) => Ok(Self::Fixed),
            Raw::Number(n) => Err(bad(n.to_string())),
            Raw::Name(s) => match s.to_ascii_lowercase().as_str() {
                "keep" | "keep_yaw" => Ok(Self::Keep),
                "path_facing" => Ok(Self::PathFacing),
                "fixed" | "fixed_yaw" => Ok(Self::Fixed),
                "face_point" | "face_reference" => Ok(Self::FacePoint),
                _ => Err(bad(format!("`{s}`"))),
            },
        }
    }
}

/// Yaw settings common to motion goals: `yaw_mode`, `yaw_angle` (rad, in the goal's frame),
/// `face_point` ([x, y, z] m in the goal's frame).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, JsonSchema)]
pub struct YawArgs {
    #[serde(default)]
    pub yaw_mode: YawMode,
    #[serde(default)]
    pub yaw_angle: Option<f64>,
    #[serde(default)]
    pub face_point: Option<[f64; 3]>,
}

/// Yaw after resolution against frames at activation.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum ResolvedYaw {
    Fixed(f64),
    PathFacing,
    Face(Vec3),
}

impl YawArgs {
    pub fn check(&self) -> Result<(), GoalError> {
        match self.yaw_mode {
            YawMode::Fixed if self.yaw_angle.is_none() => Err(GoalError::FixedNeedsAngle),
            YawMode::FacePoint if self.face_point.is_none() => Err(GoalError::FaceNeedsPoint),
            _ => Ok(()),
        }
    }

    pub fn resolve(&self, ctx: &BehaviorContext, frame: &str) -> Result<ResolvedYaw, Failure> {
        Ok(match self.yaw_mode {
            YawMode::Keep => ResolvedYaw::Fixed(ctx.yaw()),
            YawMode::PathFacing => ResolvedYaw::PathFacing,
            YawMode::Fixed => {
                let angle = self
                    .yaw_angle
                    .ok_or_else(|| Failure::invalid("yaw_mode fixed needs yaw_angle (rad)"))?;
                ResolvedYaw::Fixed(ctx.frames.yaw_to_earth(angle, frame, ctx.now)?)
            }
            YawMode::FacePoint => {
                let [x, y, z] = self
                    .face_point
                    .ok_or_else(|| Failure::invalid("yaw_mode face_point needs face_point"))?;
                ResolvedYaw::Face(
                    ctx.frames
                        .point_to_earth(&Vec3::new(x, y, z), frame, ctx.now)?,
                )
            }
        })
    }
}

/// Motion behaviors whose goal is resolved against the vehicle's state when they start and can
/// be replaced in flight. Their lifecycle rules (only when airborne; a new goal replaces the old
/// one, which comes back if it cannot start) are written once, in the [`Behavior`] impl below.
pub(crate) trait InFlight: Send {
    type Goal: Clone + 'static;
    fn goal_mut(&mut self) -> &mut Self::Goal;
    /// Resolves the current goal (frames, yaw) against the vehicle's state, ready to fly it.
    fn start(&mut self, ctx: &BehaviorContext) -> Result<(), Failure>;
    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step;
    fn resume(&mut self, _ctx: &BehaviorContext) {}
    fn goal_enu_m(&self) -> Option<Vec3> {
        None
    }
}

impl<B: InFlight> Behavior for B {
    fn activate(&mut self, ctx: &BehaviorContext) -> Result<(), Failure> {
        if !ctx.is_flying() {
            return Err(Failure::not_flying());
        }
        self.start(ctx)
    }

    fn modify(&mut self, ctx: &BehaviorContext, goal: &ParsedGoal) -> Result<(), Failure> {
        let new = goal.typed::<B::Goal>()?;
        let previous = std::mem::replace(self.goal_mut(), new);
        if let Err(e) = self.start(ctx) {
            *self.goal_mut() = previous;
            return Err(e);
        }
        Ok(())
    }

    fn run(&mut self, ctx: &BehaviorContext, requests: &mut Vec<PlatformRequest>) -> Step {
        InFlight::run(self, ctx, requests)
    }

    fn resume(&mut self, ctx: &BehaviorContext) {
        InFlight::resume(self, ctx);
    }

    fn goal_enu_m(&self) -> Option<Vec3> {
        InFlight::goal_enu_m(self)
    }
}

/// A goal point that may move (a point in a moving frame): its last position in `earth` and the
/// velocity it showed since, fed forward so the vehicle keeps up instead of lagging.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub(crate) struct MovingTarget {
    last: Option<(Vec3, std::time::Duration)>,
}

impl MovingTarget {
    /// Records where the target is now; returns its velocity (zero on the first sample).
    pub fn update(&mut self, target: Vec3, now: std::time::Duration) -> Vec3 {
        let velocity = match self.last {
            Some((prev, t)) if now > t => (target - prev) / (now - t).as_secs_f64(),
            _ => Vec3::zeros(),
        };
        self.last = Some((target, now));
        velocity
    }

    /// The last position seen.
    pub fn position(&self) -> Option<Vec3> {
        self.last.map(|(p, _)| p)
    }

    pub fn reset(&mut self) {
        self.last = None;
    }
}

/// Pseudo-frame of geographic goals: x = latitude (deg), y = longitude (deg), z = altitude AMSL (m).
pub const WGS84: &str = "wgs84";

/// A point (m) in a named frame; what mission validation checks against frames and geofence.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FramedPoint {
    pub position_m: Vec3,
    pub frame_id: String,
}

/// The frame a goal names, `earth` when absent or empty.
pub fn frame_or_earth(frame_id: &Option<String>) -> String {
    match frame_id {
        Some(f) if !f.is_empty() => f.clone(),
        _ => EARTH.to_string(),
    }
}

/// Why a goal's arguments are refused: the argument, the rule and its unit, in the words
/// operators see. Each message starts with the argument's name when there is one: mission
/// validation points at it from there.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GoalError {
    #[error("{name} must be a positive number of {unit}, got {value}")]
    NotPositive {
        name: String,
        value: f64,
        unit: String,
    },
    #[error("{name} must be >= 0 {unit}, got {value}")]
    Negative {
        name: String,
        value: f64,
        unit: String,
    },
    /// Outside `lo..=hi`; `unit` may say where a bound comes from.
    #[error("{name} must be within {lo}..={hi} {unit}, got {value}")]
    OutOfRange {
        name: String,
        value: f64,
        lo: f64,
        hi: f64,
        unit: String,
    },
    #[error("{name} must be finite numbers")]
    NotFinite { name: String },
    #[error("{name} must be finite numbers ({unit})")]
    NotFiniteIn { name: String, unit: String },
    #[error("yaw_mode fixed needs yaw_angle (rad)")]
    FixedNeedsAngle,
    #[error("yaw_mode face_point needs face_point [x, y, z] (m)")]
    FaceNeedsPoint,
    #[error("give yaw_angle or by_angle (rad), not both")]
    BothAngles,
    #[error("give yaw_angle or by_angle (rad)")]
    NoAngle,
    #[error("angle must be finite (rad)")]
    AngleNotFinite,
    #[error("path must have at least one waypoint")]
    EmptyPath,
    /// `unknown_cost` is a multiple of a free cell's cost, without a unit.
    #[error("unknown_cost must be in 0..={max}, got {value}")]
    UnknownCost { value: f64, max: f64 },
    #[error("n must be 1..={max} photos, got {n}")]
    PhotoCount { n: u32, max: u32 },
    #[error("mode must be 0 (point at the target), got {0}")]
    GimbalMode(u8),
    #[error(transparent)]
    Geo(#[from] GeoError),
}

/// Refuses non-finite or out-of-range numbers with the argument's name and unit.
pub fn check_positive(name: &str, value: f64, unit: &str) -> Result<(), GoalError> {
    if !value.is_finite() || value <= 0.0 {
        return Err(GoalError::NotPositive {
            name: name.to_string(),
            value,
            unit: unit.to_string(),
        });
    }
    Ok(())
}

/// Refuses non-finite or negative numbers with the argument's name and unit.
pub fn check_non_negative(name: &str, value: f64, unit: &str) -> Result<(), GoalError> {
    if !value.is_finite() || value < 0.0 {
        return Err(GoalError::Negative {
            name: name.to_string(),
            value,
            unit: unit.to_string(),
        });
    }
    Ok(())
}

/// Refuses non-finite numbers and numbers outside `lo..=hi`, with the argument's name and unit.
pub fn check_within(name: &str, value: f64, lo: f64, hi: f64, unit: &str) -> Result<(), GoalError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        return Ok(());
    }
    Err(GoalError::OutOfRange {
        name: name.to_string(),
        value,
        lo,
        hi,
        unit: unit.to_string(),
    })
}

pub fn check_finite(name: &str, values: &[f64]) -> Result<(), GoalError> {
    if values.iter().any(|v| !v.is_finite()) {
        return Err(GoalError::NotFinite {
            name: name.to_string(),
        });
    }
    Ok(())
}

/// Parses JSON arguments into a goal type, with the path of the offending field in the error.
/// Read in place: a copy of 10 000 waypoints' values costs about a millisecond at every start.
pub fn parse_args<T: serde::de::DeserializeOwned>(
    args: &serde_json::Value,
) -> Result<T, serde_json::Error> {
    T::deserialize(args)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn yaw_mode_accepts_numbers_and_names() {
        let m: YawMode = serde_json::from_str("1").unwrap();
        assert_eq!(m, YawMode::PathFacing);
        let m: YawMode = serde_json::from_str("\"fixed_yaw\"").unwrap();
        assert_eq!(m, YawMode::Fixed);
        assert!(serde_json::from_str::<YawMode>("7").is_err());
    }

    #[test]
    fn goal_errors_name_the_argument_rule_and_unit() {
        let said = |r: Result<(), GoalError>| r.map_err(|e| e.to_string());
        assert_eq!(
            said(check_positive("speed", 0.0, "m/s")),
            Err("speed must be a positive number of m/s, got 0".into())
        );
        assert_eq!(
            said(check_non_negative("duration", -1.5, "s")),
            Err("duration must be >= 0 s, got -1.5".into())
        );
        assert_eq!(
            said(check_within("height", f64::NAN, 0.2, 100.0, "m")),
            Err("height must be within 0.2..=100 m, got NaN".into())
        );
        assert_eq!(said(check_within("height", 100.0, 0.2, 100.0, "m")), Ok(()));
        assert_eq!(
            said(check_finite("path[2]", &[0.0, f64::INFINITY])),
            Err("path[2] must be finite numbers".into())
        );
        assert_eq!(
            GoalError::PhotoCount { n: 0, max: 10_000 }.to_string(),
            "n must be 1..=10000 photos, got 0"
        );
        assert_eq!(
            GoalError::UnknownCost {
                value: 2000.0,
                max: 1000.0
            }
            .to_string(),
            "unknown_cost must be in 0..=1000, got 2000"
        );
    }
}
