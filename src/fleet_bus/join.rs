//! Joining the fleet: whether this node has joined the peers its `[fleet] connect` lists, who
//! refused whom, and what the operator is told about it, in Kestrel's words.
//!
//! In: what Zenoh's handshakes reported ([`Heard`], read from its log lines by `zenoh_log`),
//! the endpoints this node connects to, whether a peer node was heard, and the time. Out: the
//! [`JoinStatus`] (joined, refused joins, the peers still waited for and why) and the lines to
//! log: each said once, then at most every [`REPEAT_EVERY`] with how often it happened since.
//!
//! "Joined" is latched: once every listed peer answered (or, listing none, once a peer was
//! heard), a peer that falls silent later is the lost-peer rules' business (`remote`), not this.

use std::collections::{HashMap, VecDeque};
use std::sync::{Mutex, OnceLock};
use std::time::{Duration, Instant};

/// A line said again no sooner than this after it was last said.
pub const REPEAT_EVERY: Duration = Duration::from_secs(30);
/// Lines kept until the bus logs them (the oldest go first).
const MAX_LINES: usize = 32;
/// Rate-limited kinds of lines remembered (peers, endpoints, Zenoh messages).
const MAX_KEYS: usize = 256;
/// Most lines said in one [`REPEAT_EVERY`] whatever their kind: an outsider can vary what it
/// makes Zenoh say (addresses, ports), so each kind being rate-limited is not enough. The
/// lines held back are counted and the count said once the window ends.
const MAX_LINES_PER_WINDOW: u32 = 12;

/// What one of Zenoh's handshake reports says.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Heard {
    /// An attempt to join a peer of `connect` (`endpoint` as configured) ended so.
    Attempt { endpoint: String, outcome: Outcome },
    /// The peer at `addr` refused this node's handshake: its credentials file does not hold
    /// this node's user and password.
    RefusedBy { addr: String },
    /// A peer at `addr` presented its credentials (the refusal that may follow is about it).
    Opening { addr: String },
    /// This node refused a peer's credentials (`why`), from `addr` when known.
    RefusedPeer {
        addr: Option<String>,
        why: &'static str,
    },
    /// A Zenoh warning or error nothing above explains (its text, without source paths).
    Other { text: String },
    /// Nothing an operator can act on.
    Noise,
}

/// How an attempt to join a listed peer ended.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Outcome {
    Joined,
    /// The peer already has a session with this node, opened from its side (both sides list
    /// each other in `connect`): joined.
    JoinedOtherWay,
    Refused,
    Unreachable(String),
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Severity {
    Info,
    Warn,
}

/// Whether this node has joined its fleet, as `fleet_bus` in `GET /api/status` shows it.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct JoinStatus {
    pub joined: bool,
    /// Missions and explorations are refused until joined (`require_join` and peers listed).
    pub join_required: bool,
    /// Handshakes refused for their credentials, by a peer or by this node.
    pub refused_joins: u64,
    /// The listed peers not joined yet, each with why (`127.0.0.1:7448 (refused this node:
    /// credentials do not match)`).
    pub waiting_for: Vec<String>,
}

#[derive(Debug, Clone, PartialEq, Eq)]
enum PeerState {
    Waiting,
    Unreachable(String),
    Refused,
    Joined,
}

/// The address part of an endpoint: `tcp/10.0.0.2:7447` → `10.0.0.2:7447`.
fn addr(endpoint: &str) -> &str {
    endpoint.split_once('/').map_or(endpoint, |(_, a)| a)
}

/// The host part of an address (a refused peer's source port changes every attempt).
fn host(addr: &str) -> &str {
    addr.rsplit_once(':').map_or(addr, |(h, _)| h)
}

#[derive(Debug, Default)]
pub struct JoinState {
    fleet: String,
    listed: Vec<(String, PeerState)>,
    require: bool,
    joined: bool,
    refused_joins: u64,
    /// Per kind of line: when it was last said and how often it was held back since.
    said: HashMap<String, (Instant, u64)>,
    lines: VecDeque<(Severity, String)>,
    revision: u64,
    /// The current window of [`MAX_LINES_PER_WINDOW`]: when it began, lines said, lines held.
    window: Option<(Instant, u32, u64)>,
}

