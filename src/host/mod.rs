//! The host: runs drone cores, their mission executors and their vehicles, in real time on a
//! vehicle or in simulated time in the simulator, and talks to the API.
//!
//! In: commands from the API (bounded channel, one-shot replies), the vehicles' feedback.
//! Out: the latest state of every drone (a `watch` channel), events (a `broadcast` channel a
//! slow reader can only lag on), the flight log, the persisted missions, and systemd
//! READY/WATCHDOG notifications from the control loop.

pub mod builder;
#[cfg(feature = "fleet-bus")]
pub mod bus_link;
pub mod coverage;
pub mod engine;
mod load;
pub mod map_view;
pub mod runtime;
pub mod scans;
pub mod status;
pub mod store;
pub mod vehicle;

pub use crate::platform::fleet::Fleet;
pub use builder::HostBuilder;
pub use engine::{
    Command, FrameRegistration, Host, HostError, LoadOptions, PersistedState, Uploaded,
};
pub use runtime::{HostHandle, Pace, RuntimeOptions};
pub use status::{DroneStatus, HostEvent, HostSnapshot};
