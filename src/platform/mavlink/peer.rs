//! Who may talk to Kestrel on a `udpin` socket, and whom it answers.
//!
//! In: each datagram's source address, the frames decoded from it and the time. Out: whether
//! the datagram is taken (its frames go to the session), the one address that Kestrel's
//! frames go to ([`PeerPin::destination`]) and how many times another address took its place
//! ([`PeerPin::changes`]).
//!
//! A `udpin` socket hears anyone. Answering the last sender (what the `mavlink` crate does)
//! lets any host that sends one datagram, even garbage, take the setpoint stream away from the
//! autopilot. So, by default (`pin_peer`), the address that sends the autopilot's HEARTBEAT
//! (one that names an autopilot, and the configured `target_system` if there is one) is pinned:
//! only its datagrams are taken and only it is answered. Another address may take its place
//! (an autopilot that rebooted onto a new port) only when all of these hold:
//! - the pinned address has been silent for [`PeerPolicy::repin_after`] (`[mavlink]
//!   repin_after_s`, 30 s by default: far longer than a link cut a flight rides out);
//! - the new address's HEARTBEAT comes from a system the pinned address spoke for (a stranger
//!   cannot bring a new autopilot in);
//! - no autopilot behind the pinned address was last heard armed or in the air: a vehicle that
//!   fell silent while flying is never handed to another address, its own failsafe flies it
//!   until its address speaks again (or Kestrel is restarted).
//!
//! Each change is logged and counted, and the session shows it in the vehicle's status (the
//! API's `autopilot_address`, `autopilot_address_changes` and `last_error`). `allowed_peers`
//! narrows who may be heard at all (a GCS router's address); with `pin_peer = false` Kestrel
//! answers the last allowed sender, as before.

use mavlink::dialects::ardupilotmega::{MavAutopilot, MavLandedState, MavMessage, MavModeFlag};
use mavlink::MavHeader;
use std::collections::BTreeMap;
use std::net::{IpAddr, SocketAddr};
use std::time::Duration;

/// How long the pinned peer must be silent before another address may be pinned, by default.
pub const REPIN_AFTER: Duration = Duration::from_secs(30);

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
    /// How long the pinned address must be silent before another may take its place.
    pub repin_after: Duration,
}

impl Default for PeerPolicy {
    fn default() -> Self {
        Self {
            pin: true,
            allowed: Vec::new(),
            target_system: None,
            repin_after: REPIN_AFTER,
        }
    }
}

/// What an autopilot behind the pinned address last said about flying.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
struct Flying {
    armed: bool,
    in_air: bool,
}

/// Why another address may not take the pinned one's place (logged once per silence).
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum RepinRefused {
    #[error("system {0} is not an autopilot the pinned address spoke for")]
    OtherSystem(u8),
    #[error("autopilot {0} was last heard armed or in the air")]
    Flying(u8),
}

/// The pinned peer (see the module docs).
#[derive(Debug)]
pub struct PeerPin {
    policy: PeerPolicy,
    peer: Option<SocketAddr>,
    last_heard: Duration,
    ignored: u64,
    /// The autopilots heard from the pinned address, by system id (at most 256).
    systems: BTreeMap<u8, Flying>,
    changes: u32,
    /// A refused change was logged during this silence of the pinned address.
    refusal_logged: bool,
}

impl PeerPin {
    pub fn new(policy: PeerPolicy) -> Self {
        Self {
            policy,
            peer: None,
            last_heard: Duration::ZERO,
            ignored: 0,
            systems: BTreeMap::new(),
            changes: 0,
            refusal_logged: false,
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
            self.observe(frames);
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
            if frames.is_empty() {
                return false;
            }
            self.refusal_logged = false;
            return true;
        }
        let silence = now.saturating_sub(self.last_heard);
        if self.peer.is_some() && silence < self.policy.repin_after {
            return false;
        }
        let Some(system) = frames
            .iter()
            .find_map(|(h, m)| self.autopilot_heartbeat(h, m))
        else {
            return false;
        };
        match self.peer {
            Some(old) => {
                if let Err(why) = self.may_take_over(system) {
                    if !std::mem::replace(&mut self.refusal_logged, true) {
                        tracing::warn!(target: "mavlink",
                            "{from} claims to be autopilot {system} while {old} is silent: ignored ({why})");
                    }
                    return false;
                }
                self.changes += 1;
                tracing::warn!(target: "mavlink",
                    "autopilot address {old} silent for {:.0} s: answering {from} (system {system}) now",
                    silence.as_secs_f64());
            }
            None => tracing::info!(target: "mavlink", "autopilot at {from}: only it is answered"),
        }
        self.peer = Some(from);
        true
    }

