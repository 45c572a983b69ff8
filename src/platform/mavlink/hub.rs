//! Several vehicles behind one connection (a telemetry radio, mavlink-router), told apart by
//! the autopilots' system ids.
//!
//! In: one connection, served by the same transport task as a single vehicle's (reconnection,
//! `udpin` peer pinning, ground-station forwarding), and the system id of each vehicle's
//! autopilot. Out: per vehicle, the frames its autopilot sent and every transport event; what
//! the vehicles' sessions send goes out on the one connection (each message names its target
//! system). Frames from a system no vehicle claims (another vehicle on the radio, a ground
//! station) are counted and not delivered. A vehicle whose session falls behind loses its own
//! frames, never another vehicle's.

use super::link::{Inbound, Outbound, TransportEvent, INBOUND_QUEUE, OUTBOUND_QUEUE};
use std::collections::BTreeMap;
use std::sync::{Arc, Mutex};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Transport events queued per vehicle.
const TRANSPORT_QUEUE: usize = 8;

/// One connection shared by several vehicles. Attach every vehicle, then drop the hub: its
/// tasks run until the last attached vehicle's platform is dropped.
pub struct LinkHub {
    routes: Arc<Mutex<Routes>>,
    outbound: mpsc::Sender<Outbound>,
    tasks: Arc<HubTasks>,
}

/// A vehicle's side of the hub (what [`super::link::SessionIo`] needs from a transport).
pub struct Attached {
    pub inbound: mpsc::Receiver<Inbound>,
    pub transport: mpsc::Receiver<TransportEvent>,
    pub outbound: mpsc::Sender<Outbound>,
    /// Keeps the hub's tasks running.
    pub keep: Arc<HubTasks>,
}

#[derive(Debug, thiserror::Error, PartialEq, Eq)]
pub enum AttachError {
    #[error("system id {0} is already attached to this connection")]
    Taken(u8),
}

/// The hub's tasks, aborted when the last holder is dropped.
#[derive(Default)]
pub struct HubTasks(Mutex<Vec<JoinHandle<()>>>);

impl HubTasks {
    pub fn push(&self, task: JoinHandle<()>) {
        self.0.lock().unwrap_or_else(|e| e.into_inner()).push(task);
    }
}

impl Drop for HubTasks {
    fn drop(&mut self) {
        for t in self.0.lock().unwrap_or_else(|e| e.into_inner()).iter() {
            t.abort();
        }
    }
}

#[derive(Default)]
struct Routes {
    members: BTreeMap<u32, Member>,
    /// The latest transport event, for a vehicle attached after it.
    last_transport: Option<TransportEvent>,
    /// Frames from a system no vehicle claims.
    unclaimed: u64,
    /// Frames a vehicle's full queue could not take.
    overflowed: u64,
}

struct Member {
    inbound: mpsc::Sender<Inbound>,
    transport: mpsc::Sender<TransportEvent>,
}

/// The channels a transport task is started with (`link::connection_task`, `udp_in::task`).
pub struct TransportEnds {
    pub inbound: mpsc::Sender<Inbound>,
    pub outbound: mpsc::Receiver<Outbound>,
    pub transport: mpsc::Sender<TransportEvent>,
}

impl LinkHub {
    /// The hub and the ends to start its one transport task with (on the current runtime).
    pub fn new() -> (Self, TransportEnds) {
        let (inbound_tx, inbound_rx) = mpsc::channel(INBOUND_QUEUE);
        let (outbound_tx, outbound_rx) = mpsc::channel(OUTBOUND_QUEUE);
        let (transport_tx, transport_rx) = mpsc::channel(TRANSPORT_QUEUE);
        let routes = Arc::new(Mutex::new(Routes::default()));
        let tasks = Arc::new(HubTasks::default());
        tasks.push(tokio::spawn(dispatch(
            inbound_rx,
            transport_rx,
            routes.clone(),
        )));
        let hub = LinkHub {
            routes,
            outbound: outbound_tx.clone(),
            tasks,
        };
        let ends = TransportEnds {
            inbound: inbound_tx,
            outbound: outbound_rx,
            transport: transport_tx,
        };
        (hub, ends)
    }

    /// A task that lives as long as the hub's vehicles (the transport, ground-station routers).
    pub fn keep(&self, task: JoinHandle<()>) {
        self.tasks.push(task);
    }

    /// A sender of frames to the connection (for a ground-station router).
    pub fn outbound(&self) -> mpsc::Sender<Outbound> {
        self.outbound.clone()
    }

    /// Routes `system_id`'s frames to a new vehicle.
    pub fn attach(&self, system_id: u8) -> Result<Attached, AttachError> {
        let (inbound_tx, inbound_rx) = mpsc::channel(INBOUND_QUEUE);
        let (transport_tx, transport_rx) = mpsc::channel(TRANSPORT_QUEUE);
        let mut routes = self.routes.lock().unwrap_or_else(|e| e.into_inner());
        let key = u32::from(system_id);
        if routes.members.contains_key(&key) {
            return Err(AttachError::Taken(system_id));
        }
        if let Some(last) = &routes.last_transport {
            let _ = transport_tx.try_send(last.clone());
        }
        routes.members.insert(
            key,
            Member {
                inbound: inbound_tx,
                transport: transport_tx,
            },
        );
        Ok(Attached {
            inbound: inbound_rx,
            transport: transport_rx,
            outbound: self.outbound.clone(),
            keep: self.tasks.clone(),
        })
    }
}

