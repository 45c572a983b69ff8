//! How fast the velocity sent to the autopilot may change.
//!
//! In: each velocity setpoint as it is sent (ENU m/s) and when. Out: the same setpoint with its
//! velocity moved from the last one sent by at most `rate × dt`, except that slowing down
//! along the way it was going passes at once (a stop is never held back).
//!
//! Why: Kestrel's trajectory lead and the explorer's short legs can step the command from
//! hover to the speed cap in one tick. PX4's velocity loop answers a step with an overshoot: on
//! PX4 v1.16 SIH the true speed reached 0.83-0.90 m/s after steps to a 0.75 m/s command
//! (BENCHMARKS.md, "Driving PX4"). A ramp is followed without it.

use crate::types::Vec3;
use std::time::Duration;

/// A stream interrupted for longer than this starts again unlimited (s).
const RESTART_AFTER: Duration = Duration::from_millis(250);

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Slew {
    rate_mps2: f64,
    last: Option<(Vec3, Duration)>,
}

impl Slew {
    /// `rate_mps2`: the profile's `[drive] command_slew_mps2`.
    pub fn new(rate_mps2: f64) -> Self {
        Self {
            rate_mps2,
            last: None,
        }
    }

    /// The velocity to send at `now` in place of `want_enu_mps`.
    pub fn limit(&mut self, now: Duration, want_enu_mps: Vec3) -> Vec3 {
        let sent = match self.last {
            Some((last, at)) if now >= at && now - at <= RESTART_AFTER => {
                let max_step = self.rate_mps2 * (now - at).as_secs_f64();
                step_toward(last, want_enu_mps, max_step)
            }
            _ => want_enu_mps,
        };
        self.last = Some((sent, now));
        sent
    }

    /// The stream stopped: the next setpoint starts afresh.
    pub fn reset(&mut self) {
        self.last = None;
    }
}

/// From `last` toward `want`: slowing along `last`'s direction (down to a stop) at once, the
/// rest of the change (speeding up, turning, reversing past zero) by at most `max_step`.
fn step_toward(last: Vec3, want: Vec3, max_step: f64) -> Vec3 {
    let change = want - last;
    let speed = last.norm();
    if speed < 1e-9 {
        return last + change.cap_magnitude(max_step);
    }
    let along = last / speed;
    let slowing = change.dot(&along).clamp(-speed, 0.0);
    let rest = change - along * slowing;
    last + along * slowing + rest.cap_magnitude(max_step)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(v: u64) -> Duration {
        Duration::from_millis(v)
    }

    #[test]
    fn a_step_to_the_cap_becomes_a_ramp() {
        let mut s = Slew::new(2.0);
        assert_eq!(s.limit(ms(0), Vec3::zeros()), Vec3::zeros());
        let want = Vec3::new(0.75, 0.0, 0.0);
        let sent: Vec<f64> = (1..=25).map(|k| s.limit(ms(20 * k), want).x).collect();
        // 2 m/s^2 at 50 Hz: 0.04 m/s a step, at the cap after 19 steps.
        assert!((sent[0] - 0.04).abs() < 1e-9, "{sent:?}");
        assert!((sent[9] - 0.40).abs() < 1e-9, "{sent:?}");
        assert!((sent[24] - 0.75).abs() < 1e-9, "{sent:?}");
    }

    #[test]
    fn a_stop_passes_at_once_and_a_reversal_only_down_to_zero() {
        let mut s = Slew::new(2.0);
        s.limit(ms(0), Vec3::new(0.7, 0.0, 0.0));
        assert_eq!(s.limit(ms(20), Vec3::new(0.2, 0.0, 0.0)).x, 0.2);
        assert_eq!(s.limit(ms(40), Vec3::zeros()), Vec3::zeros());
        s.limit(ms(60), Vec3::new(0.04, 0.0, 0.0));
        // Reversing: down to zero at once, then 0.04 m/s a step the other way.
        let r = s.limit(ms(80), Vec3::new(-0.7, 0.0, 0.0));
        assert!((r.x + 0.04).abs() < 1e-9, "{r:?}");
    }

    #[test]
    fn a_turn_is_limited_but_the_slowing_part_of_it_is_not() {
        let mut s = Slew::new(2.0);
        s.limit(ms(0), Vec3::new(0.7, 0.0, 0.0));
        let turned = s.limit(ms(20), Vec3::new(0.0, 0.7, 0.0));
        assert!(
            turned.x.abs() < 1e-9,
            "east speed dropped at once: {turned:?}"
        );
        assert!(
            (turned.y - 0.04).abs() < 1e-9,
            "north speed ramps: {turned:?}"
        );
    }

    #[test]
    fn after_a_gap_the_stream_starts_afresh() {
        let mut s = Slew::new(2.0);
        s.limit(ms(0), Vec3::zeros());
        let want = Vec3::new(0.5, 0.0, 0.0);
        assert_eq!(s.limit(ms(500), want), want);
        s.reset();
        assert_eq!(s.limit(ms(520), -want), -want);
    }
}
