//! What a mission does when its vehicle is held for a lost fleet-bus peer (`fleet_peer_lost`):
//! a peer's drone fell silent while flying and is not accounted for (with two Kestrels it never
//! is: one of two is no majority), so the safety stage holds every drone where it is, and the
//! item that could not progress ended with `fleet_peer_lost`. The mission pauses, holding, with
//! the reason as its last error; `[mission] on_failure` does not apply (nothing failed but the
//! bus). When no silent peer is left unaccounted, the mission resumes by itself, the interrupted
//! item starting again from where the vehicle is; RESUME does the same at once, STOP ends the
//! mission, and an operator may land the vehicle meanwhile.
//!
//! In: the item's failure; each update, the fleet view the core last saw. Out: the mission
//! status (paused, `last_error_code` `fleet_peer_lost`), alerts.

use super::MissionExecutor;
use crate::behavior::FailureCode;
use crate::core::DroneCore;

impl MissionExecutor {
    /// The current item ended with `fleet_peer_lost` (`reason`): the mission pauses.
    pub(super) fn peer_lost(&mut self, core: &DroneCore, reason: &str) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        run.paused = true;
        let id = run.mission_id;
        let alert = format!("{} mission {id} paused: {reason}", core.drone_id());
        tracing::warn!("{alert}");
        self.alerts.push(alert);
        self.last_error = Some(reason.to_string());
        self.last_error_code = Some(FailureCode::FleetPeerLost);
        self.touch();
    }

    /// Resumes a mission paused for a lost peer once every silent peer is heard again or
    /// accounted for.
    pub(super) fn follow_fleet(&mut self, core: &DroneCore) {
        if self.last_error_code != Some(FailureCode::FleetPeerLost) {
            return;
        }
        let Some(run) = self.run.as_mut().filter(|r| r.paused) else {
            return;
        };
        let me = core.drone_id();
        if core.fleet_view().others(me).any(|d| d.unaccounted) {
            return;
        }
        run.paused = false;
        let alert = format!(
            "{me} mission {} resumed: the lost fleet peer is back or accounted for",
            run.mission_id
        );
        tracing::info!("{alert}");
        self.alerts.push(alert);
        self.last_error = None;
        self.last_error_code = None;
        self.touch();
    }
}
