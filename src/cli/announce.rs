//! What Kestrel tells the ground station: the host's events as short texts for each vehicle's
//! MAVLink link (QGroundControl shows them as STATUSTEXT from component 191).
//!
//! In: the host's events, as `kestrel run`'s event printer receives them (a `broadcast`: a slow
//! reader skips, the control loop never waits). Out: a [`StatusText`] per behavior event (the
//! console's words), per change of a mission's state and per alert, handed to the vehicle's
//! [`TextSender`] without waiting; pacing, chunking and the `Kestrel: ` prefix are the MAVLink
//! session's (`platform::mavlink::statustext`).
//!
//! Left out: the autopilot's own words (the ground station has them from the autopilot), mode
//! changes (it shows the mode) and link alerts (about the very link the text would travel on).

use crate::cli::console::behavior_line;
use kestrel::behavior::{BehaviorEvent, BehaviorResult};
use kestrel::host::status::{EventBody, HostEvent};
use kestrel::mission::{ExecState, MissionStatus};
use kestrel::platform::mavlink::statustext::{Severity, StatusText};
use kestrel::platform::mavlink::TextSender;
use std::collections::HashMap;

/// Each drone's mission state as last announced.
#[derive(Debug, Default)]
pub struct Announcer {
    missions: HashMap<String, (ExecState, Option<u32>)>,
}

impl Announcer {
    /// The drone and the text for `event`, if it is one the ground station gets.
    pub fn text(&mut self, event: &HostEvent) -> Option<(String, StatusText)> {
        match event {
            HostEvent::Event { drone, event, .. } => {
                let text = match event {
                    EventBody::Behavior(b) => behavior_text(b),
                    EventBody::Alert { message } => alert_text(message)?,
                    EventBody::MissionUpdate { .. } | EventBody::Autopilot { .. } => return None,
                };
                Some((drone.clone(), text))
            }
            HostEvent::MissionStatus { drone, status } => {
                let now = (status.state, status.mission_id);
                let before = self.missions.insert(drone.clone(), now);
                let text = mission_text(before, status)?;
                Some((drone.clone(), text))
            }
            HostEvent::MapUpdate { .. } => None,
        }
    }
}

fn behavior_text(event: &BehaviorEvent) -> StatusText {
    let severity = match event {
        BehaviorEvent::Finished {
            result: BehaviorResult::Failed { .. },
            ..
        } => Severity::Error,
        BehaviorEvent::Finished {
            result: BehaviorResult::Aborted { .. },
            ..
        } => Severity::Warning,
        _ => Severity::Info,
    };
    StatusText {
        severity,
        text: behavior_line(event),
    }
}

fn alert_text(message: &str) -> Option<StatusText> {
    if message.starts_with("mode ") || message.starts_with("link ") {
        return None;
    }
    Some(StatusText {
        severity: Severity::Warning,
        text: message.to_string(),
    })
}

/// The text for a mission whose state went from `before` (state, mission id) to `status`.
fn mission_text(
    before: Option<(ExecState, Option<u32>)>,
    status: &MissionStatus,
) -> Option<StatusText> {
    let (was, was_id) = before.unwrap_or_default();
    let id = status.mission_id?;
    let notice = |what: &str| StatusText {
        severity: Severity::Notice,
        text: format!("mission {id} {what}"),
    };
    let same = was_id == Some(id);
    match status.state {
        ExecState::Running if was == ExecState::Paused && same => Some(notice("resumed")),
        ExecState::Running if was == ExecState::Idle || !same => Some(notice("started")),
        ExecState::Paused if was != ExecState::Paused || !same => Some(notice("paused")),
        ExecState::Idle if was != ExecState::Idle && same => match &status.last_error {
            Some(e) => Some(StatusText {
                severity: Severity::Error,
                text: format!("mission {id} failed: {e}"),
            }),
            None if status.pending_items == 0 && status.done_items > 0 => Some(notice("finished")),
            None => Some(notice("stopped")),
        },
        _ => None,
    }
}

