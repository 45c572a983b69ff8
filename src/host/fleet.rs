//! The vehicles a host flies: any list of [`Platform`]s, or the built-in simulator's world.
//!
//! In: per vehicle, each tick's setpoint and requests. Out: per vehicle, platform feedback;
//! alerts (collisions) from the simulator. The simulator also advances its physics between
//! ticks and can pretend a vehicle's link is lost (fault injection for tests).

use crate::control::Setpoint;
use crate::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::sim::SimWorld;
use crate::types::LinkHealth;
use std::time::Duration;

/// Why a fault could not be injected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultError {
    #[error("fault injection is only available in the simulator")]
    NotSimulated,
    #[error("no vehicle {0}")]
    NoVehicle(usize),
}

/// What a host needs from its vehicles.
pub trait Fleet: Send {
    fn len(&self) -> usize;
    fn is_empty(&self) -> bool {
        self.len() == 0
    }
    fn capabilities(&self, i: usize) -> Option<Capabilities>;
    fn poll(&mut self, i: usize, now: Duration) -> PlatformFeedback;
    fn command(
        &mut self,
        i: usize,
        now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    );
    /// Called once per tick after every vehicle was commanded; real vehicles do nothing.
    fn advance(&mut self, _now: Duration, _tick: Duration) {}
    /// New alerts since the last call: (vehicle index, message).
    fn take_alerts(&mut self) -> Vec<(usize, String)> {
        Vec::new()
    }
    /// Fault injection: cut (`true`) or restore a vehicle's link. Only the simulator can.
    fn set_link_lost(&mut self, _i: usize, _lost: bool) -> Result<(), FaultError> {
        Err(FaultError::NotSimulated)
    }
    fn is_simulated(&self) -> bool {
        false
    }
    /// The simulator's world (ground truth for tests and benches); `None` for real vehicles.
    fn sim_world(&self) -> Option<&SimWorld> {
        None
    }
    fn sim_world_mut(&mut self) -> Option<&mut SimWorld> {
        None
    }
}

impl Fleet for Vec<Box<dyn Platform>> {
    fn len(&self) -> usize {
        <[Box<dyn Platform>]>::len(self)
    }
    fn capabilities(&self, i: usize) -> Option<Capabilities> {
        self.get(i).map(|p| p.capabilities())
    }
    fn poll(&mut self, i: usize, now: Duration) -> PlatformFeedback {
        self.get_mut(i).map(|p| p.poll(now)).unwrap_or_default()
    }
    fn command(
        &mut self,
        i: usize,
        now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    ) {
        if let Some(p) = self.get_mut(i) {
            p.command(now, setpoint, requests);
        }
    }
}

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
    fn sim_world(&self) -> Option<&SimWorld> {
        Some(&self.world)
    }
    fn sim_world_mut(&mut self) -> Option<&mut SimWorld> {
        Some(&mut self.world)
    }
}
