//! Zenoh's own log lines, read for what an operator can act on and told in Kestrel's words.
//!
//! In: `tracing` events of the `zenoh*` targets (Zenoh logs through `tracing`). Out: [`Heard`]
//! reports handed to the process's [`JoinWatch`], which words them and rate-limits them; the
//! console's log output leaves Zenoh's raw lines out (unless `RUST_LOG` names zenoh).
//!
//! Zenoh 1.10 has no API for a refused handshake, so its log lines are the source:
//! - the connector's outcome per configured endpoint (`zenoh::net::runtime::orchestrator`,
//!   debug): `Successfully connected to configured peer E` or `Unable to connect to configured
//!   peer E! <error>`, where a close of reason GENERIC answering the OpenSyn is a refused
//!   credential (the only handshake check Kestrel peers can fail: they share the rest of the
//!   configuration) and one of reason INVALID means the peer already holds a session with this
//!   node, opened from its side (both sides `connect`: healthy; Zenoh logged it as an ERROR
//!   every retry);
//! - the accepting side's `UsrPwd extension - Recv OpenSyn. Invalid password.` (debug), whose
//!   peer address is in the `Establishment Accept OpenSyn: LOCAL => REMOTE` line (trace) just
//!   before it on the same thread: the handshake does not wait in between.

use std::cell::RefCell;
use std::fmt::Write as _;
use std::time::Instant;

use tracing::field::{Field, Visit};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::Targets;
use tracing_subscriber::layer::{Context, Layer};

use super::join::{Heard, JoinWatch, Outcome};

/// Zenoh warnings that say nothing an operator of a Kestrel fleet can act on.
const NOISE: &[&str] = &[
    "Gossip is disabled",
    "Scouting delay elapsed",
    "close session",
];

/// `text` without Zenoh's ` at /path/to/file.rs:123.` source locations, on one line.
pub fn without_sources(text: &str) -> String {
    let mut out = String::with_capacity(text.len());
    let mut rest = text;
    while let Some(i) = rest.find(" at /") {
        out.push_str(&rest[..i]);
        let tail = &rest[i + 1..];
        let end = tail
            .find(".rs:")
            .map(|j| j + 4 + tail[j + 4..].bytes().take_while(u8::is_ascii_digit).count());
        match end {
            Some(e) => rest = tail[e..].strip_prefix('.').unwrap_or(&tail[e..]),
            None => {
                rest = tail;
                break;
            }
        }
    }
    out.push_str(rest);
    out.split_whitespace().collect::<Vec<_>>().join(" ")
}

/// Why an endpoint could not be reached, in a few words.
fn unreachable_why(error: &str) -> String {
    const KNOWN: &[(&str, &str)] = &[
        (
            "Connection refused",
            "connection refused: is its Kestrel running and listening there?",
        ),
        ("No route to host", "no route to host"),
        ("Network is unreachable", "network unreachable"),
        ("timed out", "no answer"),
        ("Timeout", "no answer"),
        ("failed to lookup", "the name does not resolve"),
        ("Name or service not known", "the name does not resolve"),
    ];
    KNOWN
        .iter()
        .find(|(needle, _)| error.contains(needle))
        .map(|(_, why)| (*why).to_string())
        .unwrap_or_else(|| without_sources(error).chars().take(160).collect())
}

/// The close reason in `Received a close message (reason X) ...`.
fn close_reason(text: &str) -> Option<&str> {
    let rest = text.split_once("(reason ")?.1;
    rest.split_once(')').map(|(r, _)| r)
}

/// The peer address in a `... dst: tcp/127.0.0.1:7447, ...` link description.
fn link_dst(text: &str) -> Option<String> {
    let rest = text.split_once("dst: ")?.1;
    let dst = rest.split([',', ' ', '}']).next()?;
    Some(dst.split_once('/').map_or(dst, |(_, a)| a).to_string())
}

