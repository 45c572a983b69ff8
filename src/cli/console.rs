//! What Kestrel prints for a person: its log lines and the behavior events of the flights.
//!
//! In: `tracing` events (from every part), the host's behavior events. Out: one readable line
//! each on standard output, coloured only when that is a terminal. Under systemd (standard
//! output connected to the journal, as `JOURNAL_STREAM` says) log records go to journald
//! instead, with their level as the priority; if the journal cannot be reached they stay on
//! standard output.

use kestrel::behavior::{BehaviorEvent, BehaviorResult};
use kestrel::fleet_bus::join::JoinWatch;
use kestrel::fleet_bus::zenoh_log::{self, ZenohLog};
use serde_json::Value;
use std::io::IsTerminal;
use tracing_subscriber::filter::{LevelFilter, Targets};
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::util::SubscriberInitExt;
use tracing_subscriber::Layer;

/// The longest goal summary printed with a `started` line (characters).
const MAX_GOAL_CHARS: usize = 120;

/// Installs the log output: journald under systemd, otherwise lines on standard output. Zenoh's
/// own lines go to the fleet bus's reader (`fleet_bus::zenoh_log`), which says what matters in
/// Kestrel's words; they are printed raw only when `RUST_LOG` names zenoh.
pub fn init_logging() {
    let zenoh = ZenohLog::new(JoinWatch::global()).with_filter(zenoh_log::targets());
    let registry = tracing_subscriber::registry().with(zenoh);
    if stdout_is_the_journal() {
        if let Ok(journal) = tracing_journald::layer() {
            registry
                .with(
                    journal
                        .with_syslog_identifier("kestrel".into())
                        .with_filter(output_filter()),
                )
                .init();
            return;
        }
    }
    registry
        .with(
            tracing_subscriber::fmt::layer()
                .with_target(false)
                .with_ansi(std::io::stdout().is_terminal())
                .with_filter(output_filter()),
        )
        .init();
}

/// `RUST_LOG` (default `info`), with Zenoh's lines left out unless it names them.
fn output_filter() -> Targets {
    filter_for(std::env::var("RUST_LOG").ok().as_deref())
}

/// `RUST_LOG`'s per-target levels (`info,kestrel::behavior::explore=debug`): a target is a
/// prefix of the module path, a bare level is the default. Not understood or empty: `info`.
fn filter_for(asked: Option<&str>) -> Targets {
    let asked = asked.unwrap_or_default();
    let filter = asked
        .parse::<Targets>()
        .ok()
        .filter(|_| !asked.trim().is_empty())
        .unwrap_or_else(|| Targets::new().with_default(LevelFilter::INFO));
    if asked.contains("zenoh") {
        filter
    } else {
        filter.with_target("zenoh", LevelFilter::OFF)
    }
}

/// systemd sets `JOURNAL_STREAM=<device>:<inode>` to the stream it connected standard output
/// or error to; it is ours when it names our standard output (a child's output may be
/// redirected elsewhere while the variable is inherited).
fn stdout_is_the_journal() -> bool {
    use std::os::unix::fs::MetadataExt;
    let Ok(stream) = std::env::var("JOURNAL_STREAM") else {
        return false;
    };
    let Ok(stdout) = std::fs::metadata("/proc/self/fd/1") else {
        return false;
    };
    names_stream(&stream, stdout.dev(), stdout.ino())
}

fn names_stream(journal_stream: &str, dev: u64, ino: u64) -> bool {
    let mut parts = journal_stream.split(':');
    let (Some(d), Some(i), None) = (parts.next(), parts.next(), parts.next()) else {
        return false;
    };
    d.parse() == Ok(dev) && i.parse() == Ok(ino)
}

/// One line for a behavior event, e.g. `takeoff #1 started (height=1, speed=0.5)` or
/// `go_to #3 aborted (stopped): stopped`.
pub fn behavior_line(event: &BehaviorEvent) -> String {
    match event {
        BehaviorEvent::Started { id, behavior, goal } => {
            format!("{behavior} #{id} started{}", goal_summary(goal))
        }
        BehaviorEvent::Modified { id, behavior, goal } => {
            format!("{behavior} #{id} modified{}", goal_summary(goal))
        }
        BehaviorEvent::Paused { id, behavior } => format!("{behavior} #{id} paused"),
        BehaviorEvent::Resumed { id, behavior } => format!("{behavior} #{id} resumed"),
        BehaviorEvent::Finished {
            id,
            behavior,
            result,
        } => match result {
            BehaviorResult::Succeeded => format!("{behavior} #{id} succeeded"),
            BehaviorResult::Failed { code, reason } => {
                format!("{behavior} #{id} failed ({}): {reason}", code.as_str())
            }
            BehaviorResult::Aborted { code, reason } => {
                format!("{behavior} #{id} aborted ({}): {reason}", code.as_str())
            }
        },
    }
}

