//! The `udpin:` transport, Kestrel's own: one UDP socket, the peer pinned by [`PeerPin`].
//!
//! In: the bind address, the [`PeerPolicy`], Kestrel's outbound frames. Out: the frames of the
//! datagrams the pin takes (decoded, and raw to the router), sent on the same channels as every
//! other transport ([`super::link::connection_task`]). Each datagram is parsed on its own
//! (`recv_from`, then the crate's frame parser over its bytes), so a stranger's bytes can
//! neither be mistaken for the autopilot's nor break a frame of it; Kestrel's frames go with
//! `send_to` to the pinned address only, never to whoever sent last.

use super::link::{decode, Inbound, Outbound, TransportEvent};
use super::peer::{PeerPin, PeerPolicy};
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MAVLinkMessageRaw, MavHeader, MavlinkReader, MavlinkVersion};
use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::UdpSocket;
use tokio::sync::{broadcast, mpsc};
use tokio::time::Instant;

const REBIND_AFTER: Duration = Duration::from_secs(1);
/// Largest UDP payload.
const DATAGRAM: usize = 65_536;

/// Every CRC-valid frame in one datagram, in order (unknown messages are skipped later). Bytes
/// that are no frame are skipped; a frame behind a cut one may be lost with it (the parser
/// waits for the cut frame's length and the datagram ends), never mixed with the next datagram.
pub fn frames(datagram: &[u8]) -> Vec<MAVLinkMessageRaw> {
    let mut reader = MavlinkReader::new(datagram);
    let mut out = Vec::new();
    // The reader skips bytes that are no frame and ends with an error at the datagram's end.
    while let Ok(raw) = reader.read_any_raw_message::<MavMessage>() {
        out.push(raw);
    }
    out
}

/// The bytes of one outbound frame; ours get the next sequence number.
fn encode(out: &Outbound, sequence: &mut u8) -> Option<Vec<u8>> {
    match out {
        Outbound::Message(header, msg) => {
            let header = MavHeader {
                sequence: *sequence,
                ..*header
            };
            *sequence = sequence.wrapping_add(1);
            let mut bytes = Vec::with_capacity(280);
            mavlink::write_versioned_msg(&mut bytes, MavlinkVersion::V2, header, msg.as_ref())
                .ok()?;
            Some(bytes)
        }
        Outbound::Raw(raw) => Some(
            match raw.as_ref() {
                MAVLinkMessageRaw::V1(m) => m.raw_bytes(),
                MAVLinkMessageRaw::V2(m) => m.raw_bytes(),
            }
            .to_vec(),
        ),
    }
}

/// Binds `address` (`IP:port`) and serves it for as long as the session runs.
pub async fn task(
    address: String,
    policy: PeerPolicy,
    inbound: mpsc::Sender<Inbound>,
    mut outbound: mpsc::Receiver<Outbound>,
    transport: mpsc::Sender<TransportEvent>,
    router: Option<broadcast::Sender<Arc<MAVLinkMessageRaw>>>,
) {
    let start = Instant::now();
    let mut pin = PeerPin::new(policy);
    loop {
        let reason = match UdpSocket::bind(&address).await {
            Ok(socket) => {
                let _ = transport.send(TransportEvent::Connected).await;
                let io = Io {
                    socket: &socket,
                    inbound: &inbound,
                    transport: &transport,
                    router: router.as_ref(),
                    start,
                };
                match io.serve(&mut pin, &mut outbound).await {
                    Some(reason) => reason,
                    None => return,
                }
            }
            Err(e) => format!("bind: {e}"),
        };
        let _ = transport
            .send(TransportEvent::Failed(format!("udpin:{address}: {reason}")))
            .await;
        // What was queued meanwhile is stale: never send it late.
        while outbound.try_recv().is_ok() {}
        tokio::time::sleep(REBIND_AFTER).await;
    }
}

/// A frame as received, and decoded when its message is known.
type Decoded = (Arc<MAVLinkMessageRaw>, Option<(MavHeader, MavMessage)>);

struct Io<'a> {
    socket: &'a UdpSocket,
    inbound: &'a mpsc::Sender<Inbound>,
    transport: &'a mpsc::Sender<TransportEvent>,
    router: Option<&'a broadcast::Sender<Arc<MAVLinkMessageRaw>>>,
    start: Instant,
}

