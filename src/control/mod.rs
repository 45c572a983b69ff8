//! Motion control: PID loops, the motion controller and trajectory generation.
//!
//! In: a [`reference::MotionReference`] from the behavior server and the estimated state.
//! Out: a [`reference::Setpoint`] of a kind the platform accepts.

pub mod controller;
pub mod disturbance;
pub mod pid;
pub mod reference;
pub mod shaper;
pub mod trajectory;

pub use controller::{
    commanded_horizontal_speed, commanded_speed_share, Controller, ControllerConfig,
};
pub use reference::{AcceptedSetpoints, MotionReference, Setpoint, YawTarget};
pub use shaper::SpeedCaps;
