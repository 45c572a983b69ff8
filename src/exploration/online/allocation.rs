//! Which frontier a drone explores next: the thesis's heuristic, its two ablations and
//! Kestrel's default.
//!
//! In: the requesting drone, the frontiers it can reach (with their path distances) and the
//! goals the other drones hold. Out: the index of the chosen frontier (`None`: no candidate).
//!
//! Each allocator is an [`Allocator`] (its score of a frontier, higher is better); [`choose`]
//! does what they share: it first leaves out frontiers another drone already holds (centroid
//! within [`CLAIM_RADIUS_M`] of its goal) unless nothing else is left, so two drones never fly
//! to the same place.
//! - `thesis` (Eq. 4.3 as the thesis's code computes it): the largest mean straight-line distance
//!   from the frontier to the goals already allocated (the drone's previous goal included) minus
//!   twice the straight-line distance from the drone.
//! - `nearest`: the nearest frontier in a straight line (Figure 6.1's "closer").
//! - `farthest`: the frontier farthest on average from the allocated goals (Figure 6.1's "max
//!   distance").
//! - `kestrel` (the default): the shortest *flown* distance (path length through known free
//!   space, not a straight line through poles and unknown space), less a bonus for long frontiers
//!   (more to see), plus a penalty for frontiers within two beam ranges of another drone's goal
//!   (that drone will see them) and one for each metre by which another drone, going on from its
//!   goal, would be there first (it takes that frontier next; this drone goes where no one else
//!   is near, so the fleet spreads over the last, scattered frontiers instead of queueing at
//!   one), with a hysteresis that keeps the current goal unless another is clearly better (no
//!   dithering between two equal frontiers), and a bonus for frontiers near the map's edge: the
//!   unknown strip between such a frontier and the edge is a dead end, cleared now from nearby
//!   or later by a trip back that often made the end of a run (the last drone flying 20-50 m to
//!   a strip along the edge the fleet had passed, and exploring it alone).
//!   Its weights are the [`ExplorationSettings`] (config `[exploration]`, the `explore` goal's
//!   `settings`).

use nalgebra::Vector2;
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

use super::settings::ExplorationSettings;

/// Frontiers this close to another drone's goal are that drone's (m).
pub const CLAIM_RADIUS_M: f64 = 0.5;

/// The allocator, selectable per run (`--allocator`, the `explore` behavior's `allocator`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize, JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum AllocatorKind {
    #[default]
    Kestrel,
    Thesis,
    Nearest,
    Farthest,
}

/// A name that is no allocator.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("unknown allocator `{0}`: use kestrel, thesis, nearest or farthest")]
pub struct UnknownAllocator(pub String);

impl std::str::FromStr for AllocatorKind {
    type Err = UnknownAllocator;
    fn from_str(s: &str) -> Result<Self, UnknownAllocator> {
        match s {
            "kestrel" => Ok(Self::Kestrel),
            "thesis" => Ok(Self::Thesis),
            "nearest" => Ok(Self::Nearest),
            "farthest" => Ok(Self::Farthest),
            other => Err(UnknownAllocator(other.to_string())),
        }
    }
}

impl AllocatorKind {
    /// The allocator of this kind; `kestrel` weighs with `settings`, the others ignore them.
    pub fn allocator(self, settings: &ExplorationSettings) -> Box<dyn Allocator> {
        match self {
            Self::Kestrel => Box::new(Kestrel(*settings)),
            Self::Thesis => Box::new(Thesis),
            Self::Nearest => Box::new(Nearest),
            Self::Farthest => Box::new(Farthest),
        }
    }
}

/// A frontier the drone can reach.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    pub centroid_enu_m: Vector2<f64>,
    pub goal_enu_m: Vector2<f64>,
    /// Frontier length (m).
    pub size_m: f64,
    /// Flown distance from the drone to the goal (m).
    pub path_m: f64,
    /// Straight-line distance from the centroid to the nearest edge of the map (m).
    pub edge_m: f64,
}

/// The drone asking.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Requester {
    pub position_enu_m: Vector2<f64>,
    /// The goal it flies to now, if any.
    pub current_goal_enu_m: Option<Vector2<f64>>,
}

