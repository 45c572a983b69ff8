//! Shared data with units and frames: the vocabulary every layer speaks (poses, states,
//! setpoints, platform requests and reports, measurements, range scans, geographic points, the
//! fleet view, a simulated vehicle's sensor).
//! It depends on nothing else in Kestrel.
//!
//! Inside Kestrel the world frame is ENU (x east, y north, z up) and the body frame is FLU
//! (x forward, y left, z up), as in Aerostack2. NED/FRD exists only inside the MAVLink layer.
//! Every field name carries its unit (`_m`, `_mps`, `_rad`, `_radps`); absence is `Option`.

mod fleet;
mod geo;
mod geometry;
mod measurement;
mod platform;
pub mod scan;
mod setpoint;
mod simulated;
mod state;

pub use fleet::{DroneView, FleetView};
pub use geo::{GeoError, GeoPoint};
pub use geometry::{wrap_angle_rad, Pose, Vec2, Vec3};
pub use measurement::Measurement;
pub use platform::{
    Capabilities, PlatformEvent, PlatformFeedback, PlatformRequest, RequestRefused, RequestResult,
};
pub use scan::{Beam, RangeScan};
pub use setpoint::{AcceptedSetpoints, PositionLoop, Setpoint, YawTarget};
pub use simulated::{Imperfections, SensorConfig, SensorError, DEFAULT_VEHICLE_RADIUS_M};
pub use state::{
    Battery, EstimatedState, FlightStatus, LinkHealth, PlatformStatus, Validity, VehicleState,
};
