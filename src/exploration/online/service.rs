//! The frontier allocator as a fleet-level service: drones ask, on one tick, where to explore
//! next; the host answers before their next tick, from the fleet's merged map.
//!
//! In: [`ExploreRequest`]s (who asks, where it is, which allocator with which settings, what it
//! gives up) and the merged grid. Out: an [`Allocation`]: a goal with the path to it through
//! navigable space, or `Done` when this drone can reach no frontier. The service keeps the
//! goals each drone holds (a claim lapses when its drone stops asking, so a drone that fails
//! leaves its frontiers to the others) and the goals given up (seen from up close and still
//! unknown: occluded pockets; offered again once after a while, left for good the second time).
//! Frontiers that border only a small pocket of unknown (`SpaceParams::min_gain_cells`) are
//! offered only to a drone a few metres away (`ExplorationSettings::low_gain_near_m`): a visit
//! adds little, so they are worth no more than a short detour, and they do not keep the
//! exploration going. Those with under `SpaceParams::gain_cap_cells` of unknown near their goal
//! are worth a trip that grows with it (`ExplorationSettings::trip_m_per_m2`). When every
//! frontier is held, a drone farther from one than its holder is told `Done` rather than sent
//! to crowd it. With `sweep_along`, a frontier of 2 m or more is given as a sweep
//! ([`super::sweep`]): the path goes to its end nearer by path, then along it to the other end
//! (the goal), and the drone is told which way to turn so that the unknown side is the one its
//! beams sweep best. The navigable space is kept between requests and re-read only around the
//! cells that changed.
//!
//! One answer, in the steps of [`FrontierService::allocate`]: note what the drone gave up and
//! lapse old claims; survey the frontiers open to it (not given up) and the path to each that
//! is worth its trip; make candidates of them (long ones first, none a remote drone with a
//! smaller id holds, a sweep reached at its entry); leave frontiers to holders that are nearer;
//! let the allocator choose; claim the choice and give its path.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Vector2;
use serde::Serialize;

use super::allocation::{choose, AllocatorKind, Candidate, Held, Requester, CLAIM_RADIUS_M};
use super::reach::{KeepOut, Reach};
use super::settings::ExplorationSettings;
use super::space::{Frontier, Space, SpaceParams};
use super::sweep::{self, SWEEP_MIN_M};
use crate::mapping::grid::OccupancyGrid;
use crate::types::Vec3;

/// A claim lapses when its drone has not asked for this long.
pub const CLAIM_TTL: Duration = Duration::from_secs(6);
/// Frontiers whose goal lies this close to a given-up goal are left out (m).
const GIVEN_UP_RADIUS_M: f64 = 0.8;
/// A goal given up once is offered again after this long.
const GIVEN_UP_FOR: Duration = Duration::from_secs(120);
/// A goal in a keep-out disc is looked at from a reachable cell at most this far from it (m):
/// within the beams' reach with room to spare.
const LOOK_IN_M: f64 = 2.5;
/// Most given-up goals kept.
const MAX_GIVEN_UP: usize = 4096;

/// One drone's question.
#[derive(Debug, Clone, PartialEq)]
pub struct ExploreRequest {
    pub drone: Arc<str>,
    pub position_enu_m: Vec3,
    /// Height of the path's waypoints (ENU z, m).
    pub flight_height_m: f64,
    pub allocator: AllocatorKind,
    /// The allocator's weights and which small regions are worth a trip.
    pub settings: ExplorationSettings,
    pub space: SpaceParams,
    /// The goal it flies to now, if any (for hysteresis).
    pub current_goal_enu_m: Option<Vector2<f64>>,
    /// A goal it reached and watched without the frontier going away: never offered again.
    pub give_up: Option<Vector2<f64>>,
    /// Fly along a long frontier, end to end, instead of to its middle (the beams sweep it
    /// on the way).
    pub sweep_along: bool,
    /// Discs no path may enter and no goal may lie in: around drones other Kestrels flew that
    /// fell silent, which the safety stage keeps every drone away from.
    pub keep_out: Vec<KeepOut>,
    /// The goal given becomes the drone's claim (other drones leave it). `false`: a question
    /// asked only to learn what is left, whose answer is not flown.
    pub claim: bool,
}
/// What a drone is told.
#[derive(Debug, Clone, PartialEq)]
pub enum Allocation {
    Goal {
        goal_enu_m: Vec3,
        /// Waypoints from the drone to the goal, through navigable space.
        path_enu_m: Vec<Vec3>,
        /// Frontiers left in the map (all drones').
        frontiers: usize,
        /// For a sweep, which way to turn while flying it: clockwise (the unknown on the left)
        /// or not; `None`: as before.
        clockwise: Option<bool>,
    },
    /// No frontier for this drone (`frontiers`: those left that it cannot reach, is too far
    /// from for what they add, or leaves to their holders; `held`: how many of them other
    /// drones hold; `unreached`: how many it has no path to, from where it is now).
    Done {
        frontiers: usize,
        held: usize,
        unreached: usize,
    },
}

