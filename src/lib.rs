//! Kestrel: onboard autonomy for multirotor drones.
//!
//! Modules are listed in data-flow order:
//!
//! ```text
//! MAVLink ─▶ platform ─▶ estimator ─▶ state ─┬─▶ behavior server ─▶ reference ─▶ controller ─▶ platform ─▶ MAVLink
//!                                            │         ▲      │ path request                        ▲
//! range/scan/depth ─▶ mapping ─▶ grid/graph ─┴─▶ planning ◀───┘                                     │
//! HTTP/WS ─▶ api ─▶ mission executor ─▶ behavior requests                  safety/failsafe ─▶ (override)
//! ```
//!
//! Everything between `platform` and `controller` is synchronous and never reads the clock:
//! [`core::DroneCore::tick`] takes the time as an argument, so the same code runs on a vehicle
//! (real-time driver), in the simulator (simulated time) and in tests (ticked by hand).

pub mod api;
pub mod behavior;
pub mod config;
pub mod control;
pub mod core;
pub mod estimator;
pub mod exploration;
pub mod fleet_bus;
pub mod flightlog;
pub mod host;
pub mod mapping;
pub mod mission;
pub mod planning;
pub mod platform;
pub mod report;
pub mod ros2;
pub mod safety;
pub mod scenario;
pub mod sim;
pub mod types;
