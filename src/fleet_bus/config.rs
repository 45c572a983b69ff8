//! The `[fleet]` section: whether this Kestrel joins a fleet bus, under which fleet name and node
//! name, where it listens and whom it connects to, how often it publishes, and the credentials
//! its peers must present.
//!
//! In: TOML (unknown keys refused). Out: [`FleetSection::validate`] → `Err((field, message))`
//! naming the field for a name that cannot be a key (only letters, digits, `-`, `_`), an
//! endpoint that is not `tcp/HOST:PORT`, a rate out of bounds, a bus with nothing to find peers
//! by, or a roster that does not name this node and its drones.
//!
//! The roster (`[fleet.roster.NODE]`, the same on every node) is the fleet: each member's
//! public keys (what it signs with, `fleet_bus::identity`) and the drones it flies. Nothing
//! else is heard, and the majority of the lost-peer rules is counted over it.

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::PathBuf;

/// Longest fleet, node or drone name on the bus.
pub const MAX_NAME_LEN: usize = 64;
/// Most endpoints in `listen` or `connect`.
pub const MAX_ENDPOINTS: usize = 32;
/// Most members of a roster.
pub const MAX_MEMBERS: usize = 64;
/// Most keys a member lists (the new one beside the old while keys are rotated).
pub const MAX_KEYS_PER_MEMBER: usize = 4;

/// One node of the fleet, as every node's roster lists it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Member {
    /// Its public keys (base64, as `kestrel fleet-key` prints them): what it sends must be
    /// signed by one of them.
    pub keys: Vec<String>,
    /// The drones it flies: it may speak for these only (at most 32).
    pub drones: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct FleetSection {
    /// Join the fleet bus (off by default: one Kestrel alone needs no network).
    pub enabled: bool,
    /// Fleets sharing a network are kept apart by name.
    pub name: String,
    /// This Kestrel's name on the bus; absent = its first drone's id.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub node: Option<String>,
    /// Where this Kestrel accepts peers (`tcp/0.0.0.0:7447`); open this port in the firewall.
    pub listen: Vec<String>,
    /// Peers (or a Zenoh router) to connect to (`tcp/192.168.1.12:7447`); retried until they
    /// answer.
    pub connect: Vec<String>,
    /// Find peers on the local network by UDP multicast (224.0.0.224:7446) as well.
    pub scouting: bool,
    /// Drone states sent per second.
    pub state_rate_hz: f64,
    /// Map changes sent per second (only the changed regions, compressed).
    pub map_rate_hz: f64,
    /// Every this long the whole known part of each drone's map is sent again, so a peer that
    /// joins late or lost messages catches up (s).
    pub map_keyframe_period_s: f64,
    /// A peer's drone not heard from for this long is silent (s): while one that was flying is
    /// silent, this Kestrel's flying drones hold where they are (the peer, if alive and cut off,
    /// does the same).
    pub peer_timeout_s: f64,
    /// Silent this long while this Kestrel hears the majority of the fleet's nodes, a drone is
    /// taken to be where it was last heard (its autopilot's failsafe landed or held it, or its
    /// Kestrel, cut off in a minority, holds it) and the majority flies on around it (s).
    pub lost_after_s: f64,
    /// Kept from such a drone on top of `[safety] min_separation_m` (m): how far its failsafe
    /// may have carried it.
    pub silent_keepout_m: f64,
    /// This node's signing key: one line, made by `kestrel fleet-key FILE` (keep it readable by
    /// Kestrel only). Required on a bus.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub key_file: Option<PathBuf>,
    /// The fleet's members by node name, this node included; the same table on every node.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub roster: BTreeMap<String, Member>,
    /// `user:password` lines: the first is this node's, all are accepted from peers. Optional:
    /// it keeps strangers from opening a Zenoh session at all; who may say what is the
    /// roster's business.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub credentials_file: Option<PathBuf>,
    /// With peers in `connect`, refuse missions and explorations (`409 fleet_not_joined`) until
    /// every one of them has been joined once, so a node the others refused (wrong credentials)
    /// or cannot reach never flies unseen by their separation and allocation. Once joined, peers
    /// that fall silent follow the lost-peer rules instead (`peer_timeout_s`, `lost_after_s`).
    pub require_join: bool,
}

