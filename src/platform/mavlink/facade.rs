//! [`MavlinkPlatform`]: the synchronous [`Platform`] the core drives, over the async link.
//!
//! In: each control tick's setpoint and requests (sent on a bounded channel, never waiting);
//! texts for the ground station through a [`TextSender`] (the same, from any thread). Out: the
//! latest snapshot (`watch`) plus the scans and request results queued since the last poll.
//! Create it inside a tokio runtime; dropping it stops its tasks.

use super::hub::{HubTasks, LinkHub, TransportEnds};
use super::link::{
    self, Control, Event, SessionIo, Snapshot, CONTROL_QUEUE, EVENT_QUEUE, INBOUND_QUEUE,
    OUTBOUND_QUEUE, TEXT_QUEUE,
};
use super::peer::PeerPolicy;
use super::profile::Profile;
use super::router::{self, ROUTER_QUEUE};
use super::session::{Session, SessionConfig};
use super::statustext::StatusText;
use super::udp_in;
use crate::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::Setpoint;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::sync::{broadcast, mpsc, watch};
use tokio::task::JoinHandle;

/// Where to connect and whom to forward to.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LinkConfig {
    /// `udpin:0.0.0.0:14540`, `tcpout:127.0.0.1:5760`, `serial:/dev/ttyACM0:921600` ...
    pub connection: String,
    /// Ground station endpoints that get the autopilot's stream (and whose commands go back).
    pub forward: Vec<String>,
    /// `udpin` only: whose datagrams are taken and who is answered.
    pub peers: PeerPolicy,
}

#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    #[error("connection string `{0}`: {1}")]
    Address(String, String),
    #[error("the MAVLink platform needs a tokio runtime")]
    NoRuntime,
    #[error(
        "a vehicle behind a shared connection needs its autopilot's system id (target_system)"
    )]
    SharedWithoutSystem,
    #[error("shared connection: {0}")]
    Shared(String),
}

pub struct MavlinkPlatform {
    capabilities: Capabilities,
    control: mpsc::Sender<Control>,
    snapshot: watch::Receiver<Snapshot>,
    events: mpsc::Receiver<Event>,
    /// How many takeovers the core was told of.
    takeovers_seen: u64,
    texts: TextSender,
    dropped_controls: u64,
    tasks: Vec<JoinHandle<()>>,
    /// The shared connection's tasks, when behind one ([`start_hub`]).
    _hub: Option<Arc<HubTasks>>,
}

impl MavlinkPlatform {
    /// Starts the link and session tasks. The connection is opened (and re-opened) in the
    /// background; an unreachable autopilot shows as `link: connecting` with the error.
    pub fn start(
        profile: Profile,
        session_config: SessionConfig,
        link_config: LinkConfig,
    ) -> Result<Self, LinkError> {
        let handle = tokio::runtime::Handle::try_current().map_err(|_| LinkError::NoRuntime)?;
        check_addresses(&link_config)?;
        let (inbound_tx, inbound_rx) = mpsc::channel(INBOUND_QUEUE);
        let (outbound_tx, outbound_rx) = mpsc::channel(OUTBOUND_QUEUE);
        let (transport_tx, transport_rx) = mpsc::channel(8);
        let ends = TransportEnds {
            inbound: inbound_tx,
            outbound: outbound_rx,
            transport: transport_tx,
        };
        let tasks = spawn_transport(&handle, link_config, ends, &outbound_tx);
        let io = (inbound_rx, transport_rx, outbound_tx);
        Ok(Self::with_session(
            &handle,
            profile,
            session_config,
            io,
            tasks,
            None,
        ))
    }

    /// Starts one vehicle of several behind one connection ([`LinkHub`], from [`start_hub`]):
    /// its session hears only its autopilot (`session_config.target_system`, required).
    pub fn start_shared(
        profile: Profile,
        session_config: SessionConfig,
        hub: &LinkHub,
    ) -> Result<Self, LinkError> {
        let handle = tokio::runtime::Handle::try_current().map_err(|_| LinkError::NoRuntime)?;
        let system = session_config
            .target_system
            .ok_or(LinkError::SharedWithoutSystem)?;
        let attached = hub
            .attach(system)
            .map_err(|e| LinkError::Shared(e.to_string()))?;
        let io = (attached.inbound, attached.transport, attached.outbound);
        Ok(Self::with_session(
            &handle,
            profile,
            session_config,
            io,
            Vec::new(),
            Some(attached.keep),
        ))
    }

    fn with_session(
        handle: &tokio::runtime::Handle,
        profile: Profile,
        session_config: SessionConfig,
        (inbound, transport, outbound): SessionEnds,
        mut tasks: Vec<JoinHandle<()>>,
        hub: Option<Arc<HubTasks>>,
    ) -> Self {
        let session = Session::new(profile, session_config);
        let capabilities = session.capabilities();
        let (control_tx, control_rx) = mpsc::channel(CONTROL_QUEUE);
        let (snapshot_tx, snapshot_rx) = watch::channel(Snapshot::default());
        let (events_tx, events_rx) = mpsc::channel(EVENT_QUEUE);
        let (texts_tx, texts_rx) = mpsc::channel(TEXT_QUEUE);
        let io = SessionIo {
            inbound,
            control: control_rx,
            texts: texts_rx,
            transport,
            outbound,
            snapshot: snapshot_tx,
            events: events_tx,
        };
        tasks.push(handle.spawn(link::session_task(session, io)));
        Self {
            capabilities,
            control: control_tx,
            snapshot: snapshot_rx,
            events: events_rx,
            takeovers_seen: 0,
            texts: TextSender {
                tx: texts_tx,
                dropped: Arc::new(AtomicU64::new(0)),
            },
            dropped_controls: 0,
            tasks,
            _hub: hub,
        }
    }
}

