//! The MAVLink platform: PX4 and ArduPilot autopilots flown over MAVLink 2.
//!
//! In: the core's setpoints and [`crate::platform::PlatformRequest`]s; MAVLink frames from the
//! autopilot. Out: [`crate::platform::PlatformFeedback`] (status, ENU odometry, scans, request
//! outcomes); MAVLink frames to the autopilot (and, optionally, to ground stations).
//!
//! Layers, from pure to I/O:
//! - [`profile`]: what differs between autopilots, as data (`platforms/*.toml`);
//! - [`frames`]: NED/FRD ↔ ENU/FLU, the only place they meet;
//! - [`model`]: decoded messages → vehicle status and odometry;
//! - [`commands`]: COMMAND_LONG → COMMAND_ACK tracking with retries and the autopilot's reasons;
//! - [`setpoint`]: ENU setpoints → SET_POSITION_TARGET_LOCAL_NED, streamed only while fresh;
//! - [`actions`]: requests as wait/command/confirm sequences;
//! - [`takeover`]: whether Kestrel or someone else (a pilot, a ground station) flies the vehicle;
//! - [`statustext`]: Kestrel's own texts for the ground station: chunked, paced, bounded;
//! - [`session`]: all of the above for one autopilot, driven by messages, control ticks and time;
//! - [`link`], [`router`]: tokio tasks for the connection (with reconnection), reading,
//!   writing and ground-station forwarding;
//! - [`peer`], [`udp_in`]: Kestrel's own `udpin` transport, answering only the autopilot's
//!   address (pinned from its HEARTBEAT), never whoever sent the last datagram;
//! - [`hub`]: several vehicles behind one connection, told apart by system id;
//! - [`facade`]: [`MavlinkPlatform`], the synchronous `Platform` over those tasks;
//! - [`tlog`]: reading recorded captures for replay tests and benchmarks.

pub mod actions;
mod boot_clock;
pub mod commands;
pub mod config;
pub mod events;
pub mod facade;
pub mod frames;
pub mod hub;
mod legacy;
pub mod link;
pub mod model;
pub mod peer;
pub mod profile;
pub mod router;
pub mod session;
pub mod setpoint;
pub mod slew;
pub mod statustext;
pub mod takeover;
#[cfg(test)]
mod testutil;
pub mod tlog;
pub mod udp_in;
pub mod velocity_check;

pub use facade::{start_hub, LinkConfig, LinkError, MavlinkPlatform, TextSender};
pub use hub::LinkHub;
pub use profile::{Profile, ProfileError};
pub use session::{Session, SessionConfig};
