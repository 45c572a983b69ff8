//! Cooperative frontier exploration with minimal sensing (the thesis's contribution C.3), in
//! two parts.
//!
//! [`online`] runs while drones fly. In: the fleet's merged occupancy grid and each drone's
//! requests. Out: frontiers, the navigable space around them, allocations (a goal and the path
//! to it) and the watcher's decisions; the `explore` behavior (`behavior::explore`) flies them,
//! the host runs the allocator as a fleet-level service ([`online::service::FrontierService`])
//! on a thread of its own ([`online::worker::FrontierWorker`]).
//!
//! [`offline`] works on what a flight left or what a flight needs beforehand, never in the
//! loop. In: a flight log and the true world, or a seed. Out: the metrics of a run
//! ([`offline::evaluate`]) and seeded worlds ([`offline::worldgen`]).

pub mod offline;
pub mod online;