#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum ExploreError {
    #[error("no map to explore: mapping is off")]
    NoMap,
    #[error("the drone is outside the map")]
    OutsideMap,
    /// The allocator could not take the question (its thread stopped, too many waiting).
    #[error("frontier allocator unavailable: {0}")]
    Unavailable(String),
}

/// The exploration as operators see it (`GET /api/exploration`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ExplorationView {
    /// Frontiers as the allocator last read them.
    pub frontiers: Vec<FrontierView>,
    /// The goal each exploring drone holds.
    pub goals: Vec<ClaimView>,
    /// Known cells of the merged map (%); absent when mapping is off.
    pub known_pct: Option<f64>,
    /// The exploration started over the API, the last one; absent before any.
    pub progress: Option<super::progress::ProgressView>,
}

/// A frontier as shown to operators.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct FrontierView {
    pub centroid_enu_m: [f64; 2],
    pub goal_enu_m: [f64; 2],
    pub size_m: f64,
    pub orientation_rad: f64,
}

/// The goal a drone holds, as shown to operators.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ClaimView {
    pub drone: String,
    pub goal_enu_m: [f64; 2],
}

struct GivenUp {
    goal: Vector2<f64>,
    at: Duration,
}

struct Claim {
    goal: Vector2<f64>,
    stamp: Duration,
    /// Where its drone was when it last asked (unknown for another process's drones).
    from: Option<Vector2<f64>>,
}

/// A goal held by a drone another Kestrel process flies: (drone, goal, when it was claimed, on
/// the clock of the `now` given to [`FrontierService::answer`]).
pub type RemoteClaim = (Arc<str>, Vec3, Duration);

/// Most remote claims kept.
const MAX_REMOTE_CLAIMS: usize = 256;
/// Two goals this close are one frontier: a drone does not take one a remote drone with a
/// smaller id holds (m).
const CONFLICT_RADIUS_M: f64 = 1.5;

/// How far `point` lies from the nearest edge of the map (m, 0 outside it).
fn edge_distance_m(space: &Space, point: Vector2<f64>) -> f64 {
    let spec = space.spec();
    let lo = spec.origin_enu_m;
    let hi = lo
        + Vector2::new(
            f64::from(spec.width_cells) * spec.resolution_m,
            f64::from(spec.height_cells) * spec.resolution_m,
        );
    (point.x - lo.x)
        .min(hi.x - point.x)
        .min(point.y - lo.y)
        .min(hi.y - point.y)
        .max(0.0)
}

/// Whether a frontier is worth the trip of `path_m` (m): a pocket only from nearby; a region
/// smaller than the cap from a distance that grows with its area.
fn worth_trip(f: &Frontier, path_m: f64, cap_m2: f64, s: &ExplorationSettings) -> bool {
    if f.low_gain {
        path_m <= s.low_gain_near_m
    } else {
        f.gain_m2 >= cap_m2 || path_m <= s.low_gain_near_m + s.trip_m_per_m2 * f.gain_m2
    }
}

/// The frontiers open to one drone, with the path to each that is worth its trip.
struct Survey<'s> {
    open: Vec<&'s Frontier>,
    /// Per open frontier: its path length from the drone (m), if it has one worth the trip.
    paths: Vec<Option<f64>>,
}

impl<'s> Survey<'s> {
    fn new(
        open: Vec<&'s Frontier>,
        space: &Space,
        reach: &Reach,
        request: &ExploreRequest,
    ) -> Self {
        let cap_m2 = {
            let res = space.spec().resolution_m;
            request.space.gain_cap_cells as f64 * res * res
        };
        let paths = open
            .iter()
            .map(|f| {
                reach
                    .distance_m(f.goal_index)
                    .filter(|&d| worth_trip(f, d, cap_m2, &request.settings))
            })
            .collect();
        Self { open, paths }
    }

