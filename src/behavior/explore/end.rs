//! The explorer's end rule: whether an answer `Done` from the allocator ends the exploration
//! for this drone.
//!
//! In: what the answer says is left ([`Left`]) and what the drone has done so far
//! ([`EndFacts`]). Out: over or not. Nothing left anywhere after a full sweep, or, after a
//! flight (it turns all the time), only frontiers it can reach but that are not worth the trip:
//! over. Before its first flight (space may open up as it turns), with frontiers that others
//! hold, or with frontiers it has no path to from here (boxed in by unknown space that sensing
//! may open): a quarter turn, and long enough for the claims of a drone that failed to lapse,
//! so its part is taken.

use crate::exploration::online::service::CLAIM_TTL;

/// With frontiers left that others hold, a drone waits this long past the claims' lifetime
/// before it ends (s): a failed drone's claims lapse and its frontiers are offered first.
const CLAIM_LAPSE_EXTRA_S: f64 = 2.0;

/// What an answer `Done` says is left.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct Left {
    /// Frontiers left that keep the exploration going.
    pub frontiers: usize,
    /// How many of them other drones hold.
    pub held: usize,
    /// How many of them this drone has no path to from where it is.
    pub unreached: usize,
}

/// What the drone has done when the answer comes (seconds of simulated or real time).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct EndFacts {
    /// Since exploring started (after the takeoff).
    pub exploring_s: f64,
    /// Since the first of the answers `Done` in a row.
    pub done_for_s: f64,
    /// Since the drone came within a metre of where it is.
    pub here_s: f64,
    /// One sweep all around (a quarter turn for four beams).
    pub sense_s: f64,
    /// It has flown to a frontier, so its beams swept all around on the way. A goal where it
    /// already hovers (given while the space round its start is still opening up) is no
    /// flight: a metre or more of track is.
    pub flown: bool,
}

/// Whether the exploration is over for this drone.
pub(super) fn over(left: Left, facts: &EndFacts) -> bool {
    let swept = facts.exploring_s >= facts.sense_s;
    let wait_s = facts
        .sense_s
        .max(CLAIM_TTL.as_secs_f64() + CLAIM_LAPSE_EXTRA_S);
    // Within a metre of here for a quarter turn: its beams swept all around from here, so what
    // it has no path to stays that way (while no one else explores).
    let stayed = facts.here_s >= facts.sense_s;
    (swept
        && (left.frontiers == 0
            || (left.held == 0 && facts.flown && (left.unreached == 0 || stayed))))
        || facts.done_for_s >= wait_s
}

#[cfg(test)]
mod tests {
    use super::*;

    fn left(frontiers: usize, held: usize, unreached: usize) -> Left {
        Left {
            frontiers,
            held,
            unreached,
        }
    }

    /// After a full sweep, a flight, just arrived here; the first `Done`.
    fn facts() -> EndFacts {
        EndFacts {
            exploring_s: 60.0,
            done_for_s: 0.0,
            here_s: 1.0,
            sense_s: 10.5,
            flown: true,
        }
    }

    #[test]
    fn nothing_left_after_a_sweep_is_over_and_before_it_is_not() {
        assert!(over(left(0, 0, 0), &facts()));
        let early = EndFacts {
            exploring_s: 5.0,
            ..facts()
        };
        assert!(!over(left(0, 0, 0), &early));
    }

    #[test]
    fn frontiers_others_hold_or_out_of_reach_wait_for_the_claims_to_lapse() {
        assert!(!over(left(3, 1, 0), &facts()));
        assert!(!over(left(3, 0, 2), &facts()));
        let stayed = EndFacts {
            here_s: 11.0,
            ..facts()
        };
        assert!(over(left(3, 0, 2), &stayed), "swept all around from here");
        // The wait: the claims' lifetime and 2 s, or a sweep if that is longer.
        let waited = EndFacts {
            done_for_s: 8.0,
            sense_s: 3.0,
            ..facts()
        };
        assert!(over(left(3, 1, 0), &waited));
        let short = EndFacts {
            done_for_s: 7.9,
            ..waited
        };
        assert!(!over(left(3, 1, 0), &short));
        let slow_turn = EndFacts {
            done_for_s: 10.0,
            ..facts()
        };
        assert!(!over(left(3, 1, 0), &slow_turn));
    }

    #[test]
    fn frontiers_not_worth_the_trip_end_it_only_after_a_flight() {
        assert!(over(left(3, 0, 0), &facts()));
        let unflown = EndFacts {
            flown: false,
            ..facts()
        };
        assert!(!over(left(3, 0, 0), &unflown));
    }
}
