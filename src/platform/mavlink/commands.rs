//! Command tracking: every COMMAND_LONG waits for its COMMAND_ACK.
//!
//! In: commands to send ([`CommandSpec`]), COMMAND_ACKs and autopilot texts as they arrive,
//! and the time. Out: the COMMAND_LONGs due now (first sends and retries with `confirmation`
//! incremented), and one [`CommandOutcome`] per command, carrying the autopilot's own reason
//! for a refusal (ArduPilot's STATUSTEXT before the ack, PX4's EVENTs right after it).
//! At most one command of each id is in flight, as MAVLink acks are matched by command id.

use super::events::AutopilotText;
use crate::types::RequestRefused;
use mavlink::dialects::ardupilotmega::{MavCmd, MavResult, COMMAND_ACK_DATA, COMMAND_LONG_DATA};
use std::time::Duration;

/// How long a refusal waits for the texts that explain it (PX4 sends EVENTs after the ack).
const REASON_GRACE: Duration = Duration::from_millis(300);

#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct CommandId(u64);

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CommandSpec {
    pub command: MavCmd,
    pub params: [f32; 7],
    pub target_component: u8,
}

/// How a command ended.
#[derive(Debug, Clone, PartialEq)]
pub enum CommandOutcome {
    Accepted,
    /// The autopilot answered with something other than ACCEPTED; `reason` is its own text.
    Rejected {
        result: MavResult,
        reason: Option<String>,
    },
    /// No ack after every retry.
    TimedOut {
        attempts: u8,
    },
    /// The link went down before the ack.
    LinkLost,
}

impl CommandOutcome {
    /// `Ok` for ACCEPTED, else the reason in words.
    pub fn into_result(self, what: &str) -> Result<(), RequestRefused> {
        let reason = match self {
            Self::Accepted => return Ok(()),
            Self::Rejected {
                result,
                reason: Some(r),
            } => format!("{what} refused ({}): {r}", result_name(result)),
            Self::Rejected {
                result,
                reason: None,
            } => format!("{what} refused: {}", result_name(result)),
            Self::TimedOut { attempts } => {
                format!("{what}: no answer from the autopilot after {attempts} attempts")
            }
            Self::LinkLost => format!("{what}: link to the autopilot lost"),
        };
        Err(RequestRefused(reason))
    }
}