/// A goal another drone holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Held {
    pub goal_enu_m: Vector2<f64>,
    /// How far its drone was from it when it last asked (m, straight); `None` when unknown (a
    /// drone of another Kestrel: its claim does not carry its position).
    pub remaining_m: Option<f64>,
}

impl Held {
    /// A goal held by a drone whose position is not known.
    pub fn at(goal_enu_m: Vector2<f64>) -> Self {
        Self {
            goal_enu_m,
            remaining_m: None,
        }
    }

    /// How far its drone flies to `point` going on from its goal (at least; m), if known.
    fn reach_m(&self, point: Vector2<f64>) -> Option<f64> {
        self.remaining_m
            .map(|r| r + (point - self.goal_enu_m).norm())
    }
}

/// One question as every allocator sees it: the drone asking, the goals the other drones
/// hold, and the goals allocated so far (the others' and the asker's own current one).
pub struct Question<'a> {
    pub me: &'a Requester,
    pub held: &'a [Held],
    pub allocated: Vec<Vector2<f64>>,
}

impl<'a> Question<'a> {
    pub fn new(me: &'a Requester, held: &'a [Held]) -> Self {
        let allocated = held
            .iter()
            .map(|h| h.goal_enu_m)
            .chain(me.current_goal_enu_m)
            .collect();
        Self {
            me,
            held,
            allocated,
        }
    }

    /// Straight-line distance from the asker to the frontier (m).
    fn straight_m(&self, c: &Candidate) -> f64 {
        (c.centroid_enu_m - self.me.position_enu_m).norm()
    }

    /// Mean straight-line distance from the frontier to the allocated goals, the sum divided
    /// by `divisor` (at least 1).
    fn mean_to_allocated_m(&self, c: &Candidate, divisor: usize) -> f64 {
        self.allocated
            .iter()
            .map(|g| (c.centroid_enu_m - g).norm())
            .sum::<f64>()
            / divisor.max(1) as f64
    }
}

/// One allocator: how good a frontier is for the drone asking.
///
/// Contract: `score` is pure (no clock, no I/O, nothing kept between questions) and ranks any
/// candidate: higher is better, and there is no "not applicable". What all allocators share is
/// [`choose`]'s: frontiers another drone holds are left out unless nothing else is left, and a
/// tie goes to the earlier candidate.
pub trait Allocator {
    fn score(&self, candidate: &Candidate, question: &Question) -> f64;
}

/// The nearest frontier in a straight line (Figure 6.1's "closer").
pub struct Nearest;

impl Allocator for Nearest {
    fn score(&self, c: &Candidate, q: &Question) -> f64 {
        -q.straight_m(c)
    }
}

/// Eq. 4.3 as the thesis's code computes it: the mean distance to the allocated goals minus
/// twice the distance from the drone; the nearest while nothing is allocated.
pub struct Thesis;

impl Allocator for Thesis {
    fn score(&self, c: &Candidate, q: &Question) -> f64 {
        let n = q.allocated.len();
        if n == 0 {
            return -q.straight_m(c);
        }
        // The code divides by |allocated| - 1 once more than one goal is allocated.
        let divisor = if n > 1 { n - 1 } else { n };
        q.mean_to_allocated_m(c, divisor) - 2.0 * q.straight_m(c)
    }
}

/// The frontier farthest on average from the allocated goals (Figure 6.1's "max distance");
/// the nearest while nothing is allocated.
pub struct Farthest;

impl Allocator for Farthest {
    fn score(&self, c: &Candidate, q: &Question) -> f64 {
        if q.allocated.is_empty() {
            return -q.straight_m(c);
        }
        q.mean_to_allocated_m(c, q.allocated.len())
    }
}

/// Kestrel's default: the flown distance with the bonuses and penalties of the module's doc,
/// weighed by its settings.
pub struct Kestrel(pub ExplorationSettings);

