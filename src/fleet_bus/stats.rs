//! The fleet bus's counters, shared by the Zenoh session's tasks and the intake, and their view
//! in the API's status.

use serde::Serialize;
use std::sync::atomic::{AtomicU64, Ordering};

/// Counters since the bus started.
#[derive(Debug, Default)]
pub struct BusStats {
    pub state_sent_bytes: AtomicU64,
    pub state_sent: AtomicU64,
    pub map_sent_bytes: AtomicU64,
    pub map_sent: AtomicU64,
    pub received: AtomicU64,
    pub received_bytes: AtomicU64,
    /// Messages from peers that did not decode or check.
    pub refused: AtomicU64,
    /// Messages dropped because a queue (or the map inbox) was full.
    pub dropped: AtomicU64,
}

/// The counters as the API shows them.
#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct BusStatsView {
    pub state_sent: u64,
    pub state_sent_bytes: u64,
    pub map_sent: u64,
    pub map_sent_bytes: u64,
    pub received: u64,
    pub received_bytes: u64,
    pub refused: u64,
    pub dropped: u64,
}

impl BusStats {
    pub fn view(&self) -> BusStatsView {
        let r = |c: &AtomicU64| c.load(Ordering::Relaxed);
        BusStatsView {
            state_sent: r(&self.state_sent),
            state_sent_bytes: r(&self.state_sent_bytes),
            map_sent: r(&self.map_sent),
            map_sent_bytes: r(&self.map_sent_bytes),
            received: r(&self.received),
            received_bytes: r(&self.received_bytes),
            refused: r(&self.refused),
            dropped: r(&self.dropped),
        }
    }
}
