//! Autopilot texts: STATUSTEXT lines and PX4 EVENTs, kept as one kind of record.
//!
//! In: STATUSTEXT (ArduPilot's PreArm and mode-change refusals) and EVENT (PX4 reports arming
//! denials and failsafes only this way). Out: [`AutopilotText`] with a MAVLink severity and
//! readable words. PX4 events carry an id into PX4's event metadata; the ids seen in the
//! captures (`../shared/traces/`) are named here, any other id is kept as its number.

use std::time::Duration;

/// MAV_SEVERITY_WARNING: texts at this severity or worse explain a refusal.
pub const SEVERITY_WARNING: u8 = 4;

#[derive(Debug, Clone, PartialEq, Eq)]
pub struct AutopilotText {
    /// When it arrived (platform clock).
    pub at: Duration,
    /// MAV_SEVERITY: 0 emergency .. 7 debug.
    pub severity: u8,
    pub text: String,
    /// The PX4 event id, for EVENTs.
    pub event_id: Option<u32>,
}

impl AutopilotText {
    /// True when this text can explain why a command was refused.
    pub fn is_problem(&self) -> bool {
        self.severity <= SEVERITY_WARNING
    }
}

/// PX4 event ids (common and px4 namespaces) seen in the captures, with their messages.
const PX4_EVENTS: &[(u32, &str)] = &[
    (
        16_910_493,
        "Arming denied: Resolve system health failures first",
    ),
    (19_865_031, "No offboard signal"),
    (18_648_929, "Mode not suitable for arming"),
    (31_382_480, "Failsafe activated"),
    (17_154_777, "No valid mission available"),
    (17_231_145, "No manual control input"),
    (23_579_003, "No connection to the ground control station"),
    (26_266_355, "Armed"),
    (32_794_487, "Disarmed"),
    (21_054_825, "Takeoff detected"),
    (26_622_124, "Landing detected"),
];

/// An EVENT as text. `log_levels`' low nibble is the external log level, which uses the
/// MAV_SEVERITY scale (0 emergency .. 7 debug; 8 and up are protocol-only events).
pub fn px4_event(at: Duration, id: u32, log_levels: u8) -> Option<AutopilotText> {
    let severity = log_levels & 0x0f;
    if severity > 7 {
        return None;
    }
    let text = PX4_EVENTS
        .iter()
        .find(|(known, _)| *known == id)
        .map_or_else(|| format!("PX4 event {id}"), |(_, t)| (*t).to_string());
    Some(AutopilotText {
        at,
        severity,
        text,
        event_id: Some(id),
    })
}

/// A STATUSTEXT line: the text up to the first NUL, invalid UTF-8 replaced.
pub fn status_text(at: Duration, severity: u8, raw: &[u8]) -> AutopilotText {
    let end = raw.iter().position(|b| *b == 0).unwrap_or(raw.len());
    let text = String::from_utf8_lossy(raw.get(..end).unwrap_or_default())
        .trim()
        .to_string();
    AutopilotText {
        at,
        severity,
        text,
        event_id: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn known_px4_events_have_words_and_severity() {
        let t = px4_event(Duration::ZERO, 16_910_493, 0x62).unwrap();
        assert_eq!(
            t.text,
            "Arming denied: Resolve system health failures first"
        );
        assert_eq!(t.severity, 2);
        assert!(t.is_problem());
        let info = px4_event(Duration::ZERO, 21_054_825, 0x66).unwrap();
        assert!(!info.is_problem());
        assert!(px4_event(Duration::ZERO, 27_825_120, 0x88).is_none());
        assert_eq!(
            px4_event(Duration::ZERO, 7, 0x33).unwrap().text,
            "PX4 event 7"
        );
    }

    #[test]
    fn status_text_stops_at_nul() {
        let t = status_text(Duration::ZERO, 2, b"Arm: Need Position Estimate\0\0\0");
        assert_eq!(t.text, "Arm: Need Position Estimate");
    }
}