    fn each(&self) -> impl Iterator<Item = (&'s Frontier, Option<f64>)> + '_ {
        self.open.iter().copied().zip(self.paths.iter().copied())
    }

    /// Frontiers that keep the exploration going: all but the pockets not worth the trip.
    fn left(&self) -> usize {
        self.each()
            .filter(|(f, p)| p.is_some() || !f.low_gain)
            .count()
    }

    /// Short frontiers (corners, the last strips) are candidates only once no long one is
    /// left that this drone can reach.
    fn only_small(&self) -> bool {
        !self.each().any(|(f, p)| p.is_some() && !f.small)
    }

    /// `Done`, with how many frontiers are left, how many of them others hold and how many
    /// the drone has no path to.
    fn done(&self, reach: &Reach, others: &[Held]) -> Allocation {
        let left = self.left();
        let unreached = self
            .open
            .iter()
            .filter(|f| !f.low_gain && reach.distance_m(f.goal_index).is_none())
            .count();
        let held = self
            .open
            .iter()
            .filter(|f| {
                others
                    .iter()
                    .any(|h| (f.centroid_enu_m - h.goal_enu_m).norm() <= CLAIM_RADIUS_M)
            })
            .count();
        Allocation::Done {
            frontiers: left,
            held: held.min(left),
            unreached: unreached.min(left),
        }
    }
}

/// The space's frontiers, each whose goal lies in a keep-out disc given instead the reachable
/// cell nearest that goal within [`LOOK_IN_M`], from where the beams see across the disc: the
/// unknown round a silent drone's last position is still explored, from outside.
fn looked_at_from_outside(space: &Space, reach: &Reach, keep_out: &[KeepOut]) -> Vec<Frontier> {
    space
        .frontiers
        .iter()
        .map(|f| {
            let mut f = f.clone();
            if keep_out.is_empty() || !reach.kept_out(space, f.goal_index) {
                return f;
            }
            let outside = reach.nearest_reached(space, f.goal_index, LOOK_IN_M);
            if let Some((i, at)) = outside.and_then(|i| Some((i, space.center_of(i)?))) {
                f.goal_index = i;
                f.goal_enu_m = at;
            }
            f
        })
        .collect()
}

/// The allocator's memory between requests.
#[derive(Default)]
pub struct FrontierService {
    space: Option<Space>,
    claims: BTreeMap<Arc<str>, Claim>,
    /// Goals of drones flown by other processes, as last heard (replaced whole).
    remote: BTreeMap<Arc<str>, Claim>,
    given_up: Vec<GivenUp>,
}

impl FrontierService {
    pub fn new() -> Self {
        Self::default()
    }

    /// The navigable space of `grid`, brought up to date around what changed since last time.
    fn take_space(&mut self, grid: &OccupancyGrid, params: SpaceParams) -> Space {
        match self.space.take() {
            Some(mut space) => {
                space.update(grid, &params);
                space
            }
            None => Space::new(grid, &params),
        }
    }

    /// The goals held by drones other Kestrel processes fly (the latest set heard, replacing
    /// the previous one): they keep this fleet's drones away like local claims and lapse the
    /// same way, [`CLAIM_TTL`] after their stamp. At most [`MAX_REMOTE_CLAIMS`] are kept (the
    /// newest).
    pub fn set_remote_claims(&mut self, mut claims: Vec<RemoteClaim>) {
        claims.sort_by_key(|c| std::cmp::Reverse(c.2));
        claims.truncate(MAX_REMOTE_CLAIMS);
        self.remote.clear();
        for (drone, goal, stamp) in claims {
            let claim = Claim {
                goal: goal.xy(),
                stamp,
                from: None,
            };
            // One claim per drone: the newest (the list is sorted newest first).
            self.remote.entry(drone).or_insert(claim);
        }
    }

    /// Answers one request.
    pub fn answer(
        &mut self,
        now: Duration,
        grid: &OccupancyGrid,
        request: &ExploreRequest,
    ) -> Result<Allocation, ExploreError> {
        let space = self.take_space(grid, request.space);
        let answer = self.allocate(now, &space, request);
        self.space = Some(space);
        answer
    }

    /// One answer, step by step (the module's doc).
    fn allocate(
        &mut self,
        now: Duration,
        space: &Space,
        request: &ExploreRequest,
    ) -> Result<Allocation, ExploreError> {
        self.note_give_up_and_lapse(now, request.give_up);
        let here = request.position_enu_m.xy();
        let reach =
            Reach::keeping_out(space, here, &request.keep_out).ok_or(ExploreError::OutsideMap)?;
        let frontiers = looked_at_from_outside(space, &reach, &request.keep_out);
        let survey = Survey::new(self.open_frontiers(now, &frontiers), space, &reach, request);
        let mut candidates = self.candidates(space, &reach, &survey, request);
        let others = self.others(&request.drone);
        self.leave_to_nearer_holders(&mut candidates, &request.drone);
        let me = Requester {
            position_enu_m: here,
            current_goal_enu_m: request.current_goal_enu_m,
        };
        let just: Vec<Candidate> = candidates.iter().map(|(c, _)| *c).collect();
        let allocator = request.allocator.allocator(&request.settings);
        let Some(chosen) = choose(&*allocator, &me, &just, &others) else {
            self.claims.remove(&request.drone);
            return Ok(survey.done(&reach, &others));
        };
        let Some(&(_, frontier)) = candidates.get(chosen) else {
            return Ok(survey.done(&reach, &others));
        };
        Ok(self.give(now, space, &reach, frontier, request, survey.left()))
    }

