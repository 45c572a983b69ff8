//! This Kestrel's place on the fleet bus: a Zenoh session (peer mode) that publishes what the
//! control loop hands it and passes on what peers publish, checked.
//!
//! In: a [`NodeConfig`] and [`Outbound`] messages from the control loop (bounded queue: when the
//! bus is slower than the loop, the oldest are not kept; the next state and the next keyframe
//! repair it). Out: peers' states (decoded and bounds-checked; anything else is counted and
//! dropped, said at most every few seconds), their map regions coalesced in a [`MapInbox`]
//! (decoded here, on Zenoh's threads, never on the control loop's), and [`BusStats`]. Keys: `kestrel/<fleet>/<node>/state` (JSON) and
//! `kestrel/<fleet>/<node>/map` (binary, see `wire`). The control loop never waits on the bus:
//! it only `try_send`s and `try_recv`s.

use std::sync::atomic::Ordering;
use std::sync::Arc;

use tokio::sync::mpsc;

use super::config::FleetSection;
use super::identity::Signer;
use super::inbox::MapInbox;
use super::intake::{Intake, Member};
use super::join::{JoinWatch, Severity};
pub use super::stats::{BusStats, BusStatsView};
use super::wire::{MapMsg, StateMsg};

/// Messages waiting to be sent, or to be read by the control loop.
const QUEUE: usize = 256;
/// How soon a link that stopped answering is dropped (ms): Wi-Fi drops are noticed quickly.
const LEASE_MS: u64 = 3000;
/// Largest message Zenoh reassembles from its fragments (bytes): the largest a peer may send
/// (a map message and its signature) and a little room. Zenoh's own default is 1 GiB, and it
/// reassembles before anything of Kestrel's sees the message: one 500 MB put made a node peak
/// at 1.15 GB. A bigger message is dropped by the transport as its fragments arrive.
pub const MAX_REASSEMBLED_BYTES: usize =
    super::wire::MAX_MAP_BYTES + super::identity::ENVELOPE_BYTES + 4096;
/// Connections that have not finished Zenoh's handshake, held at once (Zenoh's default is 100):
/// further ones are closed as they come. About 100 idle connections from anyone who can reach
/// the port kept every peer out; now it takes more than this many held open at once, each
/// closed after [`ACCEPT_TIMEOUT_MS`]. With the API's 512 connections, within the service's
/// `LimitNOFILE` of 8192.
const ACCEPT_PENDING: usize = 512;
/// How long a connection may take to finish the handshake (ms; Zenoh's default is 10 000): two
/// round trips and the user/password check, well under a second on a fleet's Wi-Fi.
const ACCEPT_TIMEOUT_MS: u64 = 3000;
/// How often what the join watch has to say is logged.
const JOIN_LINES_EVERY: std::time::Duration = std::time::Duration::from_millis(250);

/// What the bus needs to start.
#[derive(Debug)]
pub struct NodeConfig {
    pub section: FleetSection,
    pub node: String,
    /// Cells of this Kestrel's map grid: no peer's map region may be larger.
    pub max_map_cells: usize,
    /// This node's key (`[fleet] key_file`).
    pub signer: Signer,
    /// The roster's other members, with their keys parsed.
    pub members: std::collections::BTreeMap<String, Member>,
}

#[derive(Debug)]
pub enum Outbound {
    State(StateMsg),
    Map(MapMsg),
}

/// The control loop's end of the bus.
pub struct BusPort {
    /// Peers' states, checked.
    pub inbound: mpsc::Receiver<StateMsg>,
    /// Peers' map regions, checked and coalesced.
    pub maps: Arc<MapInbox>,
    pub outbound: mpsc::Sender<Outbound>,
    pub stats: Arc<BusStats>,
    /// Whether this node joined its peers (fed by Zenoh's log lines, `zenoh_log`).
    pub join: &'static JoinWatch,
}

/// The process's join watch, expecting the peers of `section`, and its lines logged.
fn watch_joins(section: &FleetSection) -> &'static JoinWatch {
    let join = JoinWatch::global();
    join.lock()
        .expect(&section.name, &section.connect, section.require_join);
    spawn_join_lines(join);
    join
}

/// Logs what the join watch has to say (refusals, peers joined), in Kestrel's words, for as
/// long as the process runs.
fn spawn_join_lines(join: &'static JoinWatch) {
    tokio::spawn(async move {
        let mut every = tokio::time::interval(JOIN_LINES_EVERY);
        loop {
            every.tick().await;
            let lines = join.lock().take_lines();
            for (severity, line) in lines {
                match severity {
                    Severity::Info => tracing::info!("{line}"),
                    Severity::Warn => tracing::warn!("{line}"),
                }
            }
        }
    });
}

