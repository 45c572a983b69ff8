//! The state directory: loaded missions, their progress, the executors' state and the frames,
//! one file each, written durably off the control loop.
//!
//! In: at start, the directory (`layout::load`: bad files quarantined, the old single
//! `state.json` migrated); then [`Change`]s from the host after every command and tick
//! ([`Sink::push`]). Out: the state to restore; the files; [`Sink::saved`], which the API awaits
//! before it acknowledges a change; the [`StoreHealth`] shown by `GET /api/health`.

pub mod files;
pub mod layout;
pub mod writer;

pub use layout::{load, Change, LoadReport, Problem};
pub use writer::{Saved, Sink, StoreHealth};