impl Default for FleetSection {
    fn default() -> Self {
        Self {
            enabled: false,
            name: "kestrel".into(),
            node: None,
            listen: Vec::new(),
            connect: Vec::new(),
            scouting: false,
            state_rate_hz: 10.0,
            map_rate_hz: 2.0,
            map_keyframe_period_s: 10.0,
            peer_timeout_s: 1.5,
            lost_after_s: 10.0,
            silent_keepout_m: 0.5,
            key_file: None,
            roster: BTreeMap::new(),
            credentials_file: None,
            require_join: true,
        }
    }
}

/// A fleet, node or drone name usable as one chunk of a key: 1 to 64 of `[A-Za-z0-9_-]`.
pub fn valid_name(name: &str) -> bool {
    !name.is_empty()
        && name.len() <= MAX_NAME_LEN
        && name
            .bytes()
            .all(|b| b.is_ascii_alphanumeric() || b == b'-' || b == b'_')
}

fn name_error(what: &str, name: &str) -> String {
    format!("{what} `{name}` must be 1 to {MAX_NAME_LEN} letters, digits, `-` or `_`")
}

/// The base64 of 32 bytes: a public key of the roster.
pub fn valid_public_key(text: &str) -> bool {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD
        .decode(text.trim())
        .is_ok_and(|b| b.len() == 32)
}

/// `tcp/HOST:PORT` with a port number. Zenoh's UDP links are not built: they bring a QUIC and
/// TLS stack (about 2 MB of the binary) for a link that carries only best-effort traffic.
fn valid_endpoint(e: &str) -> bool {
    let Some((proto, addr)) = e.split_once('/') else {
        return false;
    };
    let Some((host, port)) = addr.rsplit_once(':') else {
        return false;
    };
    proto == "tcp" && !host.is_empty() && !host.contains('/') && port.parse::<u16>().is_ok()
}

impl FleetSection {
    /// Checks the section; `drones` are this Kestrel's drone ids (each must be a valid name).
    pub fn validate(&self, drones: &[String]) -> Result<(), (String, String)> {
        if !self.enabled {
            return Ok(());
        }
        if !valid_name(&self.name) {
            return Err((
                "fleet.name".into(),
                name_error("the fleet name", &self.name),
            ));
        }
        if let Some(node) = &self.node {
            if !valid_name(node) {
                return Err(("fleet.node".into(), name_error("the node name", node)));
            }
        }
        for d in drones {
            if !valid_name(d) {
                return Err((
                    "drone.id".into(),
                    name_error("on a fleet bus, the drone id", d),
                ));
            }
        }
        for (field, list) in [("listen", &self.listen), ("connect", &self.connect)] {
            if list.len() > MAX_ENDPOINTS {
                return Err((
                    format!("fleet.{field}"),
                    format!("{} endpoints, at most {MAX_ENDPOINTS}", list.len()),
                ));
            }
            for (i, e) in list.iter().enumerate() {
                if !valid_endpoint(e) {
                    return Err((
                        format!("fleet.{field}[{i}]"),
                        format!("`{e}` is not `tcp/HOST:PORT` (the bus runs over TCP)"),
                    ));
                }
            }
        }
        self.validate_roster(drones)?;
        if self.listen.is_empty() && self.connect.is_empty() && !self.scouting {
            return Err((
                "fleet".into(),
                "a bus needs `listen`, `connect` or `scouting = true` to find its peers".into(),
            ));
        }
        for (field, value, lo, hi) in [
            ("state_rate_hz", self.state_rate_hz, 0.5, 100.0),
            ("map_rate_hz", self.map_rate_hz, 0.1, 20.0),
            (
                "map_keyframe_period_s",
                self.map_keyframe_period_s,
                1.0,
                600.0,
            ),
            ("peer_timeout_s", self.peer_timeout_s, 0.2, 60.0),
            ("lost_after_s", self.lost_after_s, 2.0, 600.0),
            ("silent_keepout_m", self.silent_keepout_m, 0.0, 20.0),
        ] {
            if !(lo..=hi).contains(&value) {
                return Err((
                    format!("fleet.{field}"),
                    format!("{value} is outside {lo} to {hi}"),
                ));
            }
        }
        if self.lost_after_s <= self.peer_timeout_s {
            return Err((
                "fleet.lost_after_s".into(),
                format!(
                    "{} s is not longer than peer_timeout_s ({} s)",
                    self.lost_after_s, self.peer_timeout_s
                ),
            ));
        }
        if self.peer_timeout_s * self.state_rate_hz < 2.0 {
            return Err((
                "fleet.peer_timeout_s".into(),
                format!(
                    "{} s is less than two states at {} Hz: peers would blink silent",
                    self.peer_timeout_s, self.state_rate_hz
                ),
            ));
        }
        Ok(())
    }