    /// Whether a HEARTBEAT of `system` from another address may take the pinned one's place.
    fn may_take_over(&self, system: u8) -> Result<(), RepinRefused> {
        if !self.systems.contains_key(&system) {
            return Err(RepinRefused::OtherSystem(system));
        }
        match self.systems.iter().find(|(_, f)| f.armed || f.in_air) {
            Some((s, _)) => Err(RepinRefused::Flying(*s)),
            None => Ok(()),
        }
    }

    /// Notes what the pinned address's autopilots say about flying.
    fn observe(&mut self, frames: &[(MavHeader, MavMessage)]) {
        if !self.policy.pin {
            return;
        }
        for (header, msg) in frames {
            let Ok(system) = u8::try_from(header.system_id) else {
                continue;
            };
            match msg {
                MavMessage::HEARTBEAT(hb) if self.autopilot_heartbeat(header, msg).is_some() => {
                    self.systems.entry(system).or_default().armed = hb
                        .base_mode
                        .contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED);
                }
                MavMessage::EXTENDED_SYS_STATE(e) => {
                    if let Some(f) = self.systems.get_mut(&system) {
                        f.in_air = !matches!(
                            e.landed_state,
                            MavLandedState::MAV_LANDED_STATE_ON_GROUND
                                | MavLandedState::MAV_LANDED_STATE_UNDEFINED
                        );
                    }
                }
                _ => {}
            }
        }
    }

    /// The system id of an autopilot's HEARTBEAT (the configured system's, if one is).
    fn autopilot_heartbeat(&self, header: &MavHeader, msg: &MavMessage) -> Option<u8> {
        let MavMessage::HEARTBEAT(hb) = msg else {
            return None;
        };
        let system = u8::try_from(header.system_id).ok()?;
        (hb.autopilot != MavAutopilot::MAV_AUTOPILOT_INVALID
            && self.policy.target_system.is_none_or(|s| system == s))
        .then_some(system)
    }

    /// Whether the address is pinned (`pin_peer`), rather than the last sender answered.
    pub fn pins(&self) -> bool {
        self.policy.pin
    }

    /// Where Kestrel's frames go; `None` until a peer is heard.
    pub fn destination(&self) -> Option<SocketAddr> {
        self.peer
    }

    /// How many times another address took the pinned one's place.
    pub fn changes(&self) -> u32 {
        self.changes
    }

    /// Datagrams not taken so far.
    pub fn ignored(&self) -> u64 {
        self.ignored
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{
        ATTITUDE_DATA, EXTENDED_SYS_STATE_DATA, HEARTBEAT_DATA,
    };

    fn addr(s: &str) -> SocketAddr {
        s.parse().unwrap()
    }

    fn header(system_id: u8) -> MavHeader {
        MavHeader {
            system_id: u32::from(system_id),
            component_id: 1,
            sequence: 0,
        }
    }

    fn hb(system_id: u8, autopilot: MavAutopilot) -> (MavHeader, MavMessage) {
        let data = HEARTBEAT_DATA {
            autopilot,
            ..HEARTBEAT_DATA::default()
        };
        (header(system_id), MavMessage::HEARTBEAT(data))
    }

    fn px4(system_id: u8, armed: bool) -> [(MavHeader, MavMessage); 1] {
        let (h, mut msg) = hb(system_id, MavAutopilot::MAV_AUTOPILOT_PX4);
        if let MavMessage::HEARTBEAT(data) = &mut msg {
            data.base_mode
                .set(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED, armed);
        }
        [(h, msg)]
    }

    fn landed_state(system_id: u8, state: MavLandedState) -> (MavHeader, MavMessage) {
        let data = EXTENDED_SYS_STATE_DATA {
            landed_state: state,
            ..EXTENDED_SYS_STATE_DATA::default()
        };
        (header(system_id), MavMessage::EXTENDED_SYS_STATE(data))
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

    /// Issue 29, item 8: after a 4 s cut of an armed PX4's link, a HEARTBEAT from another
    /// address took the pin and Kestrel answered it, not the autopilot.
    #[test]
    fn a_stranger_never_takes_the_place_of_an_autopilot_that_fell_silent_armed() {
        let mut pin = PeerPin::new(PeerPolicy::default());
        let (ap, rogue) = (addr("127.0.0.1:14580"), addr("127.0.0.1:40000"));
        assert!(pin.admit(S(1.0), ap, &px4(1, true)));
        assert!(!pin.admit(S(5.0), rogue, &px4(1, false)));
        assert!(
            !pin.admit(S(600.0), rogue, &px4(1, false)),
            "never while armed"
        );
        assert_eq!((pin.destination(), pin.changes()), (Some(ap), 0));
        // The autopilot's own address is heard again whenever it speaks.
        assert!(pin.admit(S(601.0), ap, &px4(1, true)));
        // Disarmed but in the air (EXTENDED_SYS_STATE) counts as flying too.
        let in_air = landed_state(1, MavLandedState::MAV_LANDED_STATE_IN_AIR);
        assert!(pin.admit(S(602.0), ap, &[px4(1, false)[0].clone(), in_air]));
        assert!(!pin.admit(S(700.0), rogue, &px4(1, false)));
        assert_eq!(pin.destination(), Some(ap));
    }

    #[test]
    fn another_address_takes_over_only_a_silent_disarmed_autopilot_of_the_same_system() {
        let mut pin = PeerPin::new(PeerPolicy::default());
        let (ap, moved) = (addr("127.0.0.1:14580"), addr("127.0.0.1:14581"));
        assert!(pin.admit(S(1.0), ap, &px4(1, false)));
        let on_ground = landed_state(1, MavLandedState::MAV_LANDED_STATE_ON_GROUND);
        assert!(pin.admit(S(2.0), ap, &[on_ground]));
        // Silent, but not for `repin_after` yet.
        assert!(!pin.admit(S(31.9), moved, &px4(1, false)));
        // Another system, or a GCS heartbeat (no autopilot), never takes over.
        assert!(!pin.admit(S(40.0), moved, &px4(2, false)));
        assert!(!pin.admit(
            S(40.0),
            moved,
            &[hb(1, MavAutopilot::MAV_AUTOPILOT_INVALID)]
        ));
        assert_eq!(pin.changes(), 0);
        assert!(pin.admit(S(40.0), moved, &px4(1, false)));
        assert_eq!((pin.destination(), pin.changes()), (Some(moved), 1));
        // The old address is now the stranger.
        assert!(!pin.admit(S(40.1), ap, &px4(1, false)));
    }

    #[test]
    fn repin_after_is_the_policys() {
        let mut pin = PeerPin::new(PeerPolicy {
            repin_after: Duration::from_secs(5),
            ..PeerPolicy::default()
        });
        let (ap, moved) = (addr("127.0.0.1:14580"), addr("127.0.0.1:14581"));
        assert!(pin.admit(S(0.0), ap, &px4(1, false)));
        assert!(!pin.admit(S(4.9), moved, &px4(1, false)));
        assert!(pin.admit(S(5.0), moved, &px4(1, false)));
    }

    #[test]
    fn the_configured_system_and_allowed_addresses_narrow_who_may_pin() {
        let router = addr("192.168.1.5:14580");
        let mut pin = PeerPin::new(PeerPolicy {
            pin: true,
            allowed: vec![PeerPattern::parse("192.168.1.5").unwrap()],
            target_system: Some(7),
            ..PeerPolicy::default()
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
            ..PeerPolicy::default()
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