/// What one Zenoh log line (its level and message) says for the fleet's joining.
pub fn classify(level: Level, message: &str) -> Heard {
    if let Some(rest) = message.strip_prefix("Successfully connected to configured peer ") {
        return Heard::Attempt {
            endpoint: rest.trim().to_string(),
            outcome: Outcome::Joined,
        };
    }
    if let Some(rest) = message.strip_prefix("Unable to connect to configured peer ") {
        let Some((endpoint, error)) = rest.split_once("! ") else {
            return Heard::Noise;
        };
        let outcome = match close_reason(error) {
            Some("INVALID" | "MAX_LINKS") => Outcome::JoinedOtherWay,
            Some("GENERIC") => Outcome::Refused,
            _ => Outcome::Unreachable(unreachable_why(error)),
        };
        return Heard::Attempt {
            endpoint: endpoint.to_string(),
            outcome,
        };
    }
    if message.starts_with("Received a close message") && message.contains("response to an OpenSyn")
    {
        return match (close_reason(message), link_dst(message)) {
            (Some("GENERIC"), Some(addr)) => Heard::RefusedBy { addr },
            (Some("INVALID" | "MAX_LINKS"), _) => Heard::Noise,
            _ => Heard::Other {
                text: without_sources(message),
            },
        };
    }
    if let Some(rest) = message.strip_prefix("Establishment Accept OpenSyn: ") {
        let remote = rest.split_once(" => ").map(|(_, r)| r).unwrap_or_default();
        let remote = remote.split_once(". Received").map_or(remote, |(r, _)| r);
        return Heard::Opening {
            addr: remote
                .split_once('/')
                .map_or(remote, |(_, a)| a)
                .to_string(),
        };
    }
    if message.starts_with("UsrPwd extension - Recv OpenSyn.") {
        let why = if message.contains("Invalid password") {
            "wrong credentials"
        } else if message.contains("Invalid user") {
            "wrong credentials (unknown user)"
        } else if message.contains("Expected extension") {
            "it presented no credentials (no credentials_file)"
        } else {
            "its credentials did not decode"
        };
        return Heard::RefusedPeer { addr: None, why };
    }
    if level <= Level::WARN && !NOISE.iter().any(|n| message.starts_with(n)) {
        return Heard::Other {
            text: without_sources(message),
        };
    }
    Heard::Noise
}

/// The events this layer reads: Zenoh's warnings and errors, the connector's outcomes, and the
/// accepting side of the handshake.
pub fn targets() -> Targets {
    Targets::new()
        .with_target("zenoh", Level::WARN)
        .with_target("zenoh::net::runtime::orchestrator", Level::DEBUG)
        .with_target(
            "zenoh_transport::unicast::establishment::accept",
            Level::TRACE,
        )
}

thread_local! {
    /// The peer whose handshake this thread is accepting.
    static OPENING: RefCell<Option<String>> = const { RefCell::new(None) };
}

/// The `tracing` layer: every Zenoh event [`targets`] lets through, classified and handed to
/// the join watch (which logs through the bus, not from inside this layer: `tracing` drops an
/// event dispatched while another is being handled).
pub struct ZenohLog {
    watch: &'static JoinWatch,
}

impl ZenohLog {
    pub fn new(watch: &'static JoinWatch) -> Self {
        Self { watch }
    }
}

#[derive(Default)]
struct Message(String);

impl Visit for Message {
    fn record_debug(&mut self, field: &Field, value: &dyn std::fmt::Debug) {
        if field.name() == "message" {
            let _ = write!(self.0, "{value:?}");
        }
    }
}

