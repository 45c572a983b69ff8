//! The control loop's end of the fleet bus: between two ticks it takes in what peers sent and
//! hands the bus what is due, never waiting on the network.
//!
//! In: the bus port (`fleet_bus::node`), the `[fleet]` rates, the host. Out: remote states and
//! map regions applied to the host (at most [`MAX_IN_PER_TICK`] states and about
//! [`MAP_WORK_PER_TICK`] cell visits of map work a tick, whatever peers send); this host's state (`state_rate_hz`), changed map regions
//! (`map_rate_hz`) and keyframes (`map_keyframe_period_s`) queued for sending; a
//! [`BusReport`] (traffic, refusals, and the latency from a peer's send to this host's fleet
//! view) put into the host's snapshot once a second.

use std::collections::VecDeque;
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use crate::fleet_bus::config::FleetSection;
use crate::fleet_bus::node::{BusPort, Outbound};
use crate::host::engine::Host;
use crate::host::status::BusReport;

/// Most peer states taken in between two ticks (the rest wait for the next).
pub const MAX_IN_PER_TICK: usize = 64;
/// Map work done between two ticks, in cell visits (writing a cell of a peer's layer and
/// re-fusing it visits it once per layer): a quarter of the first try's 100 000, which left a
/// p99 of 27 ms under a flood; 14 ms with this one
/// (BENCHMARKS.md, "Control tick under a flood of map messages"). A peer's full grid takes a few
/// ticks to land; the rest waits, coalesced, in the map inbox.
pub const MAP_WORK_PER_TICK: usize = 25_000;
/// Latency samples kept for the percentiles.
const LATENCY_SAMPLES: usize = 2048;
/// Shortest time between two warnings about refused peer messages.
const WARN_EVERY: Duration = Duration::from_secs(5);

pub struct BusLink {
    port: BusPort,
    fleet: String,
    node: String,
    state_period: Duration,
    map_period: Duration,
    keyframe_period: Duration,
    last_state: Option<Instant>,
    last_map: Option<Instant>,
    last_keyframe: Option<Instant>,
    last_report: Option<Instant>,
    last_warning: Option<Instant>,
    /// Refusals not said since the last warning.
    held_warnings: u64,
    state_seq: u64,
    map_seq: u64,
    latencies_ms: VecDeque<f64>,
    refused_here: u64,
    /// The join watch's revision last reported.
    join_revision: Option<u64>,
}

fn due(last: Option<Instant>, period: Duration, now: Instant) -> bool {
    last.is_none_or(|t| now.duration_since(t) >= period)
}

fn unix_us() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| u64::try_from(d.as_micros()).unwrap_or(u64::MAX))
}

impl BusLink {
    pub fn new(port: BusPort, section: &FleetSection, node: String) -> Self {
        Self {
            port,
            fleet: section.name.clone(),
            node,
            state_period: Duration::from_secs_f64(1.0 / section.state_rate_hz),
            map_period: Duration::from_secs_f64(1.0 / section.map_rate_hz),
            keyframe_period: Duration::from_secs_f64(section.map_keyframe_period_s),
            last_state: None,
            last_map: None,
            last_keyframe: None,
            last_report: None,
            last_warning: None,
            held_warnings: 0,
            state_seq: 0,
            map_seq: 0,
            latencies_ms: VecDeque::with_capacity(LATENCY_SAMPLES),
            refused_here: 0,
            join_revision: None,
        }
    }

    fn warn(&mut self, what: &str) {
        self.refuse(1, what);
    }

    /// Counts `messages` refused here and says why, at most every [`WARN_EVERY`].
    fn refuse(&mut self, messages: u64, what: &str) {
        self.refused_here += messages;
        let now = Instant::now();
        if !due(self.last_warning, WARN_EVERY, now) {
            self.held_warnings += 1;
            return;
        }
        self.last_warning = Some(now);
        match std::mem::take(&mut self.held_warnings) {
            0 => tracing::warn!("fleet bus: {what}"),
            n => tracing::warn!("fleet bus: {what} ({n} more refused since the last line)"),
        }
    }