impl Allocator for Kestrel {
    fn score(&self, c: &Candidate, q: &Question) -> f64 {
        let s = &self.0;
        let bonus = s.size_bonus_per_m * c.size_m.min(s.size_bonus_cap_m);
        let crowd: f64 = q
            .held
            .iter()
            .map(|h| {
                s.others_penalty_m
                    * (1.0 - (c.centroid_enu_m - h.goal_enu_m).norm() / s.others_radius_m).max(0.0)
            })
            .sum();
        let keep =
            q.me.current_goal_enu_m
                .filter(|g| (c.goal_enu_m - g).norm() < s.keep_radius_m)
                .map_or(0.0, |_| s.keep_bonus_m);
        let first_m = q
            .held
            .iter()
            .filter_map(|h| h.reach_m(c.centroid_enu_m))
            .fold(f64::INFINITY, f64::min);
        let behind = s.behind_penalty_per_m * (c.path_m - first_m).max(0.0);
        let edge = s.edge_bonus_m * (1.0 - c.edge_m / s.edge_radius_m).max(0.0);
        -(c.path_m - bonus + crowd + behind - keep - edge)
    }
}

/// Picks a frontier for `me` among `candidates` with `allocator`, given the goals `held` by
/// the other drones.
pub fn choose(
    allocator: &dyn Allocator,
    me: &Requester,
    candidates: &[Candidate],
    held: &[Held],
) -> Option<usize> {
    let unclaimed: Vec<usize> = (0..candidates.len())
        .filter(|&i| {
            held.iter()
                .all(|h| (candidates[i].centroid_enu_m - h.goal_enu_m).norm() > CLAIM_RADIUS_M)
        })
        .collect();
    let pool = if unclaimed.is_empty() {
        (0..candidates.len()).collect()
    } else {
        unclaimed
    };
    let question = Question::new(me, held);
    let score = |i: usize| allocator.score(&candidates[i], &question);
    pool.into_iter().max_by(|&a, &b| {
        score(a)
            .total_cmp(&score(b))
            // Ties: the earlier candidate (raster order), deterministically.
            .then(b.cmp(&a))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn by(kind: AllocatorKind) -> Box<dyn Allocator> {
        kind.allocator(&ExplorationSettings::default())
    }

    fn at(x: f64, y: f64, path_m: f64, size_m: f64) -> Candidate {
        Candidate {
            centroid_enu_m: Vector2::new(x, y),
            goal_enu_m: Vector2::new(x, y),
            size_m,
            path_m,
            edge_m: f64::INFINITY,
        }
    }

    fn me(x: f64, y: f64) -> Requester {
        Requester {
            position_enu_m: Vector2::new(x, y),
            current_goal_enu_m: None,
        }
    }

    #[test]
    fn nearest_takes_the_straight_line_nearest() {
        let c = [at(5.0, 0.0, 5.0, 2.0), at(0.0, 3.0, 30.0, 2.0)];
        assert_eq!(
            choose(&*by(AllocatorKind::Nearest), &me(0.0, 0.0), &c, &[]),
            Some(1)
        );
    }

    #[test]
    fn kestrel_takes_the_shortest_flight_not_the_shortest_line() {
        // The frontier 3 m away lies behind a wall (30 m to fly); the one 5 m away is open.
        let c = [at(5.0, 0.0, 5.0, 2.0), at(0.0, 3.0, 30.0, 2.0)];
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[]),
            Some(0)
        );
    }

    #[test]
    fn kestrel_leaves_frontiers_near_another_drones_goal_to_it() {
        let c = [at(5.0, 0.0, 5.0, 2.0), at(-7.0, 0.0, 7.0, 2.0)];
        let other_goal = [Held::at(Vector2::new(6.0, 1.0))];
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &other_goal),
            Some(1)
        );
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[]),
            Some(0)
        );
    }

    #[test]
    fn kestrel_clears_a_strip_along_the_map_edge_before_going_on_inward() {
        // A is 5 m away in the middle of the map; B, 9 m away, is 1 m from the map's edge.
        let mut c = [at(5.0, 0.0, 5.0, 2.0), at(0.0, 9.0, 9.0, 2.0)];
        c[0].edge_m = 20.0;
        c[1].edge_m = 1.0;
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[]),
            Some(1)
        );
        // Farther from the edge the bonus fades: the nearer frontier again.
        c[1].edge_m = 4.0;
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[]),
            Some(0)
        );
        // An edge bonus of 0 turns the rule off.
        c[1].edge_m = 1.0;
        let no_edge = Kestrel(ExplorationSettings {
            edge_bonus_m: 0.0,
            ..ExplorationSettings::default()
        });
        assert_eq!(choose(&no_edge, &me(0.0, 0.0), &c, &[]), Some(0));
    }

    #[test]
    fn kestrel_keeps_its_goal_against_a_marginally_better_one() {
        let c = [at(5.0, 0.0, 5.0, 2.0), at(-4.5, 0.0, 4.5, 2.0)];
        let mut r = me(0.0, 0.0);
        r.current_goal_enu_m = Some(Vector2::new(5.0, 0.2));
        assert_eq!(choose(&*by(AllocatorKind::Kestrel), &r, &c, &[]), Some(0));
        r.current_goal_enu_m = None;
        assert_eq!(choose(&*by(AllocatorKind::Kestrel), &r, &c, &[]), Some(1));
    }

    #[test]
    fn a_frontier_another_drone_holds_is_taken_only_when_nothing_else_is_left() {
        let c = [at(1.0, 0.0, 1.0, 2.0), at(20.0, 0.0, 20.0, 2.0)];
        let held = [Held::at(Vector2::new(1.2, 0.0))];
        for kind in [
            AllocatorKind::Kestrel,
            AllocatorKind::Thesis,
            AllocatorKind::Nearest,
            AllocatorKind::Farthest,
        ] {
            assert_eq!(
                choose(&*by(kind), &me(0.0, 0.0), &c, &held),
                Some(1),
                "{kind:?}"
            );
            assert_eq!(
                choose(&*by(kind), &me(0.0, 0.0), &c[..1], &held),
                Some(0),
                "{kind:?}"
            );
        }
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &[], &held),
            None
        );
    }

    #[test]
    fn thesis_trades_spread_from_the_others_against_twice_the_distance() {
        // Others' goals at (10, 0) and (0, 10); previous goal (0, 0). Candidate A (-4, -4) is far
        // from them and near the drone; B (8, 8) is between the others' goals.
        let c = [at(-4.0, -4.0, 6.0, 2.0), at(8.0, 8.0, 12.0, 2.0)];
        let mut r = me(0.0, 0.0);
        r.current_goal_enu_m = Some(Vector2::new(0.0, 0.0));
        let others = [
            Held::at(Vector2::new(10.0, 0.0)),
            Held::at(Vector2::new(0.0, 10.0)),
        ];
        assert_eq!(
            choose(&*by(AllocatorKind::Thesis), &r, &c, &others),
            Some(0)
        );
        assert_eq!(
            choose(&*by(AllocatorKind::Farthest), &r, &c, &others),
            Some(0)
        );
        // Alone, with no goal allocated yet, the thesis takes the nearest.
        assert_eq!(
            choose(&*by(AllocatorKind::Thesis), &me(7.0, 7.0), &c, &[]),
            Some(1)
        );
    }

    #[test]
    fn kestrel_leaves_a_far_frontier_to_the_drone_that_will_be_there_first() {
        // A lies 20 m ahead, B 21 m behind. Another drone is 1 m from its goal, 9 m past A: it
        // reaches A after 10 m, this drone after 20 m. Beyond two beam ranges of that goal, so
        // only the race decides.
        let c = [at(20.0, 0.0, 20.0, 2.0), at(-21.0, 0.0, 21.0, 2.0)];
        let mut other = Held::at(Vector2::new(29.0, 0.0));
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[other]),
            Some(0),
            "where the other drone is is unknown: the nearer frontier"
        );
        other.remaining_m = Some(1.0);
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[other]),
            Some(1)
        );
        other.remaining_m = Some(12.0);
        assert_eq!(
            choose(&*by(AllocatorKind::Kestrel), &me(0.0, 0.0), &c, &[other]),
            Some(0),
            "this drone is first: its nearer frontier"
        );
    }
}
