//! The simulator's world as a fleet a host flies (`platform::fleet::Fleet`).
//!
//! In: per vehicle, each tick's setpoint and requests; the tick to advance the physics by; link
//! cuts (fault injection for tests). Out: per vehicle, platform feedback; each crash once, as an
//! alert.

use super::SimWorld;
use crate::platform::fleet::{FaultError, Fleet};
use crate::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::{LinkHealth, Pose, Setpoint};
use std::time::Duration;

/// The simulator's world as a fleet. A vehicle whose link is cut reports `Lost` and gets no
/// commands, so its own failsafe takes over, as a real autopilot's would.
pub struct SimFleet {
    pub world: SimWorld,
    link_lost: Vec<bool>,
    crash_reported: Vec<bool>,
    substeps: u32,
}

impl SimFleet {
    pub fn new(world: SimWorld, physics_substeps: u32) -> Self {
        let n = world.vehicles.len();
        Self {
            world,
            link_lost: vec![false; n],
            crash_reported: vec![false; n],
            substeps: physics_substeps.max(1),
        }
    }
}

impl Fleet for SimFleet {
    fn len(&self) -> usize {
        self.world.vehicles.len()
    }
    fn capabilities(&self, i: usize) -> Option<Capabilities> {
        self.world.vehicles.get(i).map(Platform::capabilities)
    }
    fn poll(&mut self, i: usize, now: Duration) -> PlatformFeedback {
        let lost = self.link_lost.get(i).copied().unwrap_or(false);
        let Some(v) = self.world.vehicles.get_mut(i) else {
            return PlatformFeedback::default();
        };
        let mut feedback = v.poll(now);
        if lost {
            feedback.status.link = LinkHealth::Lost;
            feedback.measurements.clear();
            feedback.request_results.clear();
        }
        feedback
    }
    fn command(
        &mut self,
        i: usize,
        now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    ) {
        if self.link_lost.get(i).copied().unwrap_or(false) {
            return;
        }
        if let Some(v) = self.world.vehicles.get_mut(i) {
            v.command(now, setpoint, requests);
        }
    }
    fn advance(&mut self, now: Duration, tick: Duration) {
        let dt = tick.as_secs_f64() / f64::from(self.substeps);
        for k in 0..self.substeps {
            let t = now + tick.mul_f64(f64::from(k) / f64::from(self.substeps));
            self.world.step(t, dt);
        }
    }
    fn take_alerts(&mut self) -> Vec<(usize, String)> {
        let mut out = Vec::new();
        for (i, v) in self.world.vehicles.iter().enumerate() {
            if let (Some(reason), Some(reported)) = (v.crashed(), self.crash_reported.get_mut(i)) {
                if !*reported {
                    *reported = true;
                    out.push((i, reason.to_string()));
                }
            }
        }
        out
    }
    fn set_link_lost(&mut self, i: usize, lost: bool) -> Result<(), FaultError> {
        let slot = self.link_lost.get_mut(i).ok_or(FaultError::NoVehicle(i))?;
        *slot = lost;
        Ok(())
    }
    fn is_simulated(&self) -> bool {
        true
    }
    fn truth_behind_estimate(&self, i: usize) -> Option<Pose> {
        self.world.truth_behind_estimate(i)
    }
}
