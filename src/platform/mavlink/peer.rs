//! Who may talk to Kestrel on a `udpin` socket, and whom it answers.
//!
//! In: each datagram's source address, the frames decoded from it and the time. Out: whether
//! the datagram is taken (its frames go to the session) and the one address that Kestrel's
//! frames go to ([`PeerPin::destination`]).
//!
//! A `udpin` socket hears anyone. Answering the last sender (what the `mavlink` crate does)
//! lets any host that sends one datagram, even garbage, take the setpoint stream away from the
//! autopilot. So, by default (`pin_peer`), the address that sends the autopilot's HEARTBEAT
//! (one that names an autopilot, and the configured `target_system` if there is one) is pinned:
//! only its datagrams are taken and only it is answered. Another address may take its place only
//! after the pinned one has been silent for [`PEER_SILENCE`] (an autopilot that rebooted onto a
//! new port). `allowed_peers` narrows who may be heard at all (a GCS router's address); with
//! `pin_peer = false` Kestrel answers the last allowed sender, as before.

use mavlink::dialects::ardupilotmega::{MavAutopilot, MavMessage};
use mavlink::MavHeader;
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

/// How long the pinned peer must be silent before another address may be pinned.
pub const PEER_SILENCE: Duration = Duration::from_secs(3);

/// A peer pattern that is neither an IP address nor `IP:port` (the text given).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("`{0}` is neither an IP address nor IP:port")]
pub struct BadPeer(pub String);

/// An address allowed to be the peer: a host (any port) or one exact `IP:port`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum PeerPattern {
    Host(IpAddr),
    Exact(SocketAddr),
}

impl PeerPattern {
    /// `"192.168.1.5"` (any port) or `"192.168.1.5:14580"`.
    pub fn parse(s: &str) -> Result<Self, BadPeer> {
        if let Ok(a) = s.parse::<SocketAddr>() {
            return Ok(Self::Exact(a));
        }
        s.parse::<IpAddr>()
            .map(Self::Host)
            .map_err(|_| BadPeer(s.to_string()))
    }

    fn matches(&self, from: SocketAddr) -> bool {
        match self {
            Self::Host(ip) => from.ip() == *ip,
            Self::Exact(a) => from == *a,
        }
    }
}

/// What the `[mavlink]` section says about `udpin` peers.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct PeerPolicy {
    /// Answer only the address the autopilot's HEARTBEAT came from.
    pub pin: bool,
    /// Addresses that may be heard at all; empty = any.
    pub allowed: Vec<PeerPattern>,
    /// Only this system's HEARTBEAT pins (the `[mavlink] target_system`).
    pub target_system: Option<u8>,
}

impl Default for PeerPolicy {
    fn default() -> Self {
        Self {
            pin: true,
            allowed: Vec::new(),
            target_system: None,
        }
    }
}

/// The pinned peer (see the module docs).
#[derive(Debug)]
pub struct PeerPin {
    policy: PeerPolicy,
    peer: Option<SocketAddr>,
    last_heard: Duration,
    ignored: u64,
}

impl PeerPin {
    pub fn new(policy: PeerPolicy) -> Self {
        Self {
            policy,
            peer: None,
            last_heard: Duration::ZERO,
            ignored: 0,
        }
    }

    /// Whether a datagram from `from` holding `frames` is taken; may pin `from`.
    pub fn admit(
        &mut self,
        now: Duration,
        from: SocketAddr,
        frames: &[(MavHeader, MavMessage)],
    ) -> bool {
        let taken = self.decide(now, from, frames);
        if taken {
            self.last_heard = now;
        } else {
            self.ignored += 1;
        }
        taken
    }

    fn decide(
        &mut self,
        now: Duration,
        from: SocketAddr,
        frames: &[(MavHeader, MavMessage)],
    ) -> bool {
        let allowed =
            self.policy.allowed.is_empty() || self.policy.allowed.iter().any(|p| p.matches(from));
        if !allowed {
            return false;
        }
        if !self.policy.pin {
            self.peer = Some(from);
            return true;
        }
        if self.peer == Some(from) {
            return !frames.is_empty();
        }
        let silent = now.saturating_sub(self.last_heard) >= PEER_SILENCE;
        if self.peer.is_some() && !silent {
            return false;
        }
        if !frames
            .iter()
            .any(|(h, m)| self.is_autopilot_heartbeat(h, m))
        {
            return false;
        }
        match self.peer {
            Some(old) => {
                tracing::warn!(target: "mavlink", "autopilot address {old} silent: answering {from} now")
            }
            None => tracing::info!(target: "mavlink", "autopilot at {from}: only it is answered"),
        }
        self.peer = Some(from);
        true
    }

    fn is_autopilot_heartbeat(&self, header: &MavHeader, msg: &MavMessage) -> bool {
        let MavMessage::HEARTBEAT(hb) = msg else {
            return false;
        };
        hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
            && self
                .policy
                .target_system
                .is_none_or(|s| header.system_id == u32::from(s))
    }