/// Hands each frame to the vehicle whose autopilot sent it, and every transport event to all.
async fn dispatch(
    mut inbound: mpsc::Receiver<Inbound>,
    mut transport: mpsc::Receiver<TransportEvent>,
    routes: Arc<Mutex<Routes>>,
) {
    loop {
        tokio::select! {
            frame = inbound.recv() => {
                let Some(frame) = frame else { return };
                deliver(&routes, frame);
            }
            event = transport.recv() => {
                let Some(event) = event else { return };
                let mut r = routes.lock().unwrap_or_else(|e| e.into_inner());
                r.members.retain(|_, m| match m.transport.try_send(event.clone()) {
                    Err(mpsc::error::TrySendError::Closed(_)) => false,
                    // A full queue holds events the session has not read yet: it will.
                    _ => true,
                });
                r.last_transport = Some(event);
            }
        }
    }
}

fn deliver(routes: &Mutex<Routes>, frame: Inbound) {
    let mut r = routes.lock().unwrap_or_else(|e| e.into_inner());
    let system = frame.header.system_id;
    let Some(member) = r.members.get(&system) else {
        r.unclaimed += 1;
        if r.unclaimed.is_power_of_two() {
            tracing::debug!(target: "mavlink", "{} frames from systems no vehicle claims (last: {system})", r.unclaimed);
        }
        return;
    };
    match member.inbound.try_send(frame) {
        Ok(()) => {}
        Err(mpsc::error::TrySendError::Closed(_)) => {
            r.members.remove(&system);
        }
        Err(mpsc::error::TrySendError::Full(_)) => {
            r.overflowed += 1;
            if r.overflowed.is_power_of_two() {
                tracing::warn!(target: "mavlink", "system {system}: {} frames dropped (its session is not keeping up)", r.overflowed);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{MavMessage, HEARTBEAT_DATA};
    use mavlink::{MAVLinkMessageRaw, MAVLinkV2MessageRaw, MavHeader};

    fn frame(system_id: u32) -> Inbound {
        let header = MavHeader {
            system_id,
            component_id: 1,
            sequence: 0,
        };
        let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        Inbound {
            header,
            msg,
            raw: Arc::new(MAVLinkMessageRaw::V2(MAVLinkV2MessageRaw::new())),
        }
    }

    #[tokio::test]
    async fn each_vehicle_gets_its_own_autopilots_frames_and_every_transport_event() {
        let (hub, ends) = LinkHub::new();
        let mut one = hub.attach(1).unwrap();
        let mut two = hub.attach(2).unwrap();
        assert_eq!(hub.attach(2).err(), Some(AttachError::Taken(2)));
        ends.transport
            .send(TransportEvent::Connected)
            .await
            .unwrap();
        for s in [2, 1, 9, 2] {
            ends.inbound.send(frame(s)).await.unwrap();
        }
        assert_eq!(one.transport.recv().await, Some(TransportEvent::Connected));
        assert_eq!(two.transport.recv().await, Some(TransportEvent::Connected));
        assert_eq!(one.inbound.recv().await.unwrap().header.system_id, 1);
        assert_eq!(two.inbound.recv().await.unwrap().header.system_id, 2);
        assert_eq!(two.inbound.recv().await.unwrap().header.system_id, 2);
        // System 9 is nobody's; nothing more for vehicle 1.
        assert!(one.inbound.try_recv().is_err());
        // What either sends goes to the one connection.
        let mut out = ends.outbound;
        one.outbound
            .send(Outbound::Message(frame(1).header, Box::new(frame(1).msg)))
            .await
            .unwrap();
        two.outbound
            .send(Outbound::Message(frame(2).header, Box::new(frame(2).msg)))
            .await
            .unwrap();
        assert!(out.recv().await.is_some() && out.recv().await.is_some());
        // A vehicle attached later learns the connection's state.
        let mut late = hub.attach(3).unwrap();
        assert_eq!(late.transport.recv().await, Some(TransportEvent::Connected));
    }

    #[tokio::test]
    async fn a_stalled_vehicle_loses_only_its_own_frames() {
        let (hub, ends) = LinkHub::new();
        let _stalled = hub.attach(1).unwrap();
        let mut live = hub.attach(2).unwrap();
        for _ in 0..INBOUND_QUEUE + 10 {
            ends.inbound.send(frame(1)).await.unwrap();
        }
        ends.inbound.send(frame(2)).await.unwrap();
        assert_eq!(live.inbound.recv().await.unwrap().header.system_id, 2);
    }

    #[tokio::test]
    async fn the_tasks_stop_with_the_last_vehicle() {
        let (hub, ends) = LinkHub::new();
        let attached = hub.attach(1).unwrap();
        drop(hub);
        drop(attached);
        // The dispatcher was aborted: its receiver is gone.
        tokio::time::timeout(std::time::Duration::from_secs(2), ends.inbound.closed())
            .await
            .expect("the dispatcher stopped");
    }
}
