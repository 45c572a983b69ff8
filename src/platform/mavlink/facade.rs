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
        let texts_done = Arc::new(AtomicU64::new(0));
        let frames_out = outbound.downgrade();
        let io = SessionIo {
            inbound,
            control: control_rx,
            texts: texts_rx,
            transport,
            outbound,
            snapshot: snapshot_tx,
            events: events_tx,
            texts_done: texts_done.clone(),
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
                accepted: Arc::new(AtomicU64::new(0)),
                done: texts_done,
                frames_out,
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
    /// Texts queued here, and those of them the session sent on or dropped.
    accepted: Arc<AtomicU64>,
    done: Arc<AtomicU64>,
    /// The frames to the autopilot (ours among them), to see they were written.
    frames_out: mpsc::WeakSender<link::Outbound>,
}

impl TextSender {
    /// Queues `text`; false when it was dropped (queue full, or the vehicle is gone).
    pub fn send(&self, text: StatusText) -> bool {
        self.accepted.fetch_add(1, Ordering::AcqRel);
        let sent = self.tx.try_send(text).is_ok();
        if !sent {
            self.accepted.fetch_sub(1, Ordering::AcqRel);
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

    /// True while a text queued here has not yet left for the autopilot: still waiting for
    /// the session's pacing or for the link, or in the frames the connection has not written.
    /// A process about to exit waits (bounded) for this to turn false, so the ground station
    /// sees the last words (`... finished`).
    pub fn pending(&self) -> bool {
        let unsent = self.accepted.load(Ordering::Acquire) > self.done.load(Ordering::Acquire);
        let unwritten = self
            .frames_out
            .upgrade()
            .is_some_and(|out| out.capacity() < out.max_capacity());
        unsent || unwritten
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::mavlink::statustext::Severity;
    use crate::platform::mavlink::testutil::{autopilot_header, hb, px4_profile};
    use mavlink::dialects::ardupilotmega::MavMessage;
    use mavlink::{MAVLinkMessageRaw, MAVLinkV2MessageRaw};

    /// The connection's side: the autopilot's heartbeat in, our frames out.
    async fn heard(ends: &TransportEnds) {
        ends.inbound
            .send(link::Inbound {
                header: autopilot_header(),
                msg: hb(0x0304_0000, false),
                raw: Arc::new(MAVLinkMessageRaw::V2(MAVLinkV2MessageRaw::new())),
            })
            .await
            .unwrap();
        ends.transport
            .send(link::TransportEvent::Connected)
            .await
            .unwrap();
    }

    #[tokio::test]
    async fn a_text_is_pending_until_its_frames_were_taken_by_the_connection() {
        let (hub, mut ends) = LinkHub::new();
        let config = SessionConfig {
            target_system: Some(1),
            ..SessionConfig::default()
        };
        let platform = MavlinkPlatform::start_shared(px4_profile(), config, &hub).unwrap();
        let texts = platform.texts();
        assert!(!texts.pending(), "nothing queued");
        let sent = texts.send(StatusText {
            severity: Severity::Notice,
            text: "mission 1 finished".into(),
        });
        assert!(sent);
        // No autopilot heard: the text waits for the link.
        tokio::time::sleep(Duration::from_millis(100)).await;
        assert!(texts.pending(), "no link yet: the text waits");
        heard(&ends).await;
        let deadline = tokio::time::Instant::now() + Duration::from_secs(5);
        let mut statustext = None;
        while statustext.is_none() {
            let out = tokio::time::timeout_at(deadline, ends.outbound.recv())
                .await
                .expect("the text goes out once the autopilot is heard")
                .unwrap();
            if let link::Outbound::Message(_, msg) = out {
                if let MavMessage::STATUSTEXT(t) = *msg {
                    statustext = Some(t);
                }
            }
        }
        let text = String::from_utf8_lossy(&statustext.unwrap().text.to_vec()).to_string();
        assert!(text.starts_with("Kestrel: mission 1 finished"), "{text}");
        // Pending until the connection took every frame queued with it.
        let settle = tokio::time::Instant::now() + Duration::from_secs(2);
        while texts.pending() && tokio::time::Instant::now() < settle {
            while ends.outbound.try_recv().is_ok() {}
            tokio::time::sleep(Duration::from_millis(5)).await;
        }
        assert!(!texts.pending(), "sent and written: nothing pending");
    }
}
