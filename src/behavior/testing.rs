//! Test support: a hand-set vehicle state to build [`BehaviorContext`]s from.

use super::services::ServiceDesk;
use super::{BehaviorConfig, BehaviorContext};
use crate::estimator::frames::FrameTree;
use crate::estimator::geodetic::GeodeticOrigin;
use crate::exploration::online::settings::ExplorationSettings;
use crate::types::FleetView;
use crate::types::{Capabilities, RequestResult};
use crate::types::{
    EstimatedState, FlightStatus, LinkHealth, PlatformStatus, Pose, Validity, Vec3,
};
use std::time::Duration;

pub(crate) struct Scene {
    pub state: EstimatedState,
    pub platform: PlatformStatus,
    pub frames: FrameTree,
    pub origin: GeodeticOrigin,
    pub config: BehaviorConfig,
    pub exploration: ExplorationSettings,
    pub capabilities: Capabilities,
    pub dt_s: f64,
    /// What the previous reference held (`BehaviorContext::held_at_enu_m`).
    pub held_at_enu_m: Option<Vec3>,
    /// Acks the platform reports in the next contexts.
    pub request_results: Vec<RequestResult>,
    pub services: ServiceDesk,
    pub fleet: FleetView,
    /// How fast the estimate drifts in the next contexts (m/s).
    pub estimate_drift_mps: f64,
    /// The safety stage's override in the next contexts.
    pub safety_override: Option<crate::safety::OverrideKind>,
    /// The map correction's step in the next contexts.
    pub map_step_m: Vec3,
}

impl Scene {
    /// Armed, flying, in offboard, at the origin with a valid estimate.
    pub fn flying() -> Self {
        Self {
            state: EstimatedState {
                valid: Validity::ALL,
                ..EstimatedState::default()
            },
            platform: PlatformStatus {
                armed: true,
                offboard: true,
                flight: FlightStatus::Flying,
                link: LinkHealth::Ok,
                ready_to_fly: true,
                ..PlatformStatus::default()
            },
            frames: FrameTree::new(),
            origin: GeodeticOrigin::default(),
            config: BehaviorConfig::default(),
            exploration: ExplorationSettings::default(),
            capabilities: Capabilities::setpoints_only(),
            dt_s: 1.0,
            held_at_enu_m: None,
            request_results: Vec::new(),
            services: ServiceDesk::default(),
            fleet: FleetView::default(),
            estimate_drift_mps: 0.0,
            safety_override: None,
            map_step_m: Vec3::zeros(),
        }
    }

    pub fn set_position(&mut self, position_m: Vec3, velocity_mps: Vec3) {
        self.state.pose = Pose::from_position_yaw(position_m, self.state.pose.yaw_rad());
        self.state.velocity_enu_mps = velocity_mps;
    }

    pub fn ctx(&self, now_s: u64) -> BehaviorContext<'_> {
        self.ctx_at(Duration::from_secs(now_s))
    }

    pub fn ctx_at(&self, now: Duration) -> BehaviorContext<'_> {
        BehaviorContext {
            drone_id: "drone_0",
            now,
            dt_s: self.dt_s,
            state: &self.state,
            platform: &self.platform,
            capabilities: self.capabilities,
            frames: &self.frames,
            geo_origin: &self.origin,
            home_enu_m: None,
            held_at_enu_m: self.held_at_enu_m,
            config: &self.config,
            exploration: &self.exploration,
            map: None,
            request_results: &self.request_results,
            services: &self.services,
            fleet: &self.fleet,
            estimate_drift_mps: self.estimate_drift_mps,
            safety_override: self.safety_override,
            map_step_m: self.map_step_m,
        }
    }
}