/// The Zenoh configuration for a section: peer mode, the endpoints, scouting only if asked,
/// messages reassembled up to [`MAX_REASSEMBLED_BYTES`], [`ACCEPT_PENDING`] handshakes at once,
/// user/password authentication when a credentials file is given.
fn zenoh_config(section: &FleetSection) -> anyhow::Result<zenoh::Config> {
    let mut json = serde_json::json!({
        "mode": "peer",
        "listen": { "endpoints": section.listen },
        "connect": {
            "endpoints": section.connect,
            "retry": { "period_init_ms": 500, "period_max_ms": 2000, "period_increase_factor": 2 },
        },
        "scouting": {
            "multicast": { "enabled": section.scouting },
            "gossip": { "enabled": section.scouting },
        },
        "transport": {
            "unicast": { "accept_pending": ACCEPT_PENDING, "accept_timeout": ACCEPT_TIMEOUT_MS },
            "link": {
                "tx": { "lease": LEASE_MS },
                "rx": { "max_message_size": MAX_REASSEMBLED_BYTES },
            },
        },
    });
    if let Some(path) = &section.credentials_file {
        let own = super::credentials::read_credentials(path)?;
        json["transport"]["auth"] = serde_json::json!({
            "usrpwd": { "user": own.user, "password": own.password, "dictionary_file": path },
        });
    }
    zenoh::Config::from_json5(&json.to_string())
        .map_err(|e| anyhow::anyhow!("fleet bus configuration: {e}"))
}

/// Opens the session on the current (multi-thread) tokio runtime and starts the tasks. The
/// configuration is checked at once; peers are reached in the background.
pub async fn start(config: NodeConfig) -> anyhow::Result<BusPort> {
    let zconfig = zenoh_config(&config.section)?;
    let join = watch_joins(&config.section);
    let session = zenoh::open(zconfig)
        .await
        .map_err(|e| anyhow::anyhow!("fleet bus: cannot open the Zenoh session: {e}"))?;
    let stats = Arc::new(BusStats::default());
    let maps = Arc::new(MapInbox::default());
    let (in_tx, inbound) = mpsc::channel(QUEUE);
    let (outbound, mut out_rx) = mpsc::channel::<Outbound>(QUEUE);
    let fleet = config.section.name.clone();
    let intake = Intake::new(
        &fleet,
        &config.node,
        config.members,
        config.max_map_cells,
        stats.clone(),
        in_tx,
        maps.clone(),
    );
    let subscriber = session
        .declare_subscriber(format!("kestrel/{fleet}/*/*"))
        .callback(move |sample| {
            // Refusals are counted and said (rate-limited) by the intake.
            let _ = intake.take(sample.key_expr().as_str(), &sample.payload().to_bytes());
        })
        .await
        .map_err(|e| anyhow::anyhow!("fleet bus: cannot subscribe: {e}"))?;
    let fleet = config.section.name.clone();
    let node = config.node.clone();
    let pub_stats = stats.clone();
    let mut signer = config.signer;
    tokio::spawn(async move {
        // The subscriber lives as long as this task: until the control loop drops its port.
        let _subscriber = subscriber;
        let state_key = format!("kestrel/{fleet}/{node}/state");
        let map_key = format!("kestrel/{fleet}/{node}/map");
        let mut not_sent = NotSent::default();
        while let Some(msg) = out_rx.recv().await {
            let (key, kind, bytes, count, sent) = match msg {
                Outbound::State(m) => (
                    &state_key,
                    "state",
                    m.encode(),
                    &pub_stats.state_sent,
                    &pub_stats.state_sent_bytes,
                ),
                Outbound::Map(m) => {
                    // Compressing a keyframe takes a few milliseconds: not on the runtime's
                    // reactor.
                    let Ok(bytes) = tokio::task::spawn_blocking(move || m.encode()).await else {
                        continue;
                    };
                    (
                        &map_key,
                        "map",
                        bytes,
                        &pub_stats.map_sent,
                        &pub_stats.map_sent_bytes,
                    )
                }
            };
            let bytes = signer.seal(&fleet, &node, kind, &bytes);
            let len = bytes.len() as u64;
            let put = session
                .put(key.as_str(), bytes)
                .congestion_control(zenoh::qos::CongestionControl::Drop)
                .await;
            match put {
                Ok(()) => {
                    count.fetch_add(1, Ordering::Relaxed);
                    sent.fetch_add(len, Ordering::Relaxed);
                }
                Err(e) => not_sent.say(&e.to_string()),
            }
        }
        let _ = session.close().await;
    });
    Ok(BusPort {
        inbound,
        maps,
        outbound,
        stats,
        join,
    })
}

/// "Not sent" said once, then at most every [`super::intake::SAY_EVERY`] with a count.
#[derive(Default)]
struct NotSent {
    last: Option<std::time::Instant>,
    held: u64,
}

impl NotSent {
    fn say(&mut self, why: &str) {
        let now = std::time::Instant::now();
        if self
            .last
            .is_some_and(|t| now.duration_since(t) < super::intake::SAY_EVERY)
        {
            self.held += 1;
            return;
        }
        let more = match std::mem::take(&mut self.held) {
            0 => String::new(),
            n => format!(" ({n} more since the last line)"),
        };
        self.last = Some(now);
        tracing::warn!("fleet bus: not sent: {why}{more}");
    }
}
