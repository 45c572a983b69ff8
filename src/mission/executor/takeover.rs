//! What a mission does when someone takes the vehicle from Kestrel (`pilot_takeover`: a pilot's
//! mode switch, a ground station's mode change or land command, a disarm in the air): it pauses
//! at once, whatever it was doing (an item, a link wait, a plan switch), with the reason as its
//! last error. The core has already ended every behavior and commands nothing, and nothing here
//! starts one: the mode stays the pilot's. RESUME starts the interrupted item again from where
//! the vehicle is (its behavior asks for offboard/GUIDED again); STOP ends the mission and leaves
//! the vehicle with the pilot (no landing, no mode change). `[mission] on_failure` does not
//! apply.
//!
//! In: the takeover's reason from the core's tick. Out: the mission status.

use super::MissionExecutor;
use crate::behavior::FailureCode;

impl MissionExecutor {
    /// The vehicle was taken from Kestrel (`reason`, e.g. `pilot took over (mode AUTO.LOITER)`):
    /// the running mission pauses.
    pub fn pilot_took_over(&mut self, reason: &str) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        run.paused = true;
        run.link_wait = None;
        let id = run.mission_id;
        tracing::warn!(
            "mission {id} paused: {reason}; RESUME takes the vehicle back, STOP leaves it with \
             the pilot"
        );
        self.last_error = Some(reason.to_string());
        self.last_error_code = Some(FailureCode::PilotTakeover);
        self.touch();
    }

    /// RESUME after a takeover (or a pause for a lost fleet peer): the mission is Kestrel's
    /// again, its error no longer current.
    pub(super) fn clear_takeover(&mut self) {
        if matches!(
            self.last_error_code,
            Some(FailureCode::PilotTakeover | FailureCode::FleetPeerLost)
        ) {
            self.last_error = None;
            self.last_error_code = None;
        }
    }
}