    /// Records the goal the drone gave up (up to [`MAX_GIVEN_UP`]) and drops the claims not
    /// renewed for [`CLAIM_TTL`].
    fn note_give_up_and_lapse(&mut self, now: Duration, give_up: Option<Vector2<f64>>) {
        if let Some(goal) = give_up {
            if self.given_up.len() < MAX_GIVEN_UP {
                self.given_up.push(GivenUp { goal, at: now });
            }
        }
        for claims in [&mut self.claims, &mut self.remote] {
            claims.retain(|_, c| now.saturating_sub(c.stamp) < CLAIM_TTL);
        }
    }

    /// The frontiers not given up: a goal given up twice is left for good; once, for
    /// [`GIVEN_UP_FOR`] (the drone may have given up for a reason that passes: another drone in
    /// the way, a path that failed).
    fn open_frontiers<'s>(&self, now: Duration, frontiers: &'s [Frontier]) -> Vec<&'s Frontier> {
        frontiers
            .iter()
            .filter(|f| {
                let near: Vec<&GivenUp> = self
                    .given_up
                    .iter()
                    .filter(|g| (f.goal_enu_m - g.goal).norm() <= GIVEN_UP_RADIUS_M)
                    .collect();
                near.is_empty()
                    || (near.len() < 2
                        && near.iter().all(|g| now.saturating_sub(g.at) > GIVEN_UP_FOR))
            })
            .collect()
    }

    /// The surveyed frontiers the allocator may choose from, each with what it sees of it:
    /// only those with a path worth the trip; short ones only when no long one is left; none
    /// a remote drone with a smaller id holds (two Kestrels may give one frontier to two
    /// drones at once, each allocating for its own and hearing the other's claim a moment
    /// later: the larger id leaves it, so both settle the same way without talking again); a
    /// sweep reached at its entry.
    fn candidates<'s>(
        &self,
        space: &Space,
        reach: &Reach,
        survey: &Survey<'s>,
        request: &ExploreRequest,
    ) -> Vec<(Candidate, &'s Frontier)> {
        let only_small = survey.only_small();
        let yielded: Vec<Vector2<f64>> = self
            .remote
            .iter()
            .filter(|(id, _)| **id < request.drone)
            .map(|(_, c)| c.goal)
            .collect();
        survey
            .each()
            .filter_map(|(f, p)| {
                let mut path_m = p?;
                if f.small && !only_small {
                    return None;
                }
                if yielded
                    .iter()
                    .any(|g| (g - f.goal_enu_m).norm() < CONFLICT_RADIUS_M)
                {
                    return None;
                }
                let mut goal_enu_m = f.goal_enu_m;
                if sweeping(request, f) {
                    let entry = sweep::ends(space, reach, f, request.current_goal_enu_m).entry;
                    path_m = reach.distance_m(entry).unwrap_or(path_m);
                    goal_enu_m = space.center_of(entry).unwrap_or(goal_enu_m);
                }
                let candidate = Candidate {
                    centroid_enu_m: f.centroid_enu_m,
                    goal_enu_m,
                    size_m: f.size_m,
                    path_m,
                    edge_m: edge_distance_m(space, f.centroid_enu_m),
                };
                Some((candidate, f))
            })
            .collect()
    }

    /// The goals the other drones hold, local and remote.
    fn others(&self, drone: &Arc<str>) -> Vec<Held> {
        self.claims
            .iter()
            .chain(&self.remote)
            .filter(|(id, _)| *id != drone)
            .map(|(_, c)| Held {
                goal_enu_m: c.goal,
                remaining_m: c.from.map(|from| (from - c.goal).norm()),
            })
            .collect()
    }

    /// With every candidate held, keeps only those this drone is nearer than their holder:
    /// one whose drone is nearer would only be crowded (and one of the two would have to give
    /// way); this drone waits instead, and ends if nothing frees up.
    fn leave_to_nearer_holders(
        &self,
        candidates: &mut Vec<(Candidate, &Frontier)>,
        drone: &Arc<str>,
    ) {
        // The holder's distance to its goal: `Some(None)` for a holder whose position is
        // unknown, `None` for a frontier nobody holds.
        let holder_m = |c: &Candidate| {
            self.claims
                .iter()
                .chain(&self.remote)
                .filter(|(id, _)| *id != drone)
                .find(|(_, h)| (c.centroid_enu_m - h.goal).norm() <= CLAIM_RADIUS_M)
                .map(|(_, h)| h.from.map(|p| (p - h.goal).norm()))
        };
        if candidates.iter().all(|(c, _)| holder_m(c).is_some()) {
            candidates.retain(|(c, _)| {
                holder_m(c)
                    .flatten()
                    .is_none_or(|holder_m| c.path_m < holder_m)
            });
        }
    }

    /// Claims `frontier` for the asking drone and gives it: a sweep (its exit the goal, with the
    /// turn) or the way to its middle; the path at the flight height.
    fn give(
        &mut self,
        now: Duration,
        space: &Space,
        reach: &Reach,
        frontier: &Frontier,
        request: &ExploreRequest,
        left: usize,
    ) -> Allocation {
        let z = request.flight_height_m;
        let to_middle = || {
            (
                frontier.goal_enu_m,
                reach
                    .path_to(space, frontier.goal_index)
                    .unwrap_or_default(),
                None,
            )
        };
        let (goal_xy, path, clockwise) = if sweeping(request, frontier) {
            let current = request.current_goal_enu_m;
            let ends = sweep::ends(space, reach, frontier, current);
            match sweep::path(space, reach, frontier, ends, current) {
                Some(path) if !path.is_empty() => (
                    space.center_of(ends.exit).unwrap_or(frontier.goal_enu_m),
                    path,
                    Some(ends.clockwise),
                ),
                _ => to_middle(),
            }
        } else {
            to_middle()
        };
        let path: Vec<Vec3> = path.into_iter().map(|p| Vec3::new(p.x, p.y, z)).collect();
        if request.claim {
            self.claims.insert(
                request.drone.clone(),
                Claim {
                    goal: frontier.goal_enu_m,
                    stamp: now,
                    from: Some(request.position_enu_m.xy()),
                },
            );
        }
        let goal = Vec3::new(goal_xy.x, goal_xy.y, z);
        Allocation::Goal {
            goal_enu_m: goal,
            path_enu_m: if path.is_empty() { vec![goal] } else { path },
            frontiers: left,
            clockwise,
        }
    }

    /// The frontiers as last read, for operators.
    pub fn frontiers(&self) -> Vec<FrontierView> {
        let Some(space) = &self.space else {
            return Vec::new();
        };
        space
            .frontiers
            .iter()
            .map(|f| FrontierView {
                centroid_enu_m: [f.centroid_enu_m.x, f.centroid_enu_m.y],
                goal_enu_m: [f.goal_enu_m.x, f.goal_enu_m.y],
                size_m: f.size_m,
                orientation_rad: f.orientation_rad,
            })
            .collect()
    }

    /// The goal each drone holds now, this process's drones first, then the others'.
    pub fn claims(&self) -> Vec<ClaimView> {
        self.claims
            .iter()
            .chain(&self.remote)
            .map(|(d, c)| ClaimView {
                drone: d.to_string(),
                goal_enu_m: [c.goal.x, c.goal.y],
            })
            .collect()
    }
}