impl JoinState {
    /// The bus starts: fleet `fleet`, joining the peers of `connect`.
    pub fn expect(&mut self, fleet: &str, connect: &[String], require_join: bool) {
        self.fleet = fleet.to_string();
        self.listed = connect
            .iter()
            .map(|e| (e.clone(), PeerState::Waiting))
            .collect();
        self.require = require_join && !connect.is_empty();
        self.joined = false;
        self.revision += 1;
    }

    /// A peer node's message was heard: a node that lists no peer has joined.
    pub fn peer_heard(&mut self, now: Instant) {
        if self.listed.is_empty() && !self.joined {
            self.joined = true;
            self.revision += 1;
            let text = format!("fleet bus: joined fleet `{}`: a peer was heard", self.fleet);
            self.say("joined", Severity::Info, text, now);
        }
    }

    pub fn hear(&mut self, heard: Heard, now: Instant) {
        match heard {
            Heard::Attempt { endpoint, outcome } => self.attempt(&endpoint, outcome, now),
            Heard::RefusedBy { addr } => {
                self.refused();
                let text = format!("fleet bus: peer at {addr} refused: credentials do not match (this node's first `user:password` line of [fleet] credentials_file is not in that peer's file)");
                self.say(&format!("refused-by {addr}"), Severity::Warn, text, now);
            }
            Heard::RefusedPeer { addr, why } => {
                self.refused();
                let (key, text) = match addr {
                    Some(a) => (
                        format!("refused {}", host(&a)),
                        format!("fleet bus: refused a peer from {a}: {why} (its first `user:password` line is not in [fleet] credentials_file)"),
                    ),
                    None => (
                        "refused".into(),
                        format!("fleet bus: refused a peer: {why}"),
                    ),
                };
                self.say(&key, Severity::Warn, text, now);
            }
            Heard::Other { text } => {
                let key: String = text.chars().take(40).collect();
                self.say(
                    &key,
                    Severity::Warn,
                    format!("fleet bus: zenoh: {text}"),
                    now,
                );
            }
            Heard::Opening { .. } | Heard::Noise => {}
        }
    }

    fn refused(&mut self) {
        self.refused_joins += 1;
        self.revision += 1;
    }

    fn attempt(&mut self, endpoint: &str, outcome: Outcome, now: Instant) {
        let Some(i) = self.listed.iter().position(|(e, _)| e == endpoint) else {
            return;
        };
        let state = match outcome {
            Outcome::Joined | Outcome::JoinedOtherWay => PeerState::Joined,
            Outcome::Refused => PeerState::Refused,
            Outcome::Unreachable(why) => {
                let text = format!(
                    "fleet bus: peer at {} not reachable ({why}); retrying",
                    addr(endpoint)
                );
                self.say(
                    &format!("unreachable {endpoint}"),
                    Severity::Info,
                    text,
                    now,
                );
                PeerState::Unreachable(why)
            }
        };
        let Some((_, old)) = self.listed.get_mut(i) else {
            return;
        };
        if *old == state || (*old == PeerState::Joined && self.joined) {
            return;
        }
        let newly_joined = state == PeerState::Joined;
        *old = state;
        self.revision += 1;
        if newly_joined {
            let text = format!("fleet bus: joined the peer at {}", addr(endpoint));
            self.say(&format!("joined {endpoint}"), Severity::Info, text, now);
        }
        if !self.joined && self.listed.iter().all(|(_, s)| *s == PeerState::Joined) {
            self.joined = true;
            let text = format!(
                "fleet bus: joined fleet `{}`: every peer of `connect` answered",
                self.fleet
            );
            self.say("joined", Severity::Info, text, now);
        }
    }

    /// Queues `text` unless a line of this `key` was said less than [`REPEAT_EVERY`] ago.
    fn say(&mut self, key: &str, severity: Severity, text: String, now: Instant) {
        if let Some((last, held)) = self.said.get_mut(key) {
            if now.duration_since(*last) < REPEAT_EVERY {
                *held += 1;
                return;
            }
            let text = match *held {
                0 => text,
                n => format!("{text} ({n} more since it was last said)"),
            };
            *last = now;
            *held = 0;
            self.push(severity, text, now);
            return;
        }
        if self.said.len() >= MAX_KEYS {
            self.said
                .retain(|_, (last, _)| now.duration_since(*last) < REPEAT_EVERY);
        }
        // Still full: the line is said (within the window's budget) but its kind not kept.
        if self.said.len() < MAX_KEYS {
            self.said.insert(key.to_string(), (now, 0));
        }
        self.push(severity, text, now);
    }