impl MavlinkPlatform {
    /// Where Kestrel's texts for this vehicle's ground station go (STATUSTEXT on its link).
    pub fn texts(&self) -> TextSender {
        self.texts.clone()
    }
}

/// Hands texts to one vehicle's session without waiting: a full queue drops the text, counted.
#[derive(Debug, Clone)]
pub struct TextSender {
    tx: mpsc::Sender<StatusText>,
    dropped: Arc<AtomicU64>,
}

impl TextSender {
    /// Queues `text`; false when it was dropped (queue full, or the vehicle is gone).
    pub fn send(&self, text: StatusText) -> bool {
        let sent = self.tx.try_send(text).is_ok();
        if !sent {
            let n = self.dropped.fetch_add(1, Ordering::Relaxed) + 1;
            if n.is_power_of_two() {
                tracing::warn!(target: "mavlink", "{n} texts for the ground station dropped");
            }
        }
        sent
    }

    /// Texts dropped so far at this end.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// A session's ends of its transport: frames in, transport events, frames out.
type SessionEnds = (
    mpsc::Receiver<link::Inbound>,
    mpsc::Receiver<link::TransportEvent>,
    mpsc::Sender<link::Outbound>,
);

/// Opens one connection for several vehicles, told apart by system id: attach each with
/// [`MavlinkPlatform::start_shared`].
pub fn start_hub(link_config: LinkConfig) -> Result<LinkHub, LinkError> {
    let handle = tokio::runtime::Handle::try_current().map_err(|_| LinkError::NoRuntime)?;
    check_addresses(&link_config)?;
    // Every vehicle's autopilot may pin the `udpin` peer (the radio or router they are behind).
    let mut link_config = link_config;
    link_config.peers.target_system = None;
    let (hub, ends) = LinkHub::new();
    let outbound = hub.outbound();
    for task in spawn_transport(&handle, link_config, ends, &outbound) {
        hub.keep(task);
    }
    Ok(hub)
}

fn check_addresses(link_config: &LinkConfig) -> Result<(), LinkError> {
    for a in std::iter::once(&link_config.connection).chain(&link_config.forward) {
        mavlink::ConnectionAddress::parse_address(a)
            .map_err(|e| LinkError::Address(a.clone(), e.to_string()))?;
    }
    Ok(())
}

/// Spawns the connection's transport task, and a router per ground-station endpoint.
fn spawn_transport(
    handle: &tokio::runtime::Handle,
    link_config: LinkConfig,
    ends: TransportEnds,
    outbound: &mpsc::Sender<link::Outbound>,
) -> Vec<JoinHandle<()>> {
    let router = (!link_config.forward.is_empty()).then(|| broadcast::channel(ROUTER_QUEUE).0);
    let mut tasks = Vec::new();
    if let Some(r) = &router {
        for endpoint in &link_config.forward {
            tasks.push(handle.spawn(router::endpoint_task(
                endpoint.clone(),
                r.subscribe(),
                outbound.clone(),
            )));
        }
    }
    let TransportEnds {
        inbound,
        outbound: outbound_rx,
        transport,
    } = ends;
    // `udpin` is Kestrel's own (the peer pinned); the crate's connection for the rest.
    tasks.push(match link_config.connection.strip_prefix("udpin:") {
        Some(bind) => handle.spawn(udp_in::task(
            bind.to_string(),
            link_config.peers,
            inbound,
            outbound_rx,
            transport,
            router,
        )),
        None => handle.spawn(link::connection_task(
            link_config.connection,
            inbound,
            outbound_rx,
            transport,
            router,
        )),
    });
    tasks
}

impl Drop for MavlinkPlatform {
    fn drop(&mut self) {
        for t in &self.tasks {
            t.abort();
        }
    }
}

impl Platform for MavlinkPlatform {
    fn capabilities(&self) -> Capabilities {
        self.capabilities
    }

    fn poll(&mut self, _now: Duration) -> PlatformFeedback {
        let snap = self.snapshot.borrow().clone();
        let mut fb = PlatformFeedback {
            status: snap.status,
            measurements: snap.odometry.into_iter().collect(),
            ..PlatformFeedback::default()
        };
        if let Some((n, event)) = snap.takeover.filter(|(n, _)| *n != self.takeovers_seen) {
            self.takeovers_seen = n;
            fb.events.push(event);
        }
        while let Ok(e) = self.events.try_recv() {
            match e {
                Event::Scan(s) => fb.scans.push(s),
                Event::Result(r) => fb.request_results.push(r),
            }
        }
        fb
    }

    fn command(
        &mut self,
        _now: Duration,
        setpoint: Option<Setpoint>,
        requests: &[PlatformRequest],
    ) {
        let control = Control {
            setpoint,
            requests: requests.to_vec(),
        };
        if self.control.try_send(control).is_err() {
            // The session task is stuck: dropping a setpoint is safe (the stream stops and the
            // autopilot's failsafe acts); a dropped request is retried by its behavior.
            self.dropped_controls += 1;
            if self.dropped_controls.is_power_of_two() {
                tracing::warn!(target: "mavlink", "{} control outputs dropped", self.dropped_controls);
            }
        }
    }
}