    /// The key file and the roster: every member named and keyed, each drone flown by one
    /// member, this node a member listing the drones it flies.
    fn validate_roster(&self, drones: &[String]) -> Result<(), (String, String)> {
        if self.key_file.is_none() {
            return Err((
                "fleet.key_file".into(),
                "every node of a fleet bus signs what it sends with a key of its own, and the \
                 fleet's [fleet.roster] lists each node's public key and drones: make this \
                 node's key with `kestrel fleet-key /etc/kestrel/fleet.key`, set key_file to it \
                 and add the roster (README, \"A fleet of Kestrels\")"
                    .into(),
            ));
        }
        let me = self.node_name(drones);
        if self.roster.len() > MAX_MEMBERS {
            return Err((
                "fleet.roster".into(),
                format!("{} members, at most {MAX_MEMBERS}", self.roster.len()),
            ));
        }
        let mut flown_by: BTreeMap<&str, &str> = BTreeMap::new();
        for (node, member) in &self.roster {
            let at = format!("fleet.roster.{node}");
            if !valid_name(node) {
                return Err((at, name_error("the node name", node)));
            }
            if member.keys.is_empty() || member.keys.len() > MAX_KEYS_PER_MEMBER {
                return Err((
                    format!("{at}.keys"),
                    format!("1 to {MAX_KEYS_PER_MEMBER} public keys"),
                ));
            }
            if let Some(bad) = member.keys.iter().find(|k| !valid_public_key(k)) {
                return Err((
                    format!("{at}.keys"),
                    format!("`{bad}` is not a public key (the base64 of 32 bytes, as `kestrel fleet-key` prints it)"),
                ));
            }
            if member.drones.len() > super::wire::MAX_DRONES_PER_NODE {
                return Err((
                    format!("{at}.drones"),
                    format!("at most {} drones", super::wire::MAX_DRONES_PER_NODE),
                ));
            }
            for d in &member.drones {
                if !valid_name(d) {
                    return Err((format!("{at}.drones"), name_error("the drone id", d)));
                }
                if let Some(other) = flown_by.insert(d, node) {
                    return Err((
                        format!("{at}.drones"),
                        format!("`{d}` is node `{other}`'s already: a drone has one node"),
                    ));
                }
            }
        }
        if flown_by.len() > super::remote::MAX_REMOTE_DRONES {
            return Err((
                "fleet.roster".into(),
                format!(
                    "{} drones, at most {}",
                    flown_by.len(),
                    super::remote::MAX_REMOTE_DRONES
                ),
            ));
        }
        let Some(own) = self.roster.get(&me) else {
            return Err((
                "fleet.roster".into(),
                format!("this node, `{me}`, is not a member: add [fleet.roster.{me}]"),
            ));
        };
        if let Some(d) = drones.iter().find(|d| !own.drones.contains(d)) {
            return Err((
                format!("fleet.roster.{me}.drones"),
                format!("this node flies `{d}`: list it"),
            ));
        }
        Ok(())
    }

    /// The other members' names.
    pub fn peers(&self, me: &str) -> Vec<String> {
        self.roster.keys().filter(|n| *n != me).cloned().collect()
    }

