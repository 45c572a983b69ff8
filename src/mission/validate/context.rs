//! What a mission is validated against, for one drone at one instant: the registry, the
//! limits, the frames, home and the geodetic origin; borrowed on the loop
//! ([`ValidationContext`]) or owned, to validate on another thread ([`ContextSnapshot`]).
//!
//! In: the host's drone (its core, the limits) at one tick. Out: the context, and whether a
//! mission validated with a snapshot still holds when it reaches the loop.

use crate::behavior::Registry;
use crate::estimator::frames::FrameTree;
use crate::estimator::geodetic::GeodeticOrigin;
use crate::safety::{GeofenceSection, LowestHeight};
use crate::types::Vec3;
use std::time::Duration;

/// What missions may ask of the vehicle.
#[derive(Debug, Clone, PartialEq)]
pub struct Limits {
    /// Fastest speed an item may ask for (m/s): the vehicle's horizontal speed limit.
    pub max_speed_mps: f64,
    pub geofence: GeofenceSection,
    pub max_items: usize,
    pub max_waypoints: usize,
}

/// What validation checks a mission against, for one drone at one instant.
pub struct ValidationContext<'a> {
    pub drone_id: &'a str,
    pub registry: &'a Registry,
    pub limits: &'a Limits,
    pub frames: &'a FrameTree,
    /// Time used to place points given in moving frames.
    pub now: Duration,
    /// Centre of the geofence and zero of its altitudes (`earth`, m).
    pub home_enu_m: Vec3,
    pub geo_origin: &'a GeodeticOrigin,
    /// The lowest height above home this drone may be sent to; `None`: the ground.
    pub lowest_height: Option<LowestHeight>,
}

/// How far home may move between a snapshot and the upload's arrival on the loop (m).
pub const HOME_TOLERANCE_M: f64 = 0.05;

/// A [`ValidationContext`] that owns its parts: taken from the host in one tick, then used to
/// validate on another thread (a large upload must not cost the control loop its tick).
#[derive(Clone)]
pub struct ContextSnapshot {
    pub drone_id: String,
    pub registry: Registry,
    pub limits: Limits,
    pub frames: FrameTree,
    pub now: Duration,
    pub home_enu_m: Vec3,
    pub geo_origin: GeodeticOrigin,
    pub lowest_height: Option<LowestHeight>,
}

impl std::fmt::Debug for ContextSnapshot {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("ContextSnapshot")
            .field("drone_id", &self.drone_id)
            .field("now", &self.now)
            .field("home_enu_m", &self.home_enu_m)
            .finish_non_exhaustive()
    }
}

impl ContextSnapshot {
    pub fn of(ctx: &ValidationContext) -> Self {
        Self {
            drone_id: ctx.drone_id.to_string(),
            registry: ctx.registry.clone(),
            limits: ctx.limits.clone(),
            frames: ctx.frames.clone(),
            now: ctx.now,
            home_enu_m: ctx.home_enu_m,
            geo_origin: *ctx.geo_origin,
            lowest_height: ctx.lowest_height,
        }
    }

    pub fn context(&self) -> ValidationContext<'_> {
        ValidationContext {
            drone_id: &self.drone_id,
            registry: &self.registry,
            limits: &self.limits,
            frames: &self.frames,
            now: self.now,
            home_enu_m: self.home_enu_m,
            geo_origin: &self.geo_origin,
            lowest_height: self.lowest_height,
        }
    }

    /// Whether a mission validated with this snapshot is still valid in `now_ctx`: same
    /// drone, limits, origin and frames (the vehicle's own pose aside), and home within
    /// [`HOME_TOLERANCE_M`] (before takeoff home is where the vehicle stands, which the
    /// estimate moves by noise).
    pub fn still_holds(&self, now_ctx: &ValidationContext) -> bool {
        self.drone_id == now_ctx.drone_id
            && &self.limits == now_ctx.limits
            && &self.geo_origin == now_ctx.geo_origin
            && self.lowest_height == now_ctx.lowest_height
            && (self.home_enu_m - now_ctx.home_enu_m).norm() <= HOME_TOLERANCE_M
            && self.frames.same_frames_as(now_ctx.frames)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::estimator::frames::FrameMotion;
    use crate::types::Pose;

    fn snapshot() -> ContextSnapshot {
        ContextSnapshot {
            drone_id: "drone_0".into(),
            registry: Registry::with_motion_behaviors(),
            limits: Limits::default(),
            frames: FrameTree::new(),
            now: Duration::from_secs(3),
            home_enu_m: Vec3::new(1.0, 2.0, 0.0),
            geo_origin: GeodeticOrigin::default(),
            lowest_height: None,
        }
    }

    #[test]
    fn a_snapshot_holds_while_only_the_vehicle_and_time_move() {
        let taken = snapshot();
        let mut now = taken.clone();
        now.now = Duration::from_secs(4);
        now.frames.set_base_link(
            Pose::from_position_yaw(Vec3::new(5.0, 0.0, 2.0), 1.0),
            now.now,
        );
        now.home_enu_m.x += 0.01;
        assert!(taken.still_holds(&now.context()));
    }

    #[test]
    fn a_snapshot_is_stale_once_frames_home_or_limits_change() {
        let taken = snapshot();
        let mut framed = taken.clone();
        framed
            .frames
            .set("panel", "earth", FrameMotion::fixed(Pose::identity()))
            .unwrap();
        assert!(!taken.still_holds(&framed.context()));
        let mut moved = taken.clone();
        moved.home_enu_m.x += 1.0;
        assert!(!taken.still_holds(&moved.context()));
        let mut slower = taken.clone();
        slower.limits.max_speed_mps /= 2.0;
        assert!(!taken.still_holds(&slower.context()));
        let mut other = taken.clone();
        other.drone_id = "drone_1".into();
        assert!(!taken.still_holds(&other.context()));
    }
}