impl<S: Subscriber> Layer<S> for ZenohLog {
    fn on_event(&self, event: &Event<'_>, _ctx: Context<'_, S>) {
        let mut message = Message::default();
        event.record(&mut message);
        let heard = match classify(*event.metadata().level(), &message.0) {
            Heard::Noise => return,
            Heard::Opening { addr } => {
                OPENING.with(|o| *o.borrow_mut() = Some(addr));
                return;
            }
            Heard::RefusedPeer { why, .. } => Heard::RefusedPeer {
                addr: OPENING.with(|o| o.borrow_mut().take()),
                why,
            },
            other => other,
        };
        self.watch.lock().hear(heard, Instant::now());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const LINK: &str = "TransportLinkUnicast { link: Link { src: tcp/127.0.0.1:54560, dst: tcp/127.0.0.1:7447, mtu: 65480, is_reliable: true, is_streamed: true }, config: TransportLinkUnicastConfig { direction: Outbound } } at /root/.cargo/registry/src/index.crates.io-1949cf8c6b5b557f/zenoh-transport-1.10.2/src/unicast/establishment/open.rs:526.";

    #[test]
    fn a_refused_handshake_is_told_from_both_sides() {
        let close = format!(
            "Received a close message (reason GENERIC) in response to an OpenSyn on: {LINK}"
        );
        assert_eq!(
            classify(Level::ERROR, &close),
            Heard::RefusedBy {
                addr: "127.0.0.1:7447".into()
            }
        );
        let attempt = format!(
            "Unable to connect to configured peer tcp/127.0.0.1:7447! {close}. Retry in 2s."
        );
        assert_eq!(
            classify(Level::DEBUG, &attempt),
            Heard::Attempt {
                endpoint: "tcp/127.0.0.1:7447".into(),
                outcome: Outcome::Refused
            }
        );
        assert_eq!(
            classify(Level::TRACE, "Establishment Accept OpenSyn: tcp/127.0.0.1:7447 => tcp/127.0.0.1:52114. Received: TransportMessage { .. }"),
            Heard::Opening { addr: "127.0.0.1:52114".into() }
        );
        assert_eq!(
            classify(
                Level::DEBUG,
                "UsrPwd extension - Recv OpenSyn. Invalid password. at /root/x/usrpwd.rs:424."
            ),
            Heard::RefusedPeer {
                addr: None,
                why: "wrong credentials"
            }
        );
    }

    #[test]
    fn a_session_opened_the_other_way_is_joined_and_quiet() {
        let close = format!(
            "Received a close message (reason INVALID) in response to an OpenSyn on: {LINK}"
        );
        assert_eq!(classify(Level::ERROR, &close), Heard::Noise);
        let attempt = format!(
            "Unable to connect to configured peer tcp/127.0.0.1:7447! {close}. Retry in 2s."
        );
        assert_eq!(
            classify(Level::DEBUG, &attempt),
            Heard::Attempt {
                endpoint: "tcp/127.0.0.1:7447".into(),
                outcome: Outcome::JoinedOtherWay
            }
        );
        assert_eq!(
            classify(
                Level::DEBUG,
                "Successfully connected to configured peer tcp/127.0.0.1:7448"
            ),
            Heard::Attempt {
                endpoint: "tcp/127.0.0.1:7448".into(),
                outcome: Outcome::Joined
            }
        );
    }

    #[test]
    fn noise_is_dropped_and_the_rest_loses_its_source_paths() {
        assert_eq!(
            classify(
                Level::WARN,
                "Gossip is disabled: cannot de-duplicate data traversing region gateways"
            ),
            Heard::Noise
        );
        assert_eq!(
            classify(Level::INFO, "Using ZID: f913457afe6fe42b08f1869bd6474710"),
            Heard::Noise
        );
        assert_eq!(
            classify(Level::ERROR, "Unable to bind tcp/0.0.0.0:7447: Address in use at /root/x/zenoh-link-tcp-1.10.2/src/unicast.rs:12. at /root/y/orchestrator.rs:99."),
            Heard::Other { text: "Unable to bind tcp/0.0.0.0:7447: Address in use".into() }
        );
        let refused = "Unable to connect to configured peer tcp/127.0.0.1:7448! Can not create a new TCP link bound to tcp/127.0.0.1:7448: [127.0.0.1:7448: Connection refused (os error 111) at /root/a/tcp.rs:105.] at /root/b/tcp.rs:133.. Retry in 500ms.";
        match classify(Level::DEBUG, refused) {
            Heard::Attempt {
                outcome: Outcome::Unreachable(why),
                ..
            } => {
                assert!(why.starts_with("connection refused"), "{why}");
            }
            other => panic!("{other:?}"),
        }
    }
}
