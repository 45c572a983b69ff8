//! The autopilot's boot clock (`time_boot_ms`), followed robustly enough to detect reboots.
//!
//! In: every `time_boot_ms` from the autopilot with its arrival time. Out: [`BootClock::observe`]
//! says when a reboot is believed. A single value that jumps (a spoofed or corrupted message)
//! is never believed: a new clock must stay self-consistent for [`CONFIRM`] (and at least
//! [`CONFIRM_MESSAGES`] messages) while no message consistent with the old clock arrives. A
//! real reboot satisfies that (the old clock is gone for good, whether or not the link fell
//! silent in between); an injected value interleaved with the live autopilot's never does. A
//! confirmed forward jump is adopted silently (e.g. after a long link silence).

use std::time::Duration;

/// The clock going back by more than this starts a reboot candidate (reordering tolerance).
const BACKSTEP_MS: u32 = 500;
/// Beyond the elapsed arrival time, this much forward drift is still the same clock.
const FORWARD_SLACK_MS: u64 = 2_000;
/// A new clock is believed only after being consistent for this long...
const CONFIRM: Duration = Duration::from_secs(1);
/// ...and over at least this many messages.
const CONFIRM_MESSAGES: u32 = 5;

#[derive(Debug, Clone, Copy)]
struct Track {
    ms: u32,
    at: Duration,
}

impl Track {
    /// Whether `ms` arriving at `now` continues this clock.
    fn continues(&self, ms: u32, now: Duration) -> bool {
        let elapsed_ms = u64::try_from(now.saturating_sub(self.at).as_millis()).unwrap_or(u64::MAX);
        ms.saturating_add(BACKSTEP_MS) >= self.ms
            && u64::from(ms) <= u64::from(self.ms).saturating_add(elapsed_ms + FORWARD_SLACK_MS)
    }
}

#[derive(Debug, Clone, Copy)]
struct Candidate {
    last: Track,
    since: Duration,
    messages: u32,
}

#[derive(Debug, Default)]
pub struct BootClock {
    current: Option<Track>,
    candidate: Option<Candidate>,
}

impl BootClock {
    /// One `time_boot_ms`; true when the autopilot is now believed to have rebooted.
    pub fn observe(&mut self, ms: u32, now: Duration) -> bool {
        let here = Track { ms, at: now };
        let Some(current) = self.current else {
            self.current = Some(here);
            return false;
        };
        if current.continues(ms, now) {
            if ms > current.ms {
                self.current = Some(here);
            }
            self.candidate = None; // the old clock is alive: whatever jumped was not a reboot
            return false;
        }
        let candidate = match self.candidate {
            Some(c) if c.last.continues(ms, now) => Candidate {
                last: if ms > c.last.ms { here } else { c.last },
                since: c.since,
                messages: c.messages + 1,
            },
            _ => Candidate {
                last: here,
                since: now,
                messages: 1,
            },
        };
        if candidate.messages < CONFIRM_MESSAGES || now.saturating_sub(candidate.since) < CONFIRM {
            self.candidate = Some(candidate);
            return false;
        }
        self.candidate = None;
        self.current = Some(candidate.last);
        candidate.last.ms < current.ms
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ms(t: u64) -> Duration {
        Duration::from_millis(t)
    }

    #[test]
    fn a_clock_that_restarts_and_keeps_counting_is_a_reboot() {
        let mut c = BootClock::default();
        for t in 0..20u32 {
            assert!(!c.observe(60_000 + t * 50, ms(u64::from(t) * 50)));
        }
        // Reordered by less than the tolerance: the same clock.
        assert!(!c.observe(60_500, ms(1_000)));
        let reboots: Vec<u32> = (0..40u32)
            .filter(|t| c.observe(300 + t * 50, ms(5_000 + u64::from(*t) * 50)))
            .collect();
        assert_eq!(
            reboots,
            vec![20],
            "believed once, after 1 s of the new clock"
        );
    }

    #[test]
    fn spoofed_jumps_between_live_messages_are_never_a_reboot() {
        let mut c = BootClock::default();
        let mut reboots = 0;
        for t in 0..6_000u32 {
            let now = ms(u64::from(t) * 10);
            let live = 600_000 + t * 10;
            reboots += u32::from(c.observe(live, now));
            // Several spoofed values per live message: back, small, forward, huge.
            for spoof in [live / 2, 100 + (t % 7) * 10, live + 90_000, u32::MAX] {
                reboots += u32::from(c.observe(spoof, now));
            }
        }
        assert_eq!(reboots, 0);
    }

    #[test]
    fn a_forward_jump_after_silence_is_adopted_without_a_reboot() {
        let mut c = BootClock::default();
        assert!(!c.observe(10_000, ms(0)));
        // 30 s of silence; the clock moved on by as much.
        assert!(!c.observe(40_000, ms(30_000)));
        assert!(!c.observe(40_100, ms(30_100)));
        assert!(
            !c.observe(30_000, ms(30_200)),
            "one step back is not believed"
        );
    }
}