/// Sends each vehicle's texts to its MAVLink session.
pub struct GroundTexts {
    announcer: Announcer,
    senders: HashMap<String, TextSender>,
}

impl GroundTexts {
    /// `senders`: the drone id of each MAVLink vehicle and its session's sender.
    pub fn new(senders: Vec<(String, TextSender)>) -> Self {
        Self {
            announcer: Announcer::default(),
            senders: senders.into_iter().collect(),
        }
    }

    /// Never waits: a text that finds the vehicle's queue full is dropped (and counted there).
    pub fn on_event(&mut self, event: &HostEvent) {
        if let Some((drone, text)) = self.announcer.text(event) {
            if let Some(sender) = self.senders.get(&drone) {
                sender.send(text);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use kestrel::behavior::{Failure, FailureCode};
    use serde_json::json;

    fn status(state: ExecState, id: u32, last_error: Option<&str>) -> HostEvent {
        HostEvent::MissionStatus {
            drone: "drone_0".into(),
            status: MissionStatus {
                state,
                mission_id: Some(id),
                pending_items: 0,
                done_items: 3,
                last_error: last_error.map(str::to_string),
                ..MissionStatus::default()
            },
        }
    }

    fn said(a: &mut Announcer, e: &HostEvent) -> Option<(Severity, String)> {
        a.text(e).map(|(_, t)| (t.severity, t.text))
    }

    #[test]
    fn mission_states_become_notices_and_a_failure_an_error() {
        let mut a = Announcer::default();
        let notice = |s: &str| Some((Severity::Notice, s.to_string()));
        assert_eq!(
            said(&mut a, &status(ExecState::Running, 4, None)),
            notice("mission 4 started")
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Running, 4, None)),
            None,
            "no change"
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Paused, 4, None)),
            notice("mission 4 paused")
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Running, 4, None)),
            notice("mission 4 resumed")
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Idle, 4, None)),
            notice("mission 4 finished")
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Running, 5, None)),
            notice("mission 5 started")
        );
        assert_eq!(
            said(&mut a, &status(ExecState::Idle, 5, Some("go_to #2 failed"))),
            Some((Severity::Error, "mission 5 failed: go_to #2 failed".into()))
        );
        // A mission loaded but never run says nothing.
        let mut fresh = Announcer::default();
        assert_eq!(said(&mut fresh, &status(ExecState::Idle, 6, None)), None);
    }

    #[test]
    fn behaviors_read_as_on_the_console_with_their_severity() {
        let mut a = Announcer::default();
        let event = |b: BehaviorEvent| HostEvent::Event {
            drone: "drone_0".into(),
            t: 1.0,
            event: EventBody::Behavior(b),
        };
        let started = event(BehaviorEvent::Started {
            id: 2,
            behavior: "go_to".into(),
            goal: json!({"speed": 2}),
        });
        assert_eq!(
            said(&mut a, &started),
            Some((Severity::Info, "go_to #2 started (speed=2)".into()))
        );
        let failed = event(BehaviorEvent::Finished {
            id: 2,
            behavior: "go_to".into(),
            result: BehaviorResult::failed(Failure::new(FailureCode::PlannerTimeout, "too slow")),
        });
        assert_eq!(said(&mut a, &failed).map(|s| s.0), Some(Severity::Error));
        let alert = |m: &str| HostEvent::Event {
            drone: "drone_0".into(),
            t: 1.0,
            event: EventBody::Alert { message: m.into() },
        };
        assert_eq!(
            said(&mut a, &alert("safety: held at the geofence")).map(|s| s.0),
            Some(Severity::Warning)
        );
        assert_eq!(said(&mut a, &alert("mode OFFBOARD")), None);
        assert_eq!(said(&mut a, &alert("link lost")), None);
    }
}
