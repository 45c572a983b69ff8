//! [`MavlinkPlatform`]: the synchronous [`Platform`] the core drives, over the async link.
//!
//! In: each control tick's setpoint and requests (sent on a bounded channel, never waiting).
//! Out: the latest snapshot (`watch`) plus the scans and request results queued since the last
//! poll. Create it inside a tokio runtime; dropping it stops its tasks.

use super::link::{
    self, Control, Event, SessionIo, Snapshot, CONTROL_QUEUE, EVENT_QUEUE, INBOUND_QUEUE,
    OUTBOUND_QUEUE,
};
use super::peer::PeerPolicy;
use super::profile::Profile;
use super::router::{self, ROUTER_QUEUE};
use super::session::{Session, SessionConfig};
use super::udp_in;
use crate::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::Setpoint;
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
}

pub struct MavlinkPlatform {
    capabilities: Capabilities,
    control: mpsc::Sender<Control>,
    snapshot: watch::Receiver<Snapshot>,
    events: mpsc::Receiver<Event>,
    dropped_controls: u64,
    tasks: Vec<JoinHandle<()>>,
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
        mavlink::ConnectionAddress::parse_address(&link_config.connection)
            .map_err(|e| LinkError::Address(link_config.connection.clone(), e.to_string()))?;
        for f in &link_config.forward {
            mavlink::ConnectionAddress::parse_address(f)
                .map_err(|e| LinkError::Address(f.clone(), e.to_string()))?;
        }
        let session = Session::new(profile, session_config);
        let capabilities = session.capabilities();
        let (inbound_tx, inbound_rx) = mpsc::channel(INBOUND_QUEUE);
        let (outbound_tx, outbound_rx) = mpsc::channel(OUTBOUND_QUEUE);
        let (control_tx, control_rx) = mpsc::channel(CONTROL_QUEUE);
        let (transport_tx, transport_rx) = mpsc::channel(8);
        let (snapshot_tx, snapshot_rx) = watch::channel(Snapshot::default());
        let (events_tx, events_rx) = mpsc::channel(EVENT_QUEUE);
        let router = (!link_config.forward.is_empty()).then(|| broadcast::channel(ROUTER_QUEUE).0);
        let mut tasks = Vec::new();
        for endpoint in &link_config.forward {
            if let Some(r) = &router {
                tasks.push(handle.spawn(router::endpoint_task(
                    endpoint.clone(),
                    r.subscribe(),
                    outbound_tx.clone(),
                )));
            }
        }
        // `udpin` is Kestrel's own (the peer pinned); the crate's connection for the rest.
        let transport = match link_config.connection.strip_prefix("udpin:") {
            Some(bind) => handle.spawn(udp_in::task(
                bind.to_string(),
                link_config.peers,
                inbound_tx,
                outbound_rx,
                transport_tx,
                router,
            )),
            None => handle.spawn(link::connection_task(
                link_config.connection,
                inbound_tx,
                outbound_rx,
                transport_tx,
                router,
            )),
        };
        tasks.push(transport);
        let io = SessionIo {
            inbound: inbound_rx,
            control: control_rx,
            transport: transport_rx,
            outbound: outbound_tx,
            snapshot: snapshot_tx,
            events: events_tx,
        };
        tasks.push(handle.spawn(link::session_task(session, io)));
        Ok(Self {
            capabilities,
            control: control_tx,
            snapshot: snapshot_rx,
            events: events_rx,
            dropped_controls: 0,
            tasks,
        })
    }
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