/// Whether `frontier` is given as a sweep: asked for, and long enough.
fn sweeping(request: &ExploreRequest, frontier: &Frontier) -> bool {
    request.sweep_along && frontier.size_m >= SWEEP_MIN_M
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::mapping::grid::{GridSpec, UNKNOWN};

    fn half_known() -> OccupancyGrid {
        // 20 x 10 m at 0.1 m: x < 10 m known free, the rest unknown.
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 200,
            height_cells: 100,
            origin_enu_m: Vector2::zeros(),
        };
        let data = (0..100)
            .flat_map(|_| (0..200).map(|x| if x < 100 { 0 } else { UNKNOWN }))
            .collect();
        OccupancyGrid::from_data(spec, data).unwrap()
    }

    fn ask(drone: &str, x: f64, y: f64) -> ExploreRequest {
        ExploreRequest {
            drone: drone.into(),
            position_enu_m: Vec3::new(x, y, 1.0),
            flight_height_m: 1.0,
            allocator: AllocatorKind::Kestrel,
            settings: ExplorationSettings::default(),
            space: SpaceParams::default(),
            current_goal_enu_m: None,
            give_up: None,
            sweep_along: false,
            keep_out: Vec::new(),
            claim: true,
        }
    }

    fn goal_of(a: &Allocation) -> Vec3 {
        match a {
            Allocation::Goal { goal_enu_m, .. } => *goal_enu_m,
            Allocation::Done { .. } => panic!("done: {a:?}"),
        }
    }

    #[test]
    fn a_question_that_claims_nothing_leaves_the_goal_to_the_others() {
        let grid = half_known();
        let mut s = FrontierService::new();
        let t = Duration::from_secs(1);
        let probe = ExploreRequest {
            claim: false,
            ..ask("a", 2.0, 2.0)
        };
        let a = s.answer(t, &grid, &probe).unwrap();
        assert!(s.claims().is_empty(), "nothing held");
        let b = s.answer(t, &grid, &ask("b", 2.0, 2.0)).unwrap();
        assert_eq!(goal_of(&b), goal_of(&a), "the same frontier is still open");
    }

    #[test]
    fn two_drones_get_different_frontiers_and_paths_that_end_at_them() {
        let grid = half_known();
        let mut s = FrontierService::new();
        let t = Duration::from_secs(1);
        let a = s.answer(t, &grid, &ask("a", 2.0, 2.0)).unwrap();
        let b = s.answer(t, &grid, &ask("b", 2.0, 2.5)).unwrap();
        let (ga, gb) = (goal_of(&a), goal_of(&b));
        assert!((ga - gb).norm() > 2.0, "{ga:?} {gb:?}");
        if let Allocation::Goal { path_enu_m, .. } = &a {
            assert_eq!(path_enu_m.last(), Some(&ga));
            assert!(path_enu_m.iter().all(|p| p.z == 1.0));
        }
        assert_eq!(s.claims().len(), 2);
        // Claims lapse when their drone stops asking: `b` alone later gets `a`'s old goal back.
        let later = t + CLAIM_TTL + Duration::from_secs(1);
        let b2 = s.answer(later, &grid, &ask("b", 2.0, 2.0)).unwrap();
        assert!((goal_of(&b2) - ga).norm() < 1e-9);
    }

    #[test]
    fn a_frontier_a_remote_drone_with_a_smaller_id_holds_is_left_to_it() {
        let grid = half_known();
        let t = Duration::from_secs(1);
        let alone = goal_of(
            &FrontierService::new()
                .answer(t, &grid, &ask("b", 2.0, 2.0))
                .unwrap(),
        );
        let mut s = FrontierService::new();
        s.set_remote_claims(vec![("a".into(), alone, t)]);
        let b = goal_of(&s.answer(t, &grid, &ask("b", 2.0, 2.0)).unwrap());
        assert!(
            (b - alone).xy().norm() >= CONFLICT_RADIUS_M,
            "{b:?} {alone:?}"
        );
    }

    #[test]
    fn a_remote_drones_goal_keeps_a_local_drone_away_until_it_lapses() {
        let grid = half_known();
        let t = Duration::from_secs(10);
        let alone = goal_of(
            &FrontierService::new()
                .answer(t, &grid, &ask("a", 2.0, 2.0))
                .unwrap(),
        );
        let mut s = FrontierService::new();
        s.set_remote_claims(vec![
            ("far:b".into(), Vec3::new(0.0, 0.0, 1.0), Duration::ZERO),
            ("far:b".into(), alone, t),
        ]);
        let shared = goal_of(&s.answer(t, &grid, &ask("a", 2.0, 2.0)).unwrap());
        assert!((shared - alone).norm() > 2.0, "{shared:?} {alone:?}");
        assert_eq!(s.claims().len(), 2, "a's own and b's newest");
        // Not heard from for the claims' lifetime: the frontier is free again.
        let later = t + CLAIM_TTL;
        let freed = goal_of(&s.answer(later, &grid, &ask("a", 2.0, 2.0)).unwrap());
        assert!((freed - alone).norm() < 1e-9, "{freed:?} {alone:?}");
        assert_eq!(s.claims().len(), 1);
    }

    #[test]
    fn a_frontier_whose_goal_lies_in_a_keep_out_disc_is_looked_at_from_outside_it() {
        let grid = half_known();
        let t = Duration::from_secs(1);
        let free = goal_of(
            &FrontierService::new()
                .answer(t, &grid, &ask("a", 2.0, 5.0))
                .unwrap(),
        );
        // A silent drone's last position on that goal: its disc covers the goal, not the
        // whole frontier.
        let disc = KeepOut {
            centre_enu_m: free.xy(),
            radius_m: 1.5,
        };
        let mut request = ask("a", 2.0, 5.0);
        request.keep_out = vec![disc];
        let answer = FrontierService::new().answer(t, &grid, &request).unwrap();
        let Allocation::Goal {
            goal_enu_m,
            path_enu_m,
            ..
        } = &answer
        else {
            panic!("the frontier is still there to look at: {answer:?}");
        };
        let from_centre = (goal_enu_m.xy() - disc.centre_enu_m).norm();
        assert!(
            (disc.radius_m..=LOOK_IN_M + 0.1).contains(&from_centre),
            "{goal_enu_m:?} {from_centre}"
        );
        assert!(path_enu_m
            .iter()
            .all(|p| (p.xy() - disc.centre_enu_m).norm() >= disc.radius_m - 0.1));
    }

    /// 20 x 10 m known free but for a square unknown pocket of `side` cells from (15, 4.8).
    fn pocket(side: usize) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 200,
            height_cells: 100,
            origin_enu_m: Vector2::zeros(),
        };
        let data = (0..100)
            .flat_map(|y| {
                (0..200).map(move |x| {
                    let pocket = (150..150 + side).contains(&x) && (48..48 + side).contains(&y);
                    if pocket {
                        UNKNOWN
                    } else {
                        0
                    }
                })
            })
            .collect();
        OccupancyGrid::from_data(spec, data).unwrap()
    }

    #[test]
    fn a_pocket_is_flown_to_only_from_nearby() {
        // A 0.5 x 0.5 m pocket around (15.25, 5.05).
        let grid = pocket(5);
        let with_gain = |mut r: ExploreRequest| {
            r.space.min_gain_cells = 50;
            r
        };
        let t = Duration::from_secs(1);
        let mut s = FrontierService::new();
        let far = s.answer(t, &grid, &with_gain(ask("a", 2.0, 5.0))).unwrap();
        assert_eq!(
            far,
            Allocation::Done {
                frontiers: 0,
                held: 0,
                unreached: 0
            }
        );
        let near = s
            .answer(t, &grid, &with_gain(ask("a", 15.25, 3.6)))
            .unwrap();
        assert!((goal_of(&near).xy() - Vector2::new(15.25, 5.05)).norm() < 1.5);
        // Without the least gain the pocket is a frontier like any other, from anywhere.
        let mut s = FrontierService::new();
        let any = s.answer(t, &grid, &ask("a", 2.0, 5.0)).unwrap();
        assert!((goal_of(&any).xy() - Vector2::new(15.25, 5.05)).norm() < 1.5);
    }

    #[test]
    fn a_small_unknown_region_is_worth_a_trip_that_grows_with_its_area() {
        // A 1 x 1 m region around (15.5, 5.3): worth 3 m (`low_gain_near_m`) + 8 m of path, so from
        // 5 m away but not from 13 m.
        let grid = pocket(10);
        let capped = |mut r: ExploreRequest| {
            r.space.min_gain_cells = 50;
            r.space.gain_cap_cells = 400;
            r
        };
        let t = Duration::from_secs(1);
        let mut s = FrontierService::new();
        let far = s.answer(t, &grid, &capped(ask("a", 2.0, 5.0))).unwrap();
        assert!(matches!(far, Allocation::Done { .. }), "{far:?}");
        let near = s.answer(t, &grid, &capped(ask("a", 10.0, 5.0))).unwrap();
        assert!((goal_of(&near).xy() - Vector2::new(15.5, 5.3)).norm() < 1.8);
        // A region of the cap or more (here: no cap) is worth any trip.
        let any = FrontierService::new()
            .answer(t, &grid, &ask("a", 2.0, 5.0))
            .unwrap();
        assert!((goal_of(&any).xy() - Vector2::new(15.5, 5.3)).norm() < 1.8);
    }

    #[test]
    fn with_every_frontier_held_a_drone_farther_than_its_holder_waits_instead_of_crowding() {
        let grid = half_known();
        let t = Duration::from_secs(1);
        let mut s = FrontierService::new();
        // Two drones 1.5 m from the frontier at x = 10 m take its two parts.
        let a = goal_of(&s.answer(t, &grid, &ask("a", 8.0, 2.5)).unwrap());
        let b = goal_of(&s.answer(t, &grid, &ask("b", 8.0, 7.5)).unwrap());
        assert!((a - b).norm() > 3.0, "{a:?} {b:?}");
        let far = s.answer(t, &grid, &ask("c", 1.0, 5.0)).unwrap();
        assert_eq!(
            far,
            Allocation::Done {
                frontiers: 2,
                held: 2,
                unreached: 0
            }
        );
        // Nearer a part than its holder: it may share it.
        let near = goal_of(&s.answer(t, &grid, &ask("d", a.x, a.y - 0.5)).unwrap());
        assert!((near - a).norm() < 1e-9, "{near:?} {a:?}");
    }

    #[test]
    fn a_drone_that_can_reach_nothing_is_done_and_given_up_goals_are_not_offered_again() {
        let grid = half_known();
        let mut s = FrontierService::new();
        let t = Duration::from_secs(1);
        // A drone deep in the unknown half reaches no frontier.
        let lost = s.answer(t, &grid, &ask("a", 15.0, 5.0)).unwrap();
        assert!(matches!(
            lost,
            Allocation::Done { frontiers, held: 0, unreached } if frontiers > 0 && unreached == frontiers
        ));
        let first = goal_of(&s.answer(t, &grid, &ask("a", 2.0, 5.0)).unwrap());
        let mut r = ask("a", 2.0, 5.0);
        r.give_up = Some(first.xy());
        let second = goal_of(&s.answer(t, &grid, &r).unwrap());
        assert!((second - first).norm() > GIVEN_UP_RADIUS_M);
        // Offered again after a while; given up a second time, never again.
        let later = t + GIVEN_UP_FOR + Duration::from_secs(1);
        let mut r = ask("a", 2.0, 5.0);
        r.give_up = Some(second.xy());
        let again = goal_of(&s.answer(later, &grid, &r).unwrap());
        assert!((again - first).norm() < 1e-9, "{again:?} {first:?}");
        let mut r = ask("a", 2.0, 5.0);
        r.give_up = Some(first.xy());
        let mut r2 = ask("a", 2.0, 5.0);
        r2.give_up = Some(second.xy());
        s.answer(later, &grid, &r).unwrap();
        let last = s.answer(later + GIVEN_UP_FOR * 2, &grid, &r2).unwrap();
        assert!(matches!(last, Allocation::Done { .. }), "{last:?}");
    }

    #[test]
    fn a_trip_is_worth_it_by_the_unknown_behind_the_frontier_and_the_settings() {
        let grid = half_known();
        let space = Space::new(&grid, &SpaceParams::default());
        let mut f = space.frontiers[0].clone();
        let s = ExplorationSettings::default();
        // A pocket: from 3 m of path.
        f.low_gain = true;
        assert!(worth_trip(&f, 3.0, 4.0, &s) && !worth_trip(&f, 3.1, 4.0, &s));
        // 0.5 m^2 behind it, under the 4 m^2 cap: 3 m + 8 m per m^2 = 7 m.
        f.low_gain = false;
        f.gain_m2 = 0.5;
        assert!(worth_trip(&f, 7.0, 4.0, &s) && !worth_trip(&f, 7.1, 4.0, &s));
        let farther = ExplorationSettings {
            trip_m_per_m2: 20.0,
            ..s
        };
        assert!(worth_trip(&f, 13.0, 4.0, &farther));
        // At the cap or more: any trip.
        f.gain_m2 = 4.0;
        assert!(worth_trip(&f, 1e6, 4.0, &s));
        // The edge distance: to the nearest side of the 20 x 10 m map, 0 outside.
        assert_eq!(edge_distance_m(&space, Vector2::new(3.0, 8.5)), 1.5);
        assert_eq!(edge_distance_m(&space, Vector2::new(-1.0, 5.0)), 0.0);
    }

    #[test]
    fn a_long_frontier_is_swept_end_to_end_turning_so_the_unknown_is_swept_best() {
        let grid = half_known();
        let t = Duration::from_secs(1);
        let mut r = ask("a", 2.0, 2.0);
        r.sweep_along = true;
        let a = FrontierService::new().answer(t, &grid, &r).unwrap();
        let Allocation::Goal {
            goal_enu_m,
            path_enu_m,
            clockwise,
            ..
        } = a
        else {
            panic!("{a:?}")
        };
        // The frontier runs north-south along x = 9.55 m (the unknown east of it): the path
        // ends with a leg along it, from one end through its middle to the other (the goal).
        let n = path_enu_m.len();
        assert!(n >= 3, "{path_enu_m:?}");
        assert_eq!(path_enu_m[n - 1], goal_enu_m);
        let along = &path_enu_m[n - 3..];
        assert!(along.iter().all(|p| (p.x - 9.55).abs() < 0.15), "{along:?}");
        let leg = along[2] - along[0];
        assert!(leg.y.abs() > 2.0, "{along:?}");
        // Northward the unknown is on the right: counter-clockwise; southward, clockwise.
        assert_eq!(clockwise, Some(leg.y < 0.0));
        // Asked again on the way, the drone keeps its goal (the sweep is not turned back).
        let mut again = ask("a", along[1].x, along[1].y);
        again.sweep_along = true;
        again.current_goal_enu_m = Some(goal_enu_m.xy());
        let mut s = FrontierService::new();
        assert_eq!(goal_of(&s.answer(t, &grid, &again).unwrap()), goal_enu_m);
        // Without sweeping the goal is the frontier's middle and the turn is left as it is.
        let plain = FrontierService::new()
            .answer(t, &grid, &ask("a", 2.0, 2.0))
            .unwrap();
        assert!(matches!(
            plain,
            Allocation::Goal {
                clockwise: None,
                ..
            }
        ));
    }
}