    /// Queues a line within the window's budget; the first line of a new window says how many
    /// the last one held back.
    fn push(&mut self, severity: Severity, text: String, now: Instant) {
        let (start, said, held) = self.window.get_or_insert((now, 0, 0));
        if now.duration_since(*start) >= REPEAT_EVERY {
            let held_back = std::mem::take(held);
            *start = now;
            *said = 0;
            if held_back > 0 {
                self.queue(
                    Severity::Warn,
                    format!("fleet bus: {held_back} more lines about peers were held back (at most {MAX_LINES_PER_WINDOW} every {} s)", REPEAT_EVERY.as_secs()),
                );
                return self.push(severity, text, now);
            }
        }
        let Some((_, said, held)) = self.window.as_mut() else {
            return;
        };
        if *said >= MAX_LINES_PER_WINDOW {
            *held += 1;
            return;
        }
        *said += 1;
        self.queue(severity, text);
    }

    fn queue(&mut self, severity: Severity, text: String) {
        if self.lines.len() == MAX_LINES {
            self.lines.pop_front();
        }
        self.lines.push_back((severity, text));
    }

    /// The lines to log, oldest first.
    pub fn take_lines(&mut self) -> Vec<(Severity, String)> {
        self.lines.drain(..).collect()
    }

    /// Changes whenever the status does.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    pub fn status(&self) -> JoinStatus {
        let waiting_for = self
            .listed
            .iter()
            .filter_map(|(e, s)| {
                let why = match s {
                    PeerState::Joined => return None,
                    PeerState::Waiting => "no answer yet".to_string(),
                    PeerState::Unreachable(why) => format!("not reachable: {why}"),
                    PeerState::Refused => "refused this node: credentials do not match".into(),
                };
                Some(format!("{} ({why})", addr(e)))
            })
            .collect();
        JoinStatus {
            joined: self.joined,
            join_required: self.require,
            refused_joins: self.refused_joins,
            waiting_for: if self.joined { Vec::new() } else { waiting_for },
        }
    }
}

/// The process's join state, shared by the log layer that hears Zenoh and the bus that reports
/// it: one per process, as the log subscriber is.
#[derive(Debug, Default)]
pub struct JoinWatch(Mutex<JoinState>);

