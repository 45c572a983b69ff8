//! Cooperative frontier exploration with minimal sensing (the thesis's contribution C.3).
//!
//! In: the fleet's merged occupancy grid and each drone's requests. Out: frontiers, the
//! navigable space around them, allocations (a goal and the path to it) and the watcher's
//! decisions; the `explore` behavior (`behavior::explore`) flies them, the host runs the
//! allocator as a fleet-level service ([`service::FrontierService`]) on a thread of its own
//! ([`worker::FrontierWorker`]).
//!
//! - [`space`]: navigable cells and frontiers of a grid (thesis Algorithm 1).
//! - [`reach`]: path distances and paths from one drone through navigable space.
//! - [`allocation`]: which frontier a drone takes (`kestrel`, `thesis`, `nearest`, `farthest`).
//! - [`settings`]: the tuned weights, one validated struct (config `[exploration]`).
//! - [`sweep`]: flying a long frontier end to end.
//! - [`service`]: the allocator service: claims, given-up goals, answers.
//! - [`worker`]: the allocator service on its own thread, fed with the map's changes.
//! - [`watcher`]: the intra-swarm avoidance decision.
//! - [`tracking`]: how far a drone strays from its path, as room added to its safety distance.
//! - [`progress`]: an exploration run as operators follow it (area curve, paths, time left).
//! - [`evaluate`]: metrics of a flight log against the true world (outside the loop).
//! - [`worldgen`]: seeded exploration worlds.

pub mod allocation;
pub mod evaluate;
pub mod progress;
pub mod reach;
pub mod service;
pub mod settings;
pub mod space;
pub mod sweep;
pub mod tracking;
pub mod watcher;
pub mod worker;
pub mod worldgen;
