//! The drone watcher: the thesis's intra-swarm avoidance, decided from the fleet view.
//!
//! In: this drone and the other flying drones (position, how far each still has to go, whether
//! it is already out of the way above). Out: whether this drone must give way now, and whether
//! it may come back. Two drones closer than `trigger_m` horizontally at the same height: the one
//! nearer its goal (an idle one counts as at its goal; ties go to the larger id) gives way,
//! climbing `climb_m` and holding there until every other drone is farther than `release_m`
//! (the thesis: 2.0 m, 1.0 m, 2.4 m). Drones whose estimates drift measure both distances from
//! the least they may truly be apart (each one's uncertainty off). Both sides decide from the
//! same view, so exactly one of them yields.

/// One drone as the watcher sees it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Watched<'a> {
    pub id: &'a str,
    pub position_enu_m: [f64; 3],
    /// Distance left to its goal (m); 0 when it has none.
    pub remaining_m: f64,
    /// Out of the way above the exploration height (giving way itself).
    pub up: bool,
    /// How far its position may be off horizontally (m, a drifting estimate's uncertainty).
    pub uncertainty_m: f64,
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WatchParams {
    pub trigger_m: f64,
    pub release_m: f64,
    pub climb_m: f64,
}

impl WatchParams {
    /// The thesis's distances for a trigger distance (release 1.2 times it, climb 1 m).
    pub fn thesis(trigger_m: f64) -> Self {
        WatchParams {
            trigger_m,
            release_m: 1.2 * trigger_m,
            climb_m: 1.0,
        }
    }
}

/// The least horizontal distance `a` and `b` may truly be apart (m, may be negative).
fn horizontal(a: &Watched, b: &Watched) -> f64 {
    let (p, q) = (&a.position_enu_m, &b.position_enu_m);
    (p[0] - q[0]).hypot(p[1] - q[1]) - a.uncertainty_m.max(0.0) - b.uncertainty_m.max(0.0)
}

/// Whether `me`, flying at `my_height_m`, must give way to one of `others` now.
pub fn must_yield(me: &Watched, my_height_m: f64, others: &[Watched], p: &WatchParams) -> bool {
    others.iter().any(|o| {
        let level = (o.position_enu_m[2] - my_height_m).abs() < 0.5 * p.climb_m;
        level
            && horizontal(me, o) < p.trigger_m
            && (me.remaining_m < o.remaining_m || (me.remaining_m == o.remaining_m && me.id > o.id))
    })
}

/// Whether a drone that gave way may come back down: every other drone is beyond the release
/// distance, or gave way too and has the larger id (two drones that both climbed, each seeing the
/// other one tick late, do not wait for each other for ever: the smaller id goes back).
pub fn may_return(me: &Watched, others: &[Watched], p: &WatchParams) -> bool {
    others
        .iter()
        .all(|o| horizontal(me, o) > p.release_m || (o.up && o.id > me.id))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn w(id: &str, x: f64, z: f64, remaining_m: f64) -> Watched<'_> {
        Watched {
            id,
            position_enu_m: [x, 0.0, z],
            remaining_m,
            up: z > 1.5,
            uncertainty_m: 0.0,
        }
    }

    #[test]
    fn of_two_close_drones_exactly_the_one_nearer_its_goal_gives_way() {
        let p = WatchParams::thesis(2.0);
        let a = w("a", 0.0, 1.0, 3.0);
        let b = w("b", 1.5, 1.0, 8.0);
        assert!(must_yield(&a, 1.0, &[b], &p));
        assert!(!must_yield(&b, 1.0, &[a], &p));
        // Equal: the larger id yields.
        let b_eq = w("b", 1.5, 1.0, 3.0);
        assert!(!must_yield(&a, 1.0, &[b_eq], &p));
        assert!(must_yield(&b_eq, 1.0, &[a], &p));
    }

    #[test]
    fn far_or_already_climbed_drones_are_no_reason_to_yield() {
        let p = WatchParams::thesis(2.0);
        let a = w("a", 0.0, 1.0, 0.0);
        assert!(!must_yield(&a, 1.0, &[w("b", 2.5, 1.0, 9.0)], &p));
        assert!(
            !must_yield(&a, 1.0, &[w("b", 1.0, 2.0, 9.0)], &p),
            "b is above"
        );
    }

    #[test]
    fn a_drone_comes_back_only_beyond_the_release_distance() {
        let p = WatchParams::thesis(2.0);
        let a = w("a", 0.0, 2.0, 0.0);
        assert!(!may_return(&a, &[w("b", 2.2, 1.0, 5.0)], &p));
        assert!(may_return(&a, &[w("b", 2.5, 1.0, 5.0)], &p));
    }

    #[test]
    fn of_two_drones_that_both_gave_way_the_smaller_id_comes_back_first() {
        let p = WatchParams::thesis(2.0);
        let (a, b) = (w("a", 0.0, 2.0, 0.0), w("b", 1.8, 2.0, 0.0));
        assert!(may_return(&a, &[b], &p));
        assert!(!may_return(&b, &[a], &p));
        // Once `a` is back down, `b` waits for it to leave.
        assert!(!may_return(&b, &[w("a", 0.0, 1.0, 3.0)], &p));
    }

    #[test]
    fn drifting_estimates_give_way_and_hold_as_far_out_as_they_may_be_off() {
        let p = WatchParams::thesis(2.0);
        let drifting = |id, x, z, remaining_m| Watched {
            uncertainty_m: 0.6,
            ..w(id, x, z, remaining_m)
        };
        // 3 m apart by their estimates, at most 1.8 m truly: the one nearer its goal climbs.
        let (a, b) = (drifting("a", 0.0, 1.0, 3.0), drifting("b", 3.0, 1.0, 8.0));
        assert!(must_yield(&a, 1.0, &[b], &p));
        assert!(!must_yield(&b, 1.0, &[a], &p));
        assert!(
            !must_yield(&a, 1.0, &[w("b", 3.0, 1.0, 8.0)], &p),
            "b holds its place"
        );
        // Up, it comes back beyond 2.4 m plus both uncertainties only.
        let up = drifting("a", 0.0, 2.0, 3.0);
        assert!(!may_return(&up, &[drifting("b", 3.5, 1.0, 8.0)], &p));
        assert!(may_return(&up, &[drifting("b", 3.7, 1.0, 8.0)], &p));
    }
}