impl Io<'_> {
    /// Until the socket fails (`Some(reason)`) or the session ends (`None`).
    async fn serve(
        &self,
        pin: &mut PeerPin,
        outbound: &mut mpsc::Receiver<Outbound>,
    ) -> Option<String> {
        let mut buf = vec![0u8; DATAGRAM];
        let mut sequence = 0u8;
        loop {
            tokio::select! {
                r = self.socket.recv_from(&mut buf) => {
                    match r {
                        Ok((n, from)) => {
                            let datagram = buf.get(..n).unwrap_or_default();
                            if !self.take(pin, from, datagram).await {
                                return None;
                            }
                        }
                        // An ICMP error for an earlier send (some systems report it here).
                        Err(e) if is_transient(&e) => {}
                        Err(e) => return Some(format!("read: {e}")),
                    }
                }
                out = outbound.recv() => {
                    let out = out?;
                    let (Some(to), Some(bytes)) = (pin.destination(), encode(&out, &mut sequence)) else {
                        continue;
                    };
                    if let Err(e) = self.socket.send_to(&bytes, to).await {
                        if !is_transient(&e) {
                            return Some(format!("write to {to}: {e}"));
                        }
                    }
                }
            }
        }
    }

    /// Hands a datagram's frames on if the pin takes it; `false` once the session is gone.
    async fn take(&self, pin: &mut PeerPin, from: SocketAddr, datagram: &[u8]) -> bool {
        let decoded: Vec<Decoded> = frames(datagram)
            .into_iter()
            .map(|raw| {
                let d = decode(&raw);
                (Arc::new(raw), d)
            })
            .collect();
        let messages: Vec<(MavHeader, MavMessage)> =
            decoded.iter().filter_map(|(_, d)| d.clone()).collect();
        let before = pin.destination();
        if !pin.admit(self.start.elapsed(), from, &messages) {
            let n = pin.ignored();
            if n.is_power_of_two() {
                tracing::warn!(target: "mavlink",
                    "{n} datagrams ignored: not from the autopilot's address {} (last from {from})",
                    pin.destination().map_or_else(|| "(none yet)".to_string(), |a| a.to_string()));
            }
            return true;
        }
        if let Some(address) = pin
            .destination()
            .filter(|a| pin.pins() && before != Some(*a))
        {
            let pinned = TransportEvent::Pinned {
                address,
                previous: before,
                changes: pin.changes(),
            };
            if self.transport.send(pinned).await.is_err() {
                return false;
            }
        }
        for (raw, d) in decoded {
            if let Some(r) = self.router {
                // No ground station listening is not an error.
                let _ = r.send(raw.clone());
            }
            let Some((header, msg)) = d else { continue };
            if self
                .inbound
                .send(Inbound { header, msg, raw })
                .await
                .is_err()
            {
                return false;
            }
        }
        true
    }
}

