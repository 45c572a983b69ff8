//! What the core asks of the vehicle (arm, offboard, takeoff, land, the gimbal...) as actions
//! in progress, and their outcomes.
//!
//! In: [`PlatformRequest`]s from the control tick, the housekeeping tick. Out: actions started
//! (planned for the profile), superseded or cancelled, and one [`RequestResult`] per request
//! for the core.

use super::Session;
use crate::platform::mavlink::actions::{self, Action, Ctx, Origin};
use crate::platform::{PlatformRequest, RequestRefused, RequestResult};
use crate::types::LinkHealth;
use std::mem::discriminant;
use std::time::Duration;

impl Session {
    /// Starts what the core asks of the vehicle, unless it is done already or in progress;
    /// a landing or disarm supersedes an arm, offboard or takeoff in progress, and the reverse.
    pub(super) fn request(&mut self, now: Duration, request: PlatformRequest) {
        if request == PlatformRequest::LandOnSetpoints {
            self.landing_on_setpoints_at = Some(now);
            return;
        }
        if let Some(mode) = actions::mode_of(request, &self.profile) {
            self.watch.commanded(mode);
        }
        match request {
            PlatformRequest::Arm => self.watch.arming_requested(true),
            PlatformRequest::Disarm => self.watch.arming_requested(false),
            _ => {}
        }
        let done = match request {
            PlatformRequest::Arm => self.model.armed(),
            PlatformRequest::Disarm => !self.model.armed(),
            PlatformRequest::StartOffboard => self.model.offboard(),
            _ => false,
        };
        let same = |a: &Action| {
            a.request()
                .is_some_and(|r| discriminant(&r) == discriminant(&request))
        };
        if self.actions.iter().any(same) {
            if !matches!(request, PlatformRequest::PointGimbal { .. }) {
                return; // already in progress (behaviors repeat their requests)
            }
            self.cancel(same, "replaced by a newer gimbal request");
        }
        if done {
            self.results.push(RequestResult {
                request,
                outcome: Ok(()),
            });
            return;
        }
        match request {
            PlatformRequest::Land | PlatformRequest::Disarm => self.cancel(
                |a| {
                    matches!(
                        a.request(),
                        Some(
                            PlatformRequest::Arm
                                | PlatformRequest::StartOffboard
                                | PlatformRequest::Takeoff { .. }
                        )
                    )
                },
                "superseded by a landing or disarm request",
            ),
            PlatformRequest::Arm => self.cancel(
                |a| a.request() == Some(PlatformRequest::Disarm),
                "superseded by an arm request",
            ),
            _ => {}
        }
        if self.model.link(now) != LinkHealth::Ok {
            self.finish(
                Origin::Request(request),
                Err(RequestRefused::from("no link to the autopilot")),
            );
            return;
        }
        match Action::plan(
            Origin::Request(request),
            request,
            &self.profile,
            &self.model,
        ) {
            Ok(a) => self.actions.push(a),
            Err(e) => self.finish(Origin::Request(request), Err(e)),
        }
    }

    pub(super) fn cancel(&mut self, which: impl Fn(&Action) -> bool, why: &str) {
        let (cancelled, kept): (Vec<_>, Vec<_>) = self.actions.drain(..).partition(|a| which(a));
        self.actions = kept;
        for a in cancelled {
            a.abandon(&mut self.tracker);
            self.finish(a.origin, Err(RequestRefused::from(why)));
        }
    }

    pub(super) fn fail_all(&mut self, why: &str) {
        self.tracker.fail_all();
        self.cancel(|_| true, why);
        self.stream_setup.clear();
    }

    /// Reports a request's outcome to the core; a failure is also the vehicle's last error.
    pub(super) fn finish(&mut self, origin: Origin, outcome: Result<(), RequestRefused>) {
        if let Err(e) = &outcome {
            tracing::debug!(target: "mavlink", "{origin:?}: {e}");
            self.model.set_error(e.to_string());
        }
        let Origin::Request(request) = origin;
        self.results.push(RequestResult { request, outcome });
    }

    /// Steps every action in progress; reports those that ended.
    pub(super) fn run_actions(&mut self, now: Duration) {
        let mut finished = Vec::new();
        let mut ctx = Ctx {
            now,
            profile: &self.profile,
            model: &self.model,
            tracker: &mut self.tracker,
            streamer: &self.streamer,
        };
        self.actions.retain_mut(|a| match a.tick(&mut ctx) {
            Some(outcome) => {
                finished.push((a.origin, outcome));
                false
            }
            None => true,
        });
        for (origin, outcome) in finished {
            self.finish(origin, outcome);
        }
    }
}
