//! What a peer's message must pass before the control loop sees it, on the bus's threads.
//!
//! In: a sample's key expression (`kestrel/<fleet>/<node>/<kind>`) and bytes, the roster (each
//! member's public keys and drones), this node's name. Out: states queued for the control loop,
//! map regions coalesced in the [`MapInbox`], and every refusal counted in [`BusStats`] and said
//! at most once every [`SAY_EVERY`] with how many more there were (an outsider decides how
//! often it is refused, not how much is logged).
//!
//! In this order, cheapest first: the node must be a member; the message no larger than its
//! kind allows; signed by one of that member's keys for this very key expression
//! (`identity::open`), so that a node can only ever speak for itself; its counter above the
//! last one that member used for that kind (no replay); decoded within bounds (`wire`); naming
//! its own node and only drones the roster gives that node.

use std::collections::BTreeMap;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use tokio::sync::mpsc;

use super::identity::{self, OpenError, PublicKey, ENVELOPE_BYTES};
use super::inbox::MapInbox;
use super::stats::BusStats;
use super::wire::{MapMsg, StateMsg, WireError, MAX_MAP_BYTES, MAX_STATE_BYTES};

/// A refusal is said at most this often (the count says the rest).
pub const SAY_EVERY: Duration = Duration::from_secs(5);

/// One member of the roster, as the intake checks it.
#[derive(Debug, Clone)]
pub struct Member {
    pub keys: Vec<PublicKey>,
    pub drones: Vec<String>,
}