    /// Where Kestrel's frames go; `None` until a peer is heard.
    pub fn destination(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// Datagrams not taken so far.
    pub fn ignored(&self) -> u64 {
        self.ignored
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{ATTITUDE_DATA, HEARTBEAT_DATA};

    fn addr(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    fn hb(system_id: u8, autopilot: MavAutopilot) -> (MavHeader, MavMessage) {
        let header = MavHeader {
            system_id: u32::from(system_id),
            component_id: 1,
            sequence: 0,
        };
        let data = HEARTBEAT_DATA {
            autopilot,
            ..HEARTBEAT_DATA::default()
        };
        (header, MavMessage::HEARTBEAT(data))
    }

    fn attitude() -> (MavHeader, MavMessage) {
        (
            MavHeader::default(),
            MavMessage::ATTITUDE(ATTITUDE_DATA::default()),
        )
    }

    const S: fn(f64) -> Duration = Duration::from_secs_f64;

    #[test]
    fn the_autopilots_address_is_pinned_and_no_other_is_answered() {
        let mut pin = PeerPin::new(PeerPolicy::default());
        let (ap, rogue) = (addr("127.0.0.1:14580"), addr("10.0.0.9:40000"));
        assert_eq!(pin.destination(), None);
        // Garbage (no frame) and non-heartbeats pin nothing.
        assert!(!pin.admit(S(0.0), rogue, &[]));
        assert!(!pin.admit(S(0.1), ap, &[attitude()]));
        assert_eq!(pin.destination(), None);
        assert!(pin.admit(S(0.2), ap, &[hb(1, MavAutopilot::MAV_AUTOPILOT_PX4)]));
        assert_eq!(pin.destination(), Some(ap));
        assert!(pin.admit(S(0.3), ap, &[attitude()]));
        // While the autopilot talks, nothing from elsewhere is taken, not even its HEARTBEAT.
        for k in 0..1000 {
            let t = S(0.3 + f64::from(k) * 0.001);
            assert!(!pin.admit(t, rogue, &[]));
            assert!(!pin.admit(t, rogue, &[hb(1, MavAutopilot::MAV_AUTOPILOT_PX4)]));
        }
        assert_eq!(pin.destination(), Some(ap));
        assert_eq!(pin.ignored(), 2002);
    }

    #[test]
    fn another_address_is_pinned_only_after_the_peer_fell_silent() {
        let mut pin = PeerPin::new(PeerPolicy::default());
        let (ap, moved) = (addr("127.0.0.1:14580"), addr("127.0.0.1:14581"));
        let px4 = [hb(1, MavAutopilot::MAV_AUTOPILOT_PX4)];
        assert!(pin.admit(S(1.0), ap, &px4));
        assert!(!pin.admit(S(3.9), moved, &px4));
        // A GCS heartbeat (no autopilot) never pins, even after the silence.
        assert!(!pin.admit(S(5.0), moved, &[hb(1, MavAutopilot::MAV_AUTOPILOT_INVALID)]));
        assert!(pin.admit(S(5.0), moved, &px4));
        assert_eq!(pin.destination(), Some(moved));
        // The old address is now the stranger.
        assert!(!pin.admit(S(5.1), ap, &px4));
    }

    #[test]
    fn the_configured_system_and_allowed_addresses_narrow_who_may_pin() {
        let router = addr("192.168.1.5:14580");
        let mut pin = PeerPin::new(PeerPolicy {
            pin: true,
            allowed: vec![PeerPattern::parse("192.168.1.5").unwrap()],
            target_system: Some(7),
        });
        assert!(!pin.admit(
            S(0.0),
            addr("192.168.1.6:14580"),
            &[hb(7, MavAutopilot::MAV_AUTOPILOT_PX4)]
        ));
        assert!(!pin.admit(S(0.0), router, &[hb(1, MavAutopilot::MAV_AUTOPILOT_PX4)]));
        assert!(pin.admit(S(0.0), router, &[hb(7, MavAutopilot::MAV_AUTOPILOT_PX4)]));
        assert_eq!(pin.destination(), Some(router));
    }

    #[test]
    fn without_pinning_the_last_allowed_sender_is_answered() {
        let mut pin = PeerPin::new(PeerPolicy {
            pin: false,
            allowed: vec![PeerPattern::parse("127.0.0.1").unwrap()],
            target_system: None,
        });
        assert!(pin.admit(S(0.0), addr("127.0.0.1:1000"), &[]));
        assert!(!pin.admit(S(0.1), addr("10.0.0.1:1000"), &[]));
        assert_eq!(pin.destination(), Some(addr("127.0.0.1:1000")));
    }

    #[test]
    fn patterns_parse_hosts_and_exact_addresses() {
        assert_eq!(
            PeerPattern::parse("10.0.0.2:5760"),
            Ok(PeerPattern::Exact(addr("10.0.0.2:5760")))
        );
        assert!(matches!(
            PeerPattern::parse("::1"),
            Ok(PeerPattern::Host(_))
        ));
        assert!(PeerPattern::parse("gcs.local").is_err());
    }
}
