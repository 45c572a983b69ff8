//! The vehicles a host flies: any list of [`Platform`]s, or a fleet that steps its own world
//! (the simulator's, `sim::fleet::SimFleet`).
//!
//! In: per vehicle, each tick's setpoint and requests. Out: per vehicle, platform feedback;
//! alerts (collisions) from a simulated fleet. A simulated fleet also advances its physics
//! between ticks and can pretend a vehicle's link is lost (fault injection for tests).

use super::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::{Pose, Setpoint};
use std::any::Any;
use std::time::Duration;

/// Why a fault could not be injected.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FaultError {
    #[error("fault injection is only available in the simulator")]
    NotSimulated,
    #[error("no vehicle {0}")]
    NoVehicle(usize),
}

/// What a host needs from its vehicles. `Any`, so that whoever built a host over a fleet of
/// its own can reach it again (the simulator's tests read its ground truth).
pub trait Fleet: Send + Any {
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
    /// The true pose of vehicle `i` where what it reports is a drifting estimate (a simulated
    /// vehicle with drift); `None` where its reports are all there is.
    fn truth_behind_estimate(&self, _i: usize) -> Option<Pose> {
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
