//! Platforms: what flies the vehicle (the built-in simulator, or an autopilot over MAVLink).
//!
//! In (from the core, each tick): a [`Setpoint`] and [`PlatformRequest`]s. Out (to the core):
//! [`PlatformStatus`] and estimator [`Measurement`]s. Nothing above this layer knows which
//! platform it flies; the MAVLink implementation lives in `platform::mavlink`, and
//! `platform::shifted` moves a vehicle's local frame into a fleet's shared one.

pub mod fleet;
pub mod mavlink;
pub mod shifted;

use crate::types::Setpoint;
pub use crate::types::{
    Capabilities, PlatformEvent, PlatformFeedback, PlatformRequest, RequestRefused, RequestResult,
};
use std::time::Duration;

/// A vehicle the core can fly, driven synchronously by a driver loop.
pub trait Platform: Send {
    fn capabilities(&self) -> Capabilities;
    /// Collects what arrived since the last call. Never blocks.
    fn poll(&mut self, now: Duration) -> PlatformFeedback;
    /// Hands over this tick's outputs. Never blocks; `None` means "nothing to command" (on the
    /// ground and idle): the platform must then not invent a setpoint of its own.
    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]);
}
