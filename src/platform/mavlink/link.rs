//! The async edge: connection with reconnection, reading, writing and session ticking.
//!
//! In: a connection string (`udpin:`, `udpout:`, `tcpout:`, `tcpin:`, `serial:PORT:BAUD`), the
//! session, and control messages from the facade. Out: the session's snapshot (`watch`), its
//! scans and request results (bounded channel), and frames on the wire. Three tasks:
//! - the connection task connects (again and again: a serial port unplugged and plugged back,
//!   a TCP server restarted), spawns a reader per connection and writes what the session sends;
//! - the session task owns the [`Session`] and feeds it messages, control outputs and a 5 ms
//!   tick, with the time since start;
//! - the router (optional, `router.rs`) copies frames between the autopilot and ground stations.

use super::session::Session;
use super::statustext::StatusText;
use crate::platform::{PlatformEvent, PlatformRequest, RequestResult};
use crate::types::Measurement;
use crate::types::PlatformStatus;
use crate::types::RangeScan;
use crate::types::Setpoint;
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::error::MessageWriteError;
use mavlink::{AsyncMavConnection, MAVLinkMessageRaw, MavHeader, MavlinkVersion, Message};
use std::net::SocketAddr;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::time::Instant;

/// Session housekeeping period (retries, heartbeat, link timeout, setpoint re-sends).
const TICK: Duration = Duration::from_millis(5);
const CONNECT_TIMEOUT: Duration = Duration::from_secs(3);
const RECONNECT_MIN: Duration = Duration::from_millis(200);
const RECONNECT_MAX: Duration = Duration::from_secs(2);
/// Queue sizes: inbound frames, outbound frames, control outputs, scans and results, texts for
/// the ground station (the session's own queue behind it drops the oldest).
pub const INBOUND_QUEUE: usize = 2048;
pub const OUTBOUND_QUEUE: usize = 512;
pub const CONTROL_QUEUE: usize = 64;
pub const EVENT_QUEUE: usize = 1024;
pub const TEXT_QUEUE: usize = 32;

pub type Connection = mavlink::AsyncConnection<MavMessage>;

/// One decoded frame with its raw bytes (kept for routing to ground stations).
pub struct Inbound {
    pub header: MavHeader,
    pub msg: MavMessage,
    pub raw: Arc<MAVLinkMessageRaw>,
}

/// A frame for the autopilot: ours (encoded by the connection) or a ground station's (as is).
pub enum Outbound {
    Message(MavHeader, Box<MavMessage>),
    Raw(Arc<MAVLinkMessageRaw>),
}

/// One control tick's outputs, from the facade to the session task.
pub struct Control {
    pub setpoint: Option<Setpoint>,
    pub requests: Vec<PlatformRequest>,
}

/// What changes continuously: the latest value is all that matters.
#[derive(Debug, Clone, Default)]
pub struct Snapshot {
    pub status: PlatformStatus,
    pub odometry: Option<Measurement>,
    /// The latest takeover and how many there were: carried with the status it changed, so the
    /// core never sees the new mode without it (and a full event queue cannot lose it).
    pub takeover: Option<(u64, PlatformEvent)>,
}

/// What must not be lost between two polls.
#[derive(Debug, Clone)]
pub enum Event {
    Scan(RangeScan),
    Result(RequestResult),
}

/// Connection state reported to the session task.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum TransportEvent {
    Connected,
    Failed(String),
    /// `udpin` with `pin_peer`: the autopilot's address was pinned; `previous` is the one it
    /// replaced, and `changes` counts such replacements (`peer.rs`).
    Pinned {
        address: SocketAddr,
        previous: Option<SocketAddr>,
        changes: u32,
    },
}

/// Decodes a raw frame with the ardupilotmega dialect (unknown ids are skipped).
pub fn decode(raw: &MAVLinkMessageRaw) -> Option<(MavHeader, MavMessage)> {
    let msg = MavMessage::parse(raw.version(), raw.message_id(), raw.payload()).ok()?;
    let header = MavHeader {
        system_id: raw.system_id(),
        component_id: raw.component_id(),
        sequence: raw.sequence(),
    };
    Some((header, msg))
}

/// Opens a connection (with a timeout: a TCP connect to a silent host can hang for minutes).
pub async fn open(address: &str) -> std::io::Result<Connection> {
    let mut conn = tokio::time::timeout(CONNECT_TIMEOUT, mavlink::connect_async(address))
        .await
        .map_err(|_| std::io::Error::new(std::io::ErrorKind::TimedOut, "connect timed out"))??;
    conn.set_protocol_version(MavlinkVersion::V2);
    conn.set_allow_recv_any_version(true);
    Ok(conn)
}

/// Reads frames until the connection fails, forwarding them decoded (and raw to the router).
async fn read_loop(
    conn: Arc<Connection>,
    inbound: mpsc::Sender<Inbound>,
    router: Option<broadcast::Sender<Arc<MAVLinkMessageRaw>>>,
) -> String {
    loop {
        let raw = match conn.recv_raw().await {
            Ok(raw) => Arc::new(raw),
            Err(e) => return format!("read: {e}"),
        };
        if let Some(r) = &router {
            // No ground station listening is not an error.
            let _ = r.send(raw.clone());
        }
        let Some((header, msg)) = decode(&raw) else {
            continue;
        };
        if inbound.send(Inbound { header, msg, raw }).await.is_err() {
            return "session ended".into();
        }
    }
}