fn is_transient(e: &std::io::Error) -> bool {
    use std::io::ErrorKind::*;
    matches!(
        e.kind(),
        ConnectionRefused | ConnectionReset | WouldBlock | Interrupted
    )
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::mavlink::testutil::{autopilot_header, hb};

    fn bytes(msg: &MavMessage) -> Vec<u8> {
        let mut out = Vec::new();
        mavlink::write_versioned_msg(&mut out, MavlinkVersion::V2, autopilot_header(), msg)
            .unwrap();
        out
    }

    #[test]
    fn every_frame_of_a_datagram_is_found_among_garbage() {
        let one = bytes(&hb(0, false));
        let mut datagram = b"\xfd\x09junk".to_vec();
        datagram.extend(&one);
        datagram.extend(b"more junk");
        datagram.extend(&one);
        assert_eq!(frames(&datagram).len(), 2);
        assert!(frames(b"").is_empty());
        assert!(
            frames(&one[..one.len() - 1]).is_empty(),
            "a cut frame is no frame"
        );
        let noise: Vec<u8> = (0..4096u32).map(|k| (k * 37 % 251) as u8).collect();
        assert!(frames(&noise).is_empty());
    }

    #[test]
    fn our_frames_are_numbered_and_raw_ones_sent_as_they_came() {
        let mut sequence = 254u8;
        let out = Outbound::Message(autopilot_header(), Box::new(hb(0, false)));
        let first = encode(&out, &mut sequence).unwrap();
        let second = encode(&out, &mut sequence).unwrap();
        let seq = |b: &[u8]| frames(b).first().map(|r| r.sequence());
        assert_eq!(
            (seq(&first), seq(&second), sequence),
            (Some(254), Some(255), 0)
        );
        let raw = frames(&first).into_iter().next().unwrap();
        assert_eq!(
            encode(&Outbound::Raw(Arc::new(raw)), &mut sequence),
            Some(first)
        );
    }

    /// Issue 29, item 8, on real sockets: the armed autopilot falls silent for longer than
    /// the old 3 s rule, a stranger's HEARTBEAT claims its system id; Kestrel's frames still go
    /// to the autopilot's address, and nothing of the stranger reaches the session.
    #[tokio::test]
    async fn a_stranger_does_not_take_a_silent_armed_autopilots_address() {
        let (in_tx, mut in_rx) = mpsc::channel(64);
        let (out_tx, out_rx) = mpsc::channel(64);
        let (tr_tx, mut tr_rx) = mpsc::channel(8);
        let probe = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let address = probe.local_addr().unwrap().to_string();
        drop(probe);
        let policy = PeerPolicy::default();
        let server = tokio::spawn(task(address.clone(), policy, in_tx, out_rx, tr_tx, None));
        assert_eq!(tr_rx.recv().await, Some(TransportEvent::Connected));
        let autopilot = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let stranger = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let armed = bytes(&hb(0, true));
        autopilot.send_to(&armed, &address).await.unwrap();
        assert!(in_rx.recv().await.is_some());
        assert!(matches!(
            tr_rx.recv().await,
            Some(TransportEvent::Pinned { .. })
        ));
        tokio::time::sleep(Duration::from_millis(3500)).await;
        for _ in 0..5 {
            stranger
                .send_to(&bytes(&hb(0, false)), &address)
                .await
                .unwrap();
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
        out_tx
            .send(Outbound::Message(
                autopilot_header(),
                Box::new(hb(0, false)),
            ))
            .await
            .unwrap();
        let mut buf = [0u8; 600];
        let to_autopilot =
            tokio::time::timeout(Duration::from_secs(2), autopilot.recv(&mut buf)).await;
        let to_stranger =
            tokio::time::timeout(Duration::from_millis(300), stranger.recv(&mut buf)).await;
        assert!(
            to_autopilot.is_ok() && to_stranger.is_err(),
            "answered the stranger"
        );
        assert!(
            in_rx.try_recv().is_err(),
            "the stranger's frames reached the session"
        );
        assert!(tr_rx.try_recv().is_err(), "no change of address");
        server.abort();
    }

    #[tokio::test]
    async fn a_flooding_stranger_is_never_answered() {
        let (in_tx, mut in_rx) = mpsc::channel(64);
        let (out_tx, out_rx) = mpsc::channel(64);
        let (tr_tx, mut tr_rx) = mpsc::channel(8);
        let probe = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
        let address = probe.local_addr().unwrap().to_string();
        drop(probe);
        let server = tokio::spawn(task(
            address.clone(),
            PeerPolicy::default(),
            in_tx,
            out_rx,
            tr_tx,
            None,
        ));
        assert_eq!(tr_rx.recv().await, Some(TransportEvent::Connected));
        let autopilot = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        let stranger = UdpSocket::bind("127.0.0.1:0").await.unwrap();
        autopilot
            .send_to(&bytes(&hb(0, false)), &address)
            .await
            .unwrap();
        let first = in_rx.recv().await.unwrap();
        assert_eq!(first.header.system_id, 1);
        // The session hears which address was pinned (the API shows it).
        assert_eq!(
            tr_rx.recv().await,
            Some(TransportEvent::Pinned {
                address: autopilot.local_addr().unwrap(),
                previous: None,
                changes: 0,
            })
        );
        for _ in 0..50 {
            stranger.send_to(b"garbage", &address).await.unwrap();
            stranger
                .send_to(&bytes(&hb(0, true)), &address)
                .await
                .unwrap();
        }
        // Kestrel's frame goes to the autopilot, not to the stranger who sent last.
        let mut answered = Vec::new();
        for _ in 0..3 {
            out_tx
                .send(Outbound::Message(
                    autopilot_header(),
                    Box::new(hb(0, false)),
                ))
                .await
                .unwrap();
        }
        let mut buf = [0u8; 600];
        let got = tokio::time::timeout(Duration::from_secs(2), autopilot.recv(&mut buf)).await;
        answered.push(got.is_ok());
        let stray = tokio::time::timeout(Duration::from_millis(200), stranger.recv(&mut buf)).await;
        assert_eq!((answered, stray.is_err()), (vec![true], true));
        assert!(
            in_rx.try_recv().is_err(),
            "none of the stranger's frames reached the session"
        );
        server.abort();
    }
}