    /// Between two ticks: peers' messages in, what is due out.
    pub fn exchange(&mut self, host: &mut Host) {
        let mut heard = false;
        for _ in 0..MAX_IN_PER_TICK {
            let Ok(m) = self.port.inbound.try_recv() else {
                break;
            };
            heard = true;
            let sent = m.sent_unix_us;
            for why in host.apply_bus_state(m) {
                self.warn(&why);
            }
            let latency_ms = unix_us().saturating_sub(sent) as f64 / 1000.0;
            if self.latencies_ms.len() == LATENCY_SAMPLES {
                self.latencies_ms.pop_front();
            }
            self.latencies_ms.push_back(latency_ms);
        }
        self.take_maps(host);
        let now = Instant::now();
        let revision = {
            let mut join = self.port.join.lock();
            if heard {
                join.peer_heard(now);
            }
            join.revision()
        };
        // A change of the join (joined, refused) is reported at once: missions wait on it.
        if self.join_revision != Some(revision) {
            self.join_revision = Some(revision);
            self.last_report = None;
        }
        if due(self.last_state, self.state_period, now) {
            self.last_state = Some(now);
            let msg = host.bus_state(&self.node, self.state_seq, unix_us());
            self.state_seq += 1;
            self.send(Outbound::State(msg));
        }
        if due(self.last_map, self.map_period, now) {
            self.last_map = Some(now);
            let keyframe = due(self.last_keyframe, self.keyframe_period, now);
            if keyframe {
                self.last_keyframe = Some(now);
            }
            for m in host.take_bus_maps(&self.node, &mut self.map_seq, keyframe) {
                self.send(Outbound::Map(m));
            }
        }
        if due(self.last_report, Duration::from_secs(1), now) {
            self.last_report = Some(now);
            host.set_bus_report(self.report());
        }
    }

    /// Peers' waiting map regions into their layers, for at most about [`MAP_WORK_PER_TICK`]
    /// cell visits.
    fn take_maps(&mut self, host: &mut Host) {
        let mut work = MAP_WORK_PER_TICK;
        while work > 0 {
            let per_cell = host.map_layers() + 1;
            let Some(slice) = self.port.maps.take(work / per_cell) else {
                break;
            };
            work = work.saturating_sub(slice.cells.len() * per_cell);
            let messages = slice.messages;
            if let Err(why) = host.apply_bus_region(slice) {
                self.refuse(messages, &why.to_string());
            }
        }
    }

    fn send(&self, msg: Outbound) {
        if self.port.outbound.try_send(msg).is_err() {
            self.port
                .stats
                .dropped
                .fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        }
    }

    fn report(&self) -> BusReport {
        let mut sorted: Vec<f64> = self.latencies_ms.iter().copied().collect();
        sorted.sort_by(f64::total_cmp);
        let pct = |p: f64| {
            let i = ((sorted.len() as f64 - 1.0) * p).round() as usize;
            sorted.get(i).copied()
        };
        let stats = self.port.stats.view();
        let join = self.port.join.lock().status();
        BusReport {
            fleet: self.fleet.clone(),
            node: self.node.clone(),
            state_sent: stats.state_sent,
            state_sent_bytes: stats.state_sent_bytes,
            map_sent: stats.map_sent,
            map_sent_bytes: stats.map_sent_bytes,
            received: stats.received,
            received_bytes: stats.received_bytes,
            refused: stats.refused + self.refused_here,
            dropped: stats.dropped,
            latency_samples: sorted.len(),
            latency_p50_ms: pct(0.5),
            latency_p99_ms: pct(0.99),
            joined: join.joined,
            join_required: join.join_required,
            refused_joins: join.refused_joins,
            waiting_for: join.waiting_for,
        }
    }
}