async fn write(conn: &Connection, out: Outbound) -> Result<(), MessageWriteError> {
    let r = match out {
        Outbound::Message(header, msg) => conn.send(&header, &msg).await,
        Outbound::Raw(raw) => conn.send_raw(&raw).await,
    };
    r.map(|_| ())
}

/// Keeps a connection to the autopilot open for as long as the session runs.
pub async fn connection_task(
    address: String,
    inbound: mpsc::Sender<Inbound>,
    mut outbound: mpsc::Receiver<Outbound>,
    transport: mpsc::Sender<TransportEvent>,
    router: Option<broadcast::Sender<Arc<MAVLinkMessageRaw>>>,
) {
    let mut backoff = RECONNECT_MIN;
    loop {
        let conn = match open(&address).await {
            Ok(c) => Arc::new(c),
            Err(e) => {
                let _ = transport
                    .send(TransportEvent::Failed(format!("{address}: {e}")))
                    .await;
                // What was queued while disconnected is stale: never send it late.
                while outbound.try_recv().is_ok() {}
                tokio::time::sleep(backoff).await;
                backoff = (backoff * 2).min(RECONNECT_MAX);
                continue;
            }
        };
        backoff = RECONNECT_MIN;
        tracing::info!(target: "mavlink", "{address} open: waiting for HEARTBEAT");
        let _ = transport.send(TransportEvent::Connected).await;
        let mut reader = tokio::spawn(read_loop(conn.clone(), inbound.clone(), router.clone()));
        let reason = loop {
            tokio::select! {
                out = outbound.recv() => match out {
                    None => {
                        reader.abort();
                        return;
                    }
                    Some(o) => {
                        if let Err(e) = write(&conn, o).await {
                            break format!("write: {e}");
                        }
                    }
                },
                r = &mut reader => break r.unwrap_or_else(|e| format!("reader: {e}")),
            }
        };
        reader.abort();
        if inbound.is_closed() {
            return;
        }
        let _ = transport
            .send(TransportEvent::Failed(format!("{address}: {reason}")))
            .await;
        tokio::time::sleep(backoff).await;
    }
}

/// The session's side of the channels.
pub struct SessionIo {
    pub inbound: mpsc::Receiver<Inbound>,
    pub control: mpsc::Receiver<Control>,
    pub texts: mpsc::Receiver<StatusText>,
    pub transport: mpsc::Receiver<TransportEvent>,
    pub outbound: mpsc::Sender<Outbound>,
    pub snapshot: watch::Sender<Snapshot>,
    pub events: mpsc::Sender<Event>,
    /// Texts taken from `texts` that left (handed to `outbound`) or were dropped.
    pub texts_done: Arc<AtomicU64>,
}

/// Runs the session until the facade is dropped.
pub async fn session_task(mut session: Session, mut io: SessionIo) {
    let start = Instant::now();
    let mut tick = tokio::time::interval(TICK);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Skip);
    let mut dropped_out = 0u64;
    let mut takeover: Option<(u64, PlatformEvent)> = None;
    let mut texts_taken = 0u64;
    loop {
        let publish = tokio::select! {
            biased;
            c = io.control.recv() => match c {
                None => return,
                Some(c) => {
                    session.on_control(start.elapsed(), c.setpoint, &c.requests);
                    true
                }
            },
            m = io.inbound.recv() => match m {
                None => return,
                Some(m) => {
                    session.on_message(start.elapsed(), &m.header, &m.msg);
                    false
                }
            },
            // Disabled once every sender is gone (`None` does not match).
            Some(text) = io.texts.recv() => {
                texts_taken += 1;
                session.announce(text);
                false
            },
            t = io.transport.recv() => {
                match t {
                    Some(TransportEvent::Failed(e)) => {
                        tracing::warn!(target: "mavlink", "connection: {e}");
                        session.note_transport_error(e);
                    }
                    Some(TransportEvent::Pinned { address, previous, changes }) => {
                        session.note_peer(address, previous, changes);
                    }
                    Some(TransportEvent::Connected) => {}
                    None => return,
                }
                false
            },
            _ = tick.tick() => {
                session.on_tick(start.elapsed());
                true
            }
        };
        for (header, msg) in session.drain_outgoing() {
            if io
                .outbound
                .try_send(Outbound::Message(header, Box::new(msg)))
                .is_err()
            {
                dropped_out += 1;
                if dropped_out.is_power_of_two() {
                    tracing::warn!(target: "mavlink", "{dropped_out} outgoing messages dropped (link congested)");
                }
            }
        }
        io.texts_done.store(
            texts_taken.saturating_sub(session.texts_waiting() as u64),
            Ordering::Release,
        );
        if publish {
            let fb = session.feedback(start.elapsed());
            for e in fb.events {
                let n = takeover.as_ref().map_or(0, |(n, _)| *n);
                takeover = Some((n + 1, e));
            }
            io.snapshot.send_replace(Snapshot {
                status: fb.status,
                odometry: fb.measurements.into_iter().last(),
                takeover: takeover.clone(),
            });
            let events = fb
                .scans
                .into_iter()
                .map(Event::Scan)
                .chain(fb.request_results.into_iter().map(Event::Result));
            for e in events {
                if io.events.try_send(e).is_err() {
                    tracing::warn!(target: "mavlink", "feedback queue full: the control loop is not polling");
                }
            }
        }
    }
}