    /// This node's name on the bus.
    pub fn node_name(&self, drones: &[String]) -> String {
        self.node
            .clone()
            .or_else(|| drones.first().cloned())
            .unwrap_or_else(|| "kestrel".into())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const KEY: &str = "AAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAAA=";

    fn member(drones: &[&str]) -> Member {
        Member {
            keys: vec![KEY.into()],
            drones: drones.iter().map(|d| d.to_string()).collect(),
        }
    }

    fn on() -> FleetSection {
        FleetSection {
            enabled: true,
            listen: vec!["tcp/0.0.0.0:7447".into()],
            key_file: Some("/etc/kestrel/fleet.key".into()),
            roster: [
                ("kestrel".to_string(), member(&[])),
                ("drone_0".to_string(), member(&["drone_0"])),
            ]
            .into(),
            ..FleetSection::default()
        }
    }

    #[test]
    fn a_bus_needs_a_key_and_a_roster_naming_this_node_and_its_drones() {
        let err = |s: FleetSection, drones: &[&str]| {
            let drones: Vec<String> = drones.iter().map(|d| d.to_string()).collect();
            s.validate(&drones).unwrap_err()
        };
        let old = FleetSection {
            key_file: None,
            roster: BTreeMap::new(),
            ..on()
        };
        let (field, message) = err(old, &["drone_0"]);
        assert_eq!(field, "fleet.key_file");
        assert!(message.contains("kestrel fleet-key"), "{message}");
        assert_eq!(err(on(), &["drone_9"]).0, "fleet.roster");
        let mut unlisted = on();
        unlisted.node = Some("drone_0".into());
        assert_eq!(
            err(unlisted, &["drone_0", "drone_5"]).0,
            "fleet.roster.drone_0.drones"
        );
        let mut twice = on();
        twice.roster.insert("other".into(), member(&["drone_0"]));
        assert!(err(twice, &["drone_0"]).1.contains("a drone has one node"));
        let mut bad_key = on();
        bad_key.roster.insert(
            "other".into(),
            Member {
                keys: vec!["bm90IGEga2V5".into()],
                drones: vec![],
            },
        );
        assert_eq!(err(bad_key, &["drone_0"]).0, "fleet.roster.other.keys");
        assert_eq!(on().peers("drone_0"), ["kestrel"]);
    }

    #[test]
    fn off_is_always_valid_and_on_needs_a_way_to_peers() {
        assert!(FleetSection::default().validate(&["a b".into()]).is_ok());
        assert!(on().validate(&["drone_0".into()]).is_ok());
        let lonely = FleetSection {
            listen: vec![],
            ..on()
        };
        assert_eq!(lonely.validate(&[]).unwrap_err().0, "fleet");
    }

    #[test]
    fn names_endpoints_and_rates_are_checked_with_the_field_named() {
        let bad_name = FleetSection {
            name: "a/b".into(),
            ..on()
        };
        assert_eq!(bad_name.validate(&[]).unwrap_err().0, "fleet.name");
        assert_eq!(
            on().validate(&["drone 1".into()]).unwrap_err().0,
            "drone.id"
        );
        let bad_endpoint = FleetSection {
            connect: vec!["tcp/10.0.0.2:7447".into(), "10.0.0.3".into()],
            ..on()
        };
        assert_eq!(
            bad_endpoint.validate(&[]).unwrap_err().0,
            "fleet.connect[1]"
        );
        // UDP links are not built in: refused before the bus starts, not when zenoh fails.
        let udp = FleetSection {
            listen: vec!["udp/0.0.0.0:7447".into()],
            ..on()
        };
        assert_eq!(
            udp.validate(&[]).unwrap_err(),
            (
                "fleet.listen[0]".to_string(),
                "`udp/0.0.0.0:7447` is not `tcp/HOST:PORT` (the bus runs over TCP)".to_string()
            )
        );
        let fast = FleetSection {
            state_rate_hz: 1000.0,
            ..on()
        };
        assert_eq!(fast.validate(&[]).unwrap_err().0, "fleet.state_rate_hz");
        let blinking = FleetSection {
            state_rate_hz: 1.0,
            peer_timeout_s: 1.0,
            ..on()
        };
        assert_eq!(
            blinking.validate(&[]).unwrap_err().0,
            "fleet.peer_timeout_s"
        );
    }

    #[test]
    fn the_node_is_named_after_its_first_drone_unless_named() {
        assert_eq!(on().node_name(&["drone_2".into()]), "drone_2");
        let named = FleetSection {
            node: Some("pi-7".into()),
            ..on()
        };
        assert_eq!(named.node_name(&["drone_2".into()]), "pi-7");
    }
}