/// Why a peer's message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum Refusal {
    #[error("node `{0}` is not in the roster")]
    UnknownNode(String),
    #[error("{0} bytes, at most {1}")]
    TooLarge(usize, usize),
    #[error(transparent)]
    Open(#[from] OpenError),
    #[error("counter {counter} is not above the last one heard ({last}): a replay, or its clock went back")]
    Replayed { counter: u64, last: u64 },
    #[error(transparent)]
    Wire(#[from] WireError),
    #[error("sent on `{key}`'s key as node `{inside}`")]
    OtherNode { key: String, inside: String },
    #[error("speaks for `{0}`, which the roster does not give it")]
    NotItsDrone(String),
}

/// The lines of refusals: one, then at most one every [`SAY_EVERY`].
#[derive(Debug, Default)]
struct Said {
    last: Option<Instant>,
    held: u64,
}

impl Said {
    /// Whether to say a line now, and how many were held back since the last.
    fn now(&mut self, now: Instant) -> Option<u64> {
        if self.last.is_some_and(|t| now.duration_since(t) < SAY_EVERY) {
            self.held += 1;
            return None;
        }
        self.last = Some(now);
        Some(std::mem::take(&mut self.held))
    }
}

pub struct Intake {
    fleet: String,
    me: String,
    members: BTreeMap<String, Member>,
    max_cells: usize,
    /// The last counter each member used, per kind.
    counters: Mutex<BTreeMap<(String, &'static str), u64>>,
    stats: Arc<BusStats>,
    states: mpsc::Sender<StateMsg>,
    maps: Arc<MapInbox>,
    said: Mutex<Said>,
}

/// The peer node and kind of a key, if the key is `kestrel/<fleet>/<node>/<kind>`.
pub fn key_parts<'a>(key: &'a str, fleet: &str) -> Option<(&'a str, &'a str)> {
    let rest = key
        .strip_prefix("kestrel/")?
        .strip_prefix(fleet)?
        .strip_prefix('/')?;
    rest.split_once('/')
}

/// A checked message.
enum Checked {
    State(StateMsg),
    Map(MapMsg),
}

impl Intake {
    pub fn new(
        fleet: &str,
        me: &str,
        members: BTreeMap<String, Member>,
        max_cells: usize,
        stats: Arc<BusStats>,
        states: mpsc::Sender<StateMsg>,
        maps: Arc<MapInbox>,
    ) -> Self {
        Self {
            fleet: fleet.to_string(),
            me: me.to_string(),
            members,
            max_cells,
            counters: Mutex::default(),
            stats,
            states,
            maps,
            said: Mutex::default(),
        }
    }

    /// One sample from the bus: checked, then queued, or refused (counted, and said within the
    /// rate). Samples of this node, or not of this fleet's keys, are ignored.
    pub fn take(&self, key: &str, bytes: &[u8]) -> Result<(), Refusal> {
        let Some((node, kind)) = key_parts(key, &self.fleet) else {
            return Ok(());
        };
        if node == self.me {
            return Ok(());
        }
        self.stats.received.fetch_add(1, Ordering::Relaxed);
        self.stats
            .received_bytes
            .fetch_add(bytes.len() as u64, Ordering::Relaxed);
        let checked = match self.check(node, kind, bytes) {
            Ok(Some(c)) => c,
            Ok(None) => return Ok(()),
            Err(refusal) => {
                self.stats.refused.fetch_add(1, Ordering::Relaxed);
                self.say(node, kind, &refusal);
                return Err(refusal);
            }
        };
        let queued = match checked {
            Checked::State(m) => self.states.try_send(m).is_ok(),
            Checked::Map(m) => self.maps.offer(m).is_ok(),
        };
        if !queued {
            self.stats.dropped.fetch_add(1, Ordering::Relaxed);
        }
        Ok(())
    }

    fn say(&self, node: &str, kind: &str, refusal: &Refusal) {
        let mut said = self.said.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(held) = said.now(Instant::now()) {
            let more = match held {
                0 => String::new(),
                n => format!(" ({n} more refused since the last line)"),
            };
            let node: String = node.chars().take(64).collect();
            let kind: String = kind.chars().take(16).collect();
            tracing::warn!("fleet bus: refused a `{kind}` message from `{node}`: {refusal}{more}");
        }
    }

    fn check(&self, node: &str, kind: &str, bytes: &[u8]) -> Result<Option<Checked>, Refusal> {
        let (kind, max) = match kind {
            "state" => ("state", MAX_STATE_BYTES),
            "map" => ("map", MAX_MAP_BYTES),
            _ => return Ok(None),
        };
        let member = self
            .members
            .get(node)
            .ok_or_else(|| Refusal::UnknownNode(node.chars().take(64).collect()))?;
        if bytes.len() > max + ENVELOPE_BYTES {
            return Err(Refusal::TooLarge(bytes.len(), max + ENVELOPE_BYTES));
        }
        let (counter, message) = identity::open(&member.keys, &self.fleet, node, kind, bytes)?;
        {
            let mut counters = self.counters.lock().unwrap_or_else(|e| e.into_inner());
            let last = counters.entry((node.to_string(), kind)).or_insert(0);
            if counter <= *last {
                return Err(Refusal::Replayed {
                    counter,
                    last: *last,
                });
            }
            *last = counter;
        }
        let other_node = |inside: &str| Refusal::OtherNode {
            key: node.to_string(),
            inside: inside.to_string(),
        };
        let not_its = |drone: &str| !member.drones.iter().any(|d| d == drone);
        if kind == "state" {
            let m = StateMsg::decode(message)?;
            if m.node != node {
                return Err(other_node(&m.node));
            }
            if let Some(d) = m.drones.iter().find(|d| not_its(&d.id)) {
                return Err(Refusal::NotItsDrone(d.id.clone()));
            }
            return Ok(Some(Checked::State(m)));
        }
        let m = MapMsg::decode(message, self.max_cells)?;
        if m.header.node != node {
            return Err(other_node(&m.header.node));
        }
        if not_its(&m.header.drone) {
            return Err(Refusal::NotItsDrone(m.header.drone));
        }
        Ok(Some(Checked::Map(m)))
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::fleet_bus::identity::Signer;
    use crate::fleet_bus::wire::WIRE_VERSION;

    fn state(node: &str, drones: &[&str]) -> Vec<u8> {
        let drones: Vec<serde_json::Value> = drones
            .iter()
            .map(|d| {
                serde_json::json!({"id": d, "position_enu_m": [0, 0, 0],
                    "velocity_enu_mps": [0, 0, 0], "yaw_rad": 0, "flying": true, "link": "ok"})
            })
            .collect();
        serde_json::to_vec(
            &serde_json::json!({"v": WIRE_VERSION, "node": node, "seq": 0,
            "sent_unix_us": 0, "drones": drones}),
        )
        .unwrap()
    }

    struct Fleet {
        intake: Intake,
        states: mpsc::Receiver<StateMsg>,
        stats: Arc<BusStats>,
        a: Signer,
        b: Signer,
    }

    fn fleet() -> Fleet {
        let (a, b) = (
            Signer::from_seed(&[1; 32]).unwrap(),
            Signer::from_seed(&[2; 32]).unwrap(),
        );
        let member = |s: &Signer, d: &str| Member {
            keys: vec![s.public()],
            drones: vec![d.to_string()],
        };
        let members = [
            ("a".to_string(), member(&a, "drone_a")),
            ("b".to_string(), member(&b, "drone_b")),
        ]
        .into();
        let stats = Arc::new(BusStats::default());
        let (tx, states) = mpsc::channel(8);
        let intake = Intake::new(
            "farm",
            "me",
            members,
            100,
            stats.clone(),
            tx,
            Arc::default(),
        );
        Fleet {
            intake,
            states,
            stats,
            a,
            b,
        }
    }

    /// Issue 29, item 1: a peer writing on another node's keys is refused and counted.
    #[test]
    fn a_peer_writing_on_another_nodes_keys_is_refused_and_counted() {
        let mut f = fleet();
        let key_a = "kestrel/farm/a/state";
        // `b` speaks as `a`, on `a`'s key, with its own key: the signature is not `a`'s.
        let forged = f.b.seal("farm", "a", "state", &state("a", &["drone_a"]));
        assert_eq!(
            f.intake.take(key_a, &forged),
            Err(Refusal::Open(OpenError::BadSignature("a".into())))
        );
        // Unsigned, as a peer of the old wire would send it.
        assert_eq!(
            f.intake.take(key_a, &state("a", &["drone_a"])),
            Err(Refusal::Open(OpenError::Unsigned))
        );
        // `b`'s own key, but speaking for `a`'s drone, or naming `a` inside.
        let theirs = f.b.seal("farm", "b", "state", &state("b", &["drone_a"]));
        assert_eq!(
            f.intake.take("kestrel/farm/b/state", &theirs),
            Err(Refusal::NotItsDrone("drone_a".into()))
        );
        let inside = f.b.seal("farm", "b", "state", &state("a", &["drone_b"]));
        assert!(matches!(
            f.intake.take("kestrel/farm/b/state", &inside),
            Err(Refusal::OtherNode { .. })
        ));
        // A made-up node is refused before anything is checked.
        let made_up = f.b.seal("farm", "x", "state", &state("x", &[]));
        assert_eq!(
            f.intake.take("kestrel/farm/x/state", &made_up),
            Err(Refusal::UnknownNode("x".into()))
        );
        assert_eq!(f.stats.refused.load(Ordering::Relaxed), 5);
        assert!(f.states.try_recv().is_err(), "nothing reached the loop");
        // `a` itself is heard.
        let own = f.a.seal("farm", "a", "state", &state("a", &["drone_a"]));
        f.intake.take(key_a, &own).unwrap();
        assert_eq!(f.states.try_recv().unwrap().node, "a");
    }

    #[test]
    fn a_recorded_message_played_again_is_refused() {
        let mut f = fleet();
        let key = "kestrel/farm/a/state";
        let first = f.a.seal("farm", "a", "state", &state("a", &["drone_a"]));
        let second = f.a.seal("farm", "a", "state", &state("a", &["drone_a"]));
        f.intake.take(key, &second).unwrap();
        assert!(matches!(
            f.intake.take(key, &second),
            Err(Refusal::Replayed { .. })
        ));
        assert!(matches!(
            f.intake.take(key, &first),
            Err(Refusal::Replayed { .. })
        ));
        // Nor can a state be played on the map key.
        assert!(f.intake.take("kestrel/farm/a/map", &second).is_err());
        assert_eq!(f.stats.refused.load(Ordering::Relaxed), 3);
    }

    #[test]
    fn keys_name_the_fleet_and_the_node() {
        assert_eq!(
            key_parts("kestrel/farm/pi-2/state", "farm"),
            Some(("pi-2", "state"))
        );
        assert_eq!(key_parts("kestrel/other/pi-2/state", "farm"), None);
        assert_eq!(key_parts("kestrel/farmx/pi-2/state", "farm"), None);
    }

    #[test]
    fn refusals_are_said_once_then_at_most_every_few_seconds_with_a_count() {
        let mut said = Said::default();
        let t0 = Instant::now();
        assert_eq!(said.now(t0), Some(0));
        for k in 1..1000 {
            assert_eq!(said.now(t0 + Duration::from_millis(k)), None);
        }
        assert_eq!(said.now(t0 + SAY_EVERY), Some(999));
    }
}
