//! Sweeping a long frontier end to end: which end to enter, which way to turn, and the path
//! along it.
//!
//! In: the navigable [`Space`], the asking drone's [`Reach`], a [`Frontier`] and the drone's
//! current goal. Out: the entry and exit cells with the turn ([`ends`]) and the path that flies
//! them ([`path`]). The allocator service gives a frontier of [`SWEEP_MIN_M`] or more as a sweep
//! when the drone asks with `sweep_along`.

use nalgebra::Vector2;

use super::reach::Reach;
use super::space::{Frontier, Space};

/// Frontiers at least this long are swept end to end when asked (m).
pub const SWEEP_MIN_M: f64 = 2.0;
/// A frontier end this close to the drone's current goal is still that goal (m).
const SWEEP_KEEP_M: f64 = 1.0;

/// Where a sweep enters and leaves its frontier (cell indices) and which way the drone turns.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Ends {
    pub entry: usize,
    pub exit: usize,
    pub clockwise: bool,
}

/// How to sweep `frontier`: from the end nearer by path to the other, turning so that the
/// unknown lies on the side the turning beams sweep best: on the right of the travel when
/// turning counter-clockwise, on the left when turning clockwise. An end at the drone's
/// `current` goal stays the exit, so a sweep is not turned back.
pub fn ends(
    space: &Space,
    reach: &Reach,
    frontier: &Frontier,
    current: Option<Vector2<f64>>,
) -> Ends {
    let [a, b] = frontier.end_indices;
    let at = |i: usize| space.center_of(i).unwrap_or(frontier.goal_enu_m);
    let far = |i: usize| reach.distance_m(i).unwrap_or(f64::INFINITY);
    let unknown_on_left = |from: usize, to: usize| {
        let along = at(to) - at(from);
        space
            .unknown_side(frontier)
            .is_some_and(|u| along.x * u.y - along.y * u.x > 0.0)
    };
    let bound = |i: usize| current.is_some_and(|g| (at(i) - g).norm() < SWEEP_KEEP_M);
    let (entry, exit) = if bound(b) || (!bound(a) && far(a) <= far(b)) {
        (a, b)
    } else {
        (b, a)
    };
    Ends {
        entry,
        exit,
        clockwise: unknown_on_left(entry, exit),
    }
}

/// The path that sweeps `frontier` from its entry to its exit: to the entry, then along
/// through the frontier's middle (straight where that is navigable, else the shortest path to
/// the exit). A drone already bound for the exit flies straight on to it, so a sweep is not
/// turned back. `None` when the exit cannot be reached.
pub fn path(
    space: &Space,
    reach: &Reach,
    frontier: &Frontier,
    ends: Ends,
    current: Option<Vector2<f64>>,
) -> Option<Vec<Vector2<f64>>> {
    let Ends { entry, exit, .. } = ends;
    let at = |i: usize| space.center_of(i).unwrap_or(frontier.goal_enu_m);
    let direct = || reach.path_to(space, exit);
    if current.is_some_and(|g| (at(exit) - g).norm() < SWEEP_KEEP_M) {
        return direct();
    }
    let mid = frontier.goal_index;
    match reach.path_to(space, entry) {
        Some(mut path)
            if reach.line_clear(space, entry, mid) && reach.line_clear(space, mid, exit) =>
        {
            path.push(at(mid));
            path.push(at(exit));
            Some(path)
        }
        _ => direct(),
    }
}
