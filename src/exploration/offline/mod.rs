//! Exploration outside the loop: judging a flight and making worlds to fly.
//!
//! - [`evaluate`]: metrics of a flight log against the true world (as an outside evaluator
//!   would).
//! - [`worldgen`]: seeded exploration worlds.

pub mod evaluate;
pub mod worldgen;