fn result_name(r: MavResult) -> &'static str {
    match r {
        MavResult::MAV_RESULT_ACCEPTED => "accepted",
        MavResult::MAV_RESULT_TEMPORARILY_REJECTED => "temporarily rejected",
        MavResult::MAV_RESULT_DENIED => "denied",
        MavResult::MAV_RESULT_UNSUPPORTED => "unsupported",
        MavResult::MAV_RESULT_FAILED => "failed",
        MavResult::MAV_RESULT_IN_PROGRESS => "in progress",
        MavResult::MAV_RESULT_CANCELLED => "cancelled",
        _ => "not executed",
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum State {
    Queued,
    InFlight {
        sent_at: Duration,
    },
    /// Refused at `at`; waiting briefly for the texts that explain it.
    Refused {
        result: MavResult,
        at: Duration,
    },
}

#[derive(Debug)]
struct Pending {
    id: CommandId,
    spec: CommandSpec,
    state: State,
    attempts: u8,
    first_sent: Option<Duration>,
    reasons: Vec<String>,
}

/// Pending commands and finished outcomes.
#[derive(Debug)]
pub struct CommandTracker {
    timeout: Duration,
    retries: u8,
    next_id: u64,
    pending: Vec<Pending>,
    finished: Vec<(CommandId, CommandOutcome)>,
}

impl CommandTracker {
    pub fn new(timeout: Duration, retries: u8) -> Self {
        Self {
            timeout,
            retries,
            next_id: 0,
            pending: Vec::new(),
            finished: Vec::new(),
        }
    }

    pub fn submit(&mut self, spec: CommandSpec) -> CommandId {
        self.next_id += 1;
        let id = CommandId(self.next_id);
        self.pending.push(Pending {
            id,
            spec,
            state: State::Queued,
            attempts: 0,
            first_sent: None,
            reasons: Vec::new(),
        });
        id
    }

    pub fn is_pending(&self, id: CommandId) -> bool {
        self.pending.iter().any(|p| p.id == id)
    }

    /// The outcome of a finished command, once (later calls return `None`).
    pub fn take_outcome(&mut self, id: CommandId) -> Option<CommandOutcome> {
        let i = self.finished.iter().position(|(f, _)| *f == id)?;
        Some(self.finished.swap_remove(i).1)
    }

    /// Drops a command nobody waits for any more (its outcome, if any, is discarded).
    pub fn forget(&mut self, id: CommandId) {
        self.pending.retain(|p| p.id != id);
        self.finished.retain(|(f, _)| *f != id);
    }

    /// Ends every pending command: the link is gone and nothing is commanded blind.
    pub fn fail_all(&mut self) {
        for p in self.pending.drain(..) {
            self.finished.push((p.id, CommandOutcome::LinkLost));
        }
    }

    /// Returns the COMMAND_LONGs to send at `now`.
    pub fn poll(&mut self, now: Duration, target_system: u8) -> Vec<COMMAND_LONG_DATA> {
        let mut out = Vec::new();
        let mut finished = Vec::new();
        let mut busy: Vec<MavCmd> = self
            .pending
            .iter()
            .filter(|p| !matches!(p.state, State::Queued))
            .map(|p| p.spec.command)
            .collect();
        for p in &mut self.pending {
            match p.state {
                State::Queued if !busy.contains(&p.spec.command) => {
                    busy.push(p.spec.command);
                    p.first_sent = Some(now);
                    out.push(send(p, now, target_system));
                }
                State::InFlight { sent_at } if now.saturating_sub(sent_at) >= self.timeout => {
                    if p.attempts > self.retries {
                        finished.push((
                            p.id,
                            CommandOutcome::TimedOut {
                                attempts: p.attempts,
                            },
                        ));
                    } else {
                        out.push(send(p, now, target_system));
                    }
                }
                State::Refused { result, at } if now.saturating_sub(at) >= REASON_GRACE => {
                    finished.push((p.id, rejected(result, &p.reasons)));
                }
                _ => {}
            }
        }
        self.finish(finished);
        out
    }

    /// Matches an ack (addressed to us or to everyone) to the command in flight.
    pub fn on_ack(
        &mut self,
        now: Duration,
        ack: &COMMAND_ACK_DATA,
        our_system: u8,
        our_component: u8,
    ) {
        let for_us = (ack.target_system == 0 || ack.target_system == our_system)
            && (ack.target_component == 0 || ack.target_component == our_component);
        if !for_us {
            return;
        }
        let Some(p) = self
            .pending
            .iter_mut()
            .find(|p| p.spec.command == ack.command && matches!(p.state, State::InFlight { .. }))
        else {
            return;
        };
        match ack.result {
            MavResult::MAV_RESULT_ACCEPTED => {
                let id = p.id;
                self.finish(vec![(id, CommandOutcome::Accepted)]);
            }
            // Still working: wait a full timeout again without re-sending.
            MavResult::MAV_RESULT_IN_PROGRESS => p.state = State::InFlight { sent_at: now },
            result => p.state = State::Refused { result, at: now },
        }
    }

    /// Collects problem texts for every command sent before them.
    pub fn on_text(&mut self, text: &AutopilotText) {
        if !text.is_problem() {
            return;
        }
        for p in &mut self.pending {
            let after_send = p.first_sent.is_some_and(|t| text.at >= t);
            if after_send && !p.reasons.contains(&text.text) {
                p.reasons.push(text.text.clone());
            }
        }
    }

    fn finish(&mut self, done: Vec<(CommandId, CommandOutcome)>) {
        for (id, outcome) in done {
            self.pending.retain(|p| p.id != id);
            self.finished.push((id, outcome));
        }
    }
}

fn rejected(result: MavResult, reasons: &[String]) -> CommandOutcome {
    CommandOutcome::Rejected {
        result,
        reason: (!reasons.is_empty()).then(|| reasons.join("; ")),
    }
}

fn send(p: &mut Pending, now: Duration, target_system: u8) -> COMMAND_LONG_DATA {
    let confirmation = p.attempts;
    p.attempts = p.attempts.saturating_add(1);
    p.state = State::InFlight { sent_at: now };
    let [param1, param2, param3, param4, param5, param6, param7] = p.spec.params;
    COMMAND_LONG_DATA {
        param1,
        param2,
        param3,
        param4,
        param5,
        param6,
        param7,
        command: p.spec.command,
        target_system,
        target_component: p.spec.target_component,
        confirmation,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: fn(u64) -> Duration = Duration::from_millis;

    fn arm() -> CommandSpec {
        CommandSpec {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            params: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
            target_component: 1,
        }
    }

    fn ack(result: MavResult) -> COMMAND_ACK_DATA {
        COMMAND_ACK_DATA {
            command: MavCmd::MAV_CMD_COMPONENT_ARM_DISARM,
            result,
            target_system: 1,
            target_component: 191,
            ..COMMAND_ACK_DATA::DEFAULT
        }
    }

    fn text(at: Duration, s: &str) -> AutopilotText {
        AutopilotText {
            at,
            severity: 2,
            text: s.into(),
            event_id: None,
        }
    }

    #[test]
    fn accepted_on_first_ack() {
        let mut t = CommandTracker::new(MS(500), 2);
        let id = t.submit(arm());
        let sent = t.poll(MS(0), 1);
        assert_eq!(sent.len(), 1);
        assert_eq!(sent[0].confirmation, 0);
        assert!(
            t.poll(MS(100), 1).is_empty(),
            "no re-send before the timeout"
        );
        t.on_ack(MS(10), &ack(MavResult::MAV_RESULT_ACCEPTED), 1, 191);
        assert_eq!(t.take_outcome(id), Some(CommandOutcome::Accepted));
        assert_eq!(t.take_outcome(id), None);
    }

    #[test]
    fn retries_with_confirmation_then_times_out() {
        let mut t = CommandTracker::new(MS(500), 2);
        let id = t.submit(arm());
        let confirmations: Vec<u8> = [0, 500, 1000, 1500]
            .into_iter()
            .flat_map(|ms| t.poll(MS(ms), 1))
            .map(|c| c.confirmation)
            .collect();
        assert_eq!(confirmations, vec![0, 1, 2]);
        assert_eq!(
            t.take_outcome(id),
            Some(CommandOutcome::TimedOut { attempts: 3 })
        );
    }

    #[test]
    fn refusal_carries_texts_before_and_after_the_ack() {
        let mut t = CommandTracker::new(MS(500), 2);
        let id = t.submit(arm());
        t.poll(MS(0), 1);
        t.on_text(&text(MS(5), "Arm: Need Position Estimate"));
        t.on_ack(MS(6), &ack(MavResult::MAV_RESULT_FAILED), 1, 191);
        t.on_text(&text(MS(8), "PreArm: GPS not healthy"));
        assert!(t.poll(MS(100), 1).is_empty());
        assert_eq!(t.take_outcome(id), None, "waits for the reason");
        t.poll(MS(400), 1);
        let outcome = t.take_outcome(id).unwrap();
        let msg = outcome.into_result("arming").unwrap_err().to_string();
        assert_eq!(
            msg,
            "arming refused (failed): Arm: Need Position Estimate; PreArm: GPS not healthy"
        );
    }

    #[test]
    fn one_in_flight_per_command_id_and_acks_for_others_ignored() {
        let mut t = CommandTracker::new(MS(500), 2);
        let a = t.submit(arm());
        let b = t.submit(arm());
        assert_eq!(t.poll(MS(0), 1).len(), 1);
        let mut other = ack(MavResult::MAV_RESULT_ACCEPTED);
        other.target_system = 255;
        t.on_ack(MS(1), &other, 1, 191);
        assert!(t.is_pending(a));
        t.on_ack(MS(2), &ack(MavResult::MAV_RESULT_ACCEPTED), 1, 191);
        assert_eq!(t.take_outcome(a), Some(CommandOutcome::Accepted));
        assert_eq!(
            t.poll(MS(3), 1).len(),
            1,
            "the second goes out after the first"
        );
        t.fail_all();
        assert_eq!(t.take_outcome(b), Some(CommandOutcome::LinkLost));
    }

    #[test]
    fn in_progress_extends_without_resending() {
        let mut t = CommandTracker::new(MS(500), 0);
        let id = t.submit(arm());
        t.poll(MS(0), 1);
        t.on_ack(MS(400), &ack(MavResult::MAV_RESULT_IN_PROGRESS), 1, 191);
        assert!(t.poll(MS(600), 1).is_empty());
        assert!(t.is_pending(id));
        t.on_ack(MS(700), &ack(MavResult::MAV_RESULT_ACCEPTED), 1, 191);
        assert_eq!(t.take_outcome(id), Some(CommandOutcome::Accepted));
    }
}
