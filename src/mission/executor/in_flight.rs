//! What a vehicle in the air does when its mission fails (`[mission] on_failure`): `hold` where
//! it is (the default; the behavior server already holds it), `land` where it is, or `rtl`
//! (return to the arming point at `[mission] rtl_height_m` or higher, then land). Every failure
//! that ends a mission in the air is covered (an item, a parallel item, an exploration), with an
//! alert that says what the vehicle does and why. Not subject to it: `pilot_takeover` (someone
//! else flies the vehicle and Kestrel commands nothing) and a lost link or a crash (nothing to
//! command); a vehicle on the ground stays there.
//!
//! In: the failed item and its code, the vehicle's state, on the update after the failure (a
//! refused START changes nothing, so it leaves the vehicle as it was). Out: a behavior started on
//! the core, an alert.

use super::MissionExecutor;
use crate::behavior::FailureCode;
use crate::core::{BehaviorCommand, DroneCore};
use crate::types::LinkHealth;
use serde::{Deserialize, Serialize};

/// `[mission] on_failure`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum InFlightFailure {
    /// Hover where the failure left the vehicle until an operator acts.
    #[default]
    Hold,
    /// Land where it is.
    Land,
    /// Return to the arming point and land there.
    Rtl,
}

/// The item whose failure ended a mission.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct InFlightFailed {
    pub index: usize,
    pub behavior: String,
    pub code: Option<FailureCode>,
}

impl MissionExecutor {
    /// Applies `[mission] on_failure` after an item failed and ended the mission.
    pub(super) fn after_failure(&mut self, core: &mut DroneCore, failed: &InFlightFailed) {
        let (index, behavior, code) = (failed.index, &failed.behavior, failed.code);
        let status = core.platform_status();
        let in_air = status.armed && status.flight.is_airborne() && status.link == LinkHealth::Ok;
        let exempt = matches!(
            code,
            Some(FailureCode::PilotTakeover | FailureCode::LinkLost | FailureCode::Crashed)
        );
        if !in_air || exempt {
            return;
        }
        let why = code.map_or("failed", FailureCode::as_str);
        let (doing, start) = match self.config.on_failure {
            InFlightFailure::Hold => ("holding", None),
            InFlightFailure::Land => ("landing", Some(("land", serde_json::json!({})))),
            InFlightFailure::Rtl => (
                "returning to launch",
                Some((
                    "rtl",
                    serde_json::json!({
                        "height": self.config.rtl_height_m,
                        "speed": self.config.rtl_speed_mps,
                    }),
                )),
            ),
        };
        let drone = core.drone_id().to_string();
        let mut alert = format!("{drone} {doing} after {behavior} #{index} failed: {why}");
        if let Some((name, goal)) = start {
            let command = BehaviorCommand::Start {
                behavior: name.into(),
                goal,
            };
            if let Err(e) = core.command(command) {
                alert = format!("{alert}; {name} refused ({e}): holding");
            }
        }
        tracing::warn!("{alert}");
        self.alerts.push(alert);
    }
}
