//! What a running mission does when the link to the autopilot drops: the item in flight ends
//! (`link_lost`; the autopilot's own failsafe flies the vehicle meanwhile), the mission waits up to
//! `[mission] link_wait_s` for the link, then follows `[mission] on_link_regained`:
//! `resume` starts the interrupted item again, `land` ends the mission and lands, `hold` pauses the
//! mission with the vehicle hovering until RESUME or STOP. A `land` item is finished whatever the
//! policy (it counts as done when the autopilot landed by itself meanwhile, even when the link
//! came back only after `link_wait` had failed the mission); a vehicle that landed during the
//! outage ends the mission. The same rules hold on every platform (simulator, PX4,
//! ArduPilot) and on every path (API, CLI), since this is the one place they live.
//!
//! In: the core's link and arming state each tick. Out: behavior commands, the mission status.

use super::{InFlightFailure, MissionExecutor, Run};
use crate::behavior::FailureCode;
use crate::core::{BehaviorCommand, DroneCore};
use crate::mission::model::ItemResult;
use crate::types::LinkHealth;
use serde::{Deserialize, Serialize};
use std::time::Duration;

/// What the mission does once the link is back (`[mission] on_link_regained`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum LinkRegained {
    /// End the mission and land where the vehicle is.
    #[default]
    Land,
    /// Pause the mission and hover; RESUME goes on with the interrupted item.
    Hold,
    /// Start the interrupted item again and go on.
    Resume,
}

/// The executor's settings.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ExecutorConfig {
    /// How long the vehicle holds between two plans when START switches.
    pub switch_hold: Duration,
    pub on_link_regained: LinkRegained,
    /// How long a mission waits for a lost link before it fails.
    pub link_wait: Duration,
    /// What a vehicle in the air does when its mission fails.
    pub on_failure: InFlightFailure,
    /// `on_failure = "rtl"`: height above home to fly back at (m; never lower than the vehicle is).
    pub rtl_height_m: f64,
    /// `on_failure = "rtl"`: speed to fly back at (m/s).
    pub rtl_speed_mps: f64,
}

impl Default for ExecutorConfig {
    fn default() -> Self {
        Self {
            switch_hold: Duration::from_secs(1),
            on_link_regained: LinkRegained::default(),
            link_wait: Duration::from_secs(30),
            on_failure: InFlightFailure::default(),
            rtl_height_m: 3.0,
            rtl_speed_mps: 1.0,
        }
    }
}

/// An item interrupted by a link loss.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct LinkWait {
    index: usize,
    since: Duration,
}

impl MissionExecutor {
    /// A `land` item failed because the link stayed lost past `link_wait`. Once the link is back
    /// the vehicle says whether it landed meanwhile (the autopilot's own failsafe): if it is on
    /// the ground and disarmed, the item is recorded as succeeded, and when it was the mission's
    /// last the mission completes and its error is cleared. Still flying: the failure stands.
    pub(super) fn confirm_landing(&mut self, core: &DroneCore) {
        let Some((id, index)) = self.unconfirmed_landing else {
            return;
        };
        if self.run.is_some() {
            // Another run started since: that mission's record is no longer this one to amend.
            self.unconfirmed_landing = None;
            return;
        }
        let status = core.platform_status();
        if status.link != LinkHealth::Ok {
            return;
        }
        self.unconfirmed_landing = None;
        if status.armed || status.flight.is_airborne() {
            return;
        }
        let Some(items) = self.missions.get(&id).map(|l| l.mission.items.len()) else {
            return;
        };
        let reason = "the autopilot landed while the link was lost".to_string();
        tracing::info!("mission {id} item {index} (land): {reason}");
        self.record(id, index, ItemResult::Succeeded, Some(reason), None);
        let last = index + 1 >= items;
        self.with_progress(id, |p| {
            p.cursor = index + 1;
            p.finished |= last;
        });
        if last {
            self.last_error = None;
            self.last_error_code = None;
        }
    }

    /// The current item ended because the link was lost: wait for it.
    pub(super) fn wait_for_link(&mut self, index: usize, now: Duration) {
        if let Some(run) = self.run.as_mut() {
            run.link_wait = Some(LinkWait { index, since: now });
        }
        tracing::warn!("link lost during item {index}: waiting for it to come back");
        self.touch();
    }

    /// While waiting for the link: give up after `link_wait`, or act once it is back.
    pub(super) fn follow_link(&mut self, core: &mut DroneCore, now: Duration) {
        let Some(wait) = self.run.as_ref().and_then(|r: &Run| r.link_wait) else {
            return;
        };
        let id = self.running_id().unwrap_or_default();
        let behavior = self
            .missions
            .get(&id)
            .and_then(|l| l.mission.items.get(wait.index))
            .map(|i| i.behavior().to_string())
            .unwrap_or_default();
        let link_back =
            core.platform_status().link == LinkHealth::Ok && core.estimate().valid.position;
        if !link_back {
            if now.saturating_sub(wait.since) > self.config.link_wait {
                let reason = format!(
                    "the link to the autopilot did not come back within {:.0} s",
                    self.config.link_wait.as_secs_f64()
                );
                self.fail(
                    core,
                    wait.index,
                    &behavior,
                    &reason,
                    Some(FailureCode::LinkLost),
                );
                if behavior == "land" {
                    self.unconfirmed_landing = Some((id, wait.index));
                }
            }
            return;
        }
        if let Some(run) = self.run.as_mut() {
            run.link_wait = None;
        }
        self.touch();
        let landing = behavior == "land";
        if !core.platform_status().armed {
            if landing {
                let reason = "the autopilot landed while the link was lost".to_string();
                self.record(id, wait.index, ItemResult::Succeeded, Some(reason), None);
                self.with_progress(id, |p| p.cursor = wait.index + 1);
            } else {
                let reason = "the vehicle landed while the link was lost";
                self.fail(
                    core,
                    wait.index,
                    &behavior,
                    reason,
                    Some(FailureCode::LinkLost),
                );
            }
            return;
        }
        if landing {
            tracing::info!("link back: landing again");
            return;
        }
        match self.config.on_link_regained {
            LinkRegained::Resume => {
                tracing::info!("link back: resuming the mission at item {}", wait.index);
            }
            LinkRegained::Land => {
                let message = format!(
                    "mission {id} ended: link to the autopilot lost during item {} ({behavior}); \
                     landing ([mission] on_link_regained = \"land\")",
                    wait.index
                );
                tracing::warn!("{message}");
                self.end_run(core, "link lost: landing", Some(message));
                self.last_error_code = Some(FailureCode::LinkLost);
                let land = BehaviorCommand::Start {
                    behavior: "land".into(),
                    goal: serde_json::json!({}),
                };
                if let Err(e) = core.command(land) {
                    tracing::error!("link back but landing refused: {e}");
                }
            }
            LinkRegained::Hold => {
                tracing::info!("link back: mission paused at item {}, hovering", wait.index);
                if let Some(run) = self.run.as_mut() {
                    run.paused = true;
                }
                let hover = BehaviorCommand::Start {
                    behavior: "hover".into(),
                    goal: serde_json::json!({}),
                };
                if let Err(e) = core.command(hover) {
                    tracing::error!("link back but hovering refused: {e}");
                }
            }
        }
    }
}