impl JoinWatch {
    pub fn global() -> &'static JoinWatch {
        static WATCH: OnceLock<JoinWatch> = OnceLock::new();
        WATCH.get_or_init(JoinWatch::default)
    }

    /// The state, locked (a panic elsewhere while it was held leaves it usable).
    pub fn lock(&self) -> std::sync::MutexGuard<'_, JoinState> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn attempt(endpoint: &str, outcome: Outcome) -> Heard {
        Heard::Attempt {
            endpoint: endpoint.into(),
            outcome,
        }
    }

    const A: &str = "tcp/127.0.0.1:7447";
    const B: &str = "tcp/127.0.0.1:7448";

    #[test]
    fn joined_once_every_listed_peer_answered_either_way_and_it_stays_joined() {
        let t0 = Instant::now();
        let mut s = JoinState::default();
        s.expect("farm-7", &[A.into(), B.into()], true);
        assert!(!s.status().joined && s.status().join_required);
        assert_eq!(
            s.status().waiting_for,
            [
                "127.0.0.1:7447 (no answer yet)",
                "127.0.0.1:7448 (no answer yet)"
            ]
        );
        s.hear(attempt(A, Outcome::Joined), t0);
        s.hear(
            attempt(B, Outcome::Unreachable("connection refused".into())),
            t0,
        );
        assert_eq!(
            s.status().waiting_for,
            ["127.0.0.1:7448 (not reachable: connection refused)"]
        );
        s.hear(attempt(B, Outcome::JoinedOtherWay), t0);
        assert!(s.status().joined);
        assert!(s.status().waiting_for.is_empty());
        // A peer lost later is the lost-peer rules' business: still joined.
        s.hear(
            attempt(A, Outcome::Unreachable("connection refused".into())),
            t0,
        );
        assert!(s.status().joined);
        let lines: Vec<String> = s.take_lines().into_iter().map(|(_, l)| l).collect();
        assert!(
            lines.iter().any(|l| l.contains("joined fleet `farm-7`")),
            "{lines:?}"
        );
        assert!(lines.iter().all(|l| !l.contains("zenoh")), "{lines:?}");
    }

    #[test]
    fn refusals_are_counted_every_time_and_said_once_per_peer_then_rate_limited() {
        let t0 = Instant::now();
        let mut s = JoinState::default();
        s.expect("farm-7", &[A.into()], true);
        for k in 0..5 {
            let t = t0 + Duration::from_secs(2 * k);
            s.hear(attempt(A, Outcome::Refused), t);
            s.hear(
                Heard::RefusedBy {
                    addr: "127.0.0.1:7447".into(),
                },
                t,
            );
            s.hear(
                Heard::RefusedPeer {
                    addr: Some(format!("127.0.0.1:{}", 52000 + k)),
                    why: "wrong credentials",
                },
                t,
            );
        }
        let status = s.status();
        assert_eq!(status.refused_joins, 10);
        assert!(!status.joined);
        assert_eq!(
            status.waiting_for,
            ["127.0.0.1:7447 (refused this node: credentials do not match)"]
        );
        let lines = s.take_lines();
        assert_eq!(lines.len(), 2, "{lines:?}");
        assert!(lines.iter().all(|(sev, _)| *sev == Severity::Warn));
        assert!(lines[0]
            .1
            .starts_with("fleet bus: peer at 127.0.0.1:7447 refused: credentials do not match"));
        assert!(lines[1]
            .1
            .starts_with("fleet bus: refused a peer from 127.0.0.1:52000: wrong credentials"));
        // Said again after REPEAT_EVERY, with how often it was held back.
        s.hear(
            Heard::RefusedBy {
                addr: "127.0.0.1:7447".into(),
            },
            t0 + REPEAT_EVERY + Duration::from_secs(9),
        );
        let again = s.take_lines();
        assert_eq!(again.len(), 1);
        assert!(
            again[0].1.ends_with("(4 more since it was last said)"),
            "{again:?}"
        );
    }

    /// Issue 29, item 7: an outsider who varies what Zenoh reports (a new address each time)
    /// gets at most MAX_LINES_PER_WINDOW lines a window, then one line with the count.
    #[test]
    fn varied_refusals_are_capped_per_window_and_counted() {
        let t0 = Instant::now();
        let mut s = JoinState::default();
        s.expect("farm-7", &[], true);
        for k in 0..500u32 {
            s.hear(
                Heard::RefusedPeer {
                    addr: Some(format!("10.0.{}.{}:5000", k / 250, k % 250)),
                    why: "wrong credentials",
                },
                t0 + Duration::from_millis(u64::from(k)),
            );
        }
        assert_eq!(s.status().refused_joins, 500);
        assert!(s.said.len() <= MAX_KEYS);
        assert_eq!(s.take_lines().len(), MAX_LINES_PER_WINDOW as usize);
        s.hear(
            Heard::Other {
                text: "something new".into(),
            },
            t0 + REPEAT_EVERY + Duration::from_secs(1),
        );
        let next: Vec<String> = s.take_lines().into_iter().map(|(_, l)| l).collect();
        assert_eq!(next.len(), 2, "{next:?}");
        assert!(next[0].contains("488 more lines"), "{next:?}");
    }

    #[test]
    fn a_node_listing_no_peer_joins_when_one_is_heard_and_holds_nothing() {
        let mut s = JoinState::default();
        s.expect("farm-7", &[], true);
        assert!(!s.status().joined && !s.status().join_required);
        s.peer_heard(Instant::now());
        assert!(s.status().joined);
        let mut off = JoinState::default();
        off.expect("farm-7", &[A.into()], false);
        assert!(!off.status().join_required);
    }
}