/// ` (key=value, ...)` of a goal's arguments; long lists are counted, not printed.
fn goal_summary(goal: &Value) -> String {
    let Some(args) = goal.as_object().filter(|a| !a.is_empty()) else {
        return String::new();
    };
    let parts: Vec<String> = args
        .iter()
        .map(|(k, v)| format!("{k}={}", value_summary(v)))
        .collect();
    let mut s = parts.join(", ");
    if s.chars().count() > MAX_GOAL_CHARS {
        s = s.chars().take(MAX_GOAL_CHARS - 1).collect::<String>() + "…";
    }
    format!(" ({s})")
}

fn value_summary(v: &Value) -> String {
    match v {
        Value::String(s) => s.clone(),
        Value::Array(items) if items.len() > 4 => format!("[{} items]", items.len()),
        other => other.to_string(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::behavior::{Failure, FailureCode};
    use serde_json::json;

    #[test]
    fn events_read_as_sentences() {
        let started = BehaviorEvent::Started {
            id: 1,
            behavior: "takeoff".into(),
            goal: json!({"height": 1.5, "speed": 0.5}),
        };
        assert_eq!(
            behavior_line(&started),
            "takeoff #1 started (height=1.5, speed=0.5)"
        );
        let stopped = BehaviorEvent::Finished {
            id: 3,
            behavior: "go_to".into(),
            result: BehaviorResult::aborted(Failure::new(FailureCode::Stopped, "stopped")),
        };
        assert_eq!(
            behavior_line(&stopped),
            "go_to #3 aborted (stopped): stopped"
        );
        let done = BehaviorEvent::Finished {
            id: 4,
            behavior: "land".into(),
            result: BehaviorResult::Succeeded,
        };
        assert_eq!(behavior_line(&done), "land #4 succeeded");
    }

    #[test]
    fn long_goals_are_shortened() {
        let path: Vec<Value> = (0..50).map(|i| json!([i, 0, 2])).collect();
        let goal = json!({"path": path, "speed": 1.0, "frame_id": "earth"});
        let line = behavior_line(&BehaviorEvent::Started {
            id: 2,
            behavior: "follow_path".into(),
            goal,
        });
        assert_eq!(
            line,
            "follow_path #2 started (frame_id=earth, path=[50 items], speed=1.0)"
        );
        let huge = json!({"note": "x".repeat(1000)});
        let line = behavior_line(&BehaviorEvent::Modified {
            id: 2,
            behavior: "hover".into(),
            goal: huge,
        });
        assert!(line.chars().count() < 150, "{line}");
    }

    #[test]
    fn rust_log_sets_levels_per_target_and_zenoh_stays_quiet() {
        use tracing::Level;
        let unset = filter_for(None);
        assert!(unset.would_enable("kestrel::host", &Level::INFO));
        assert!(!unset.would_enable("kestrel::host", &Level::DEBUG));
        assert!(!unset.would_enable("zenoh_transport::unicast", &Level::ERROR));
        let asked = filter_for(Some("warn,kestrel::behavior::explore=debug"));
        assert!(asked.would_enable("kestrel::behavior::explore::events", &Level::DEBUG));
        assert!(!asked.would_enable("kestrel::host", &Level::INFO));
        assert!(asked.would_enable("kestrel::host", &Level::WARN));
        assert!(!asked.would_enable("zenoh", &Level::ERROR));
        let zenoh = filter_for(Some("info,zenoh=debug"));
        assert!(zenoh.would_enable("zenoh::net::runtime", &Level::DEBUG));
        for wrong in [Some(""), Some("kestrel=loud")] {
            let f = filter_for(wrong);
            assert!(f.would_enable("kestrel", &Level::INFO), "{wrong:?}");
            assert!(!f.would_enable("kestrel", &Level::DEBUG), "{wrong:?}");
        }
    }

    #[test]
    fn the_journal_stream_must_name_our_output() {
        assert!(names_stream("8:12345", 8, 12345));
        assert!(!names_stream("8:12345", 8, 1));
        assert!(!names_stream("8", 8, 12345));
        assert!(!names_stream("8:12345:1", 8, 12345));
        assert!(!names_stream("", 0, 0));
    }
}
