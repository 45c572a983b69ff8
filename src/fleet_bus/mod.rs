//! The fleet bus: several Kestrel processes (one per drone, or one per group) forming one fleet
//! over Zenoh, so that the fleet view, the merged map, the safety stage's separation check, the
//! drone watcher and the frontier allocator work across processes as within one.
//!
//! In: the `[fleet]` section; from the control loop, this host's drone states (with their
//! exploration claims) and the changed regions of its drones' map layers; from peers, theirs.
//! Out: remote drones in the fleet view (`local: false`, with a position uncertainty that grows
//! while their node is silent), their map layers in the merged map, their claims in the
//! allocator. `config`, `credentials` and `wire` (formats and checks), `remote` (what was
//! heard), `inbox` (peers' map regions coalesced for the control loop) and `join` (whether this node joined its peers, who refused whom) are plain code;
//! `zenoh_log` reads Zenoh's log lines for `join`; `stats` counts; `node` (the Zenoh session) is
//! built with the `fleet-bus` feature, `identity` (signing) and `intake` (a peer's message
//! checked) with `fleet-identity`, which `fleet-bus` includes and the fuzz targets use.

pub mod config;
pub mod credentials;
#[cfg(feature = "fleet-identity")]
pub mod identity;
pub mod inbox;
#[cfg(feature = "fleet-identity")]
pub mod intake;
pub mod join;
#[cfg(feature = "fleet-bus")]
pub mod node;
pub mod remote;
pub mod stats;
pub mod wire;
pub mod zenoh_log;
