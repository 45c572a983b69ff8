//! Shared data with units and frames.
//!
//! Inside Kestrel the world frame is ENU (x east, y north, z up) and the body frame is FLU
//! (x forward, y left, z up), as in Aerostack2. NED/FRD exists only inside the MAVLink layer.
//! Every field name carries its unit (`_m`, `_mps`, `_rad`, `_radps`); absence is `Option`.

mod geometry;
mod state;

pub use geometry::{wrap_angle_rad, Pose, Vec2, Vec3};
pub use state::{
    Battery, EstimatedState, FlightStatus, LinkHealth, PlatformStatus, Validity, VehicleState,
};
