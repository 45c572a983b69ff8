//! Exploration while drones fly: the space, its frontiers, who takes which, the service that
//! answers the drones, and the watcher that keeps them apart.
//!
//! - [`space`]: navigable cells and frontiers of a grid (thesis Algorithm 1).
//! - [`reach`]: path distances and paths from one drone through navigable space.
//! - [`allocation`]: which frontier a drone takes: one [`allocation::Allocator`] per kind
//!   (`kestrel`, `thesis`, `nearest`, `farthest`).
//! - [`settings`]: the tuned weights, one validated struct (config `[exploration]`, the
//!   `explore` goal's `settings`).
//! - [`sweep`]: flying a long frontier end to end.
//! - [`service`]: the allocator service: claims, given-up goals, answers.
//! - [`worker`]: the allocator service on its own thread, fed with the map's changes.
//! - [`watcher`]: the intra-swarm avoidance decision.
//! - [`tracking`]: how far a drone strays from its path, as room added to its safety distance.
//! - [`progress`]: an exploration run as operators follow it (area curve, paths, time left;
//!   its pose samples are the evaluator's, [`super::offline::evaluate::PoseSample`]).

pub mod allocation;
pub mod progress;
pub mod reach;
pub mod service;
pub mod settings;
pub mod space;
pub mod sweep;
pub mod tracking;
pub mod watcher;
pub mod worker;
