//! A*, Dijkstra and Voronoi planners on the grid.
//!
//! In: a [`PlanRequest`], a [`PlanningMap`], a [`PlanBudget`]. Out: a [`PlannedPath`] or a
//! [`PlanError`]. All three share the search in [`super::search`], the blocking rules in the
//! module docs of [`super`], and line-of-sight pruning in [`super::simplify`]. They differ in:
//! * A*: octile heuristic, cost = length. When every enterable cell costs the same (unknown
//!   cells blocked or free of charge) and the start is outside the inflated zone, the search is
//!   jump point search: same moves, same optimal cost, far fewer heap operations; the expansion
//!   budget then counts jump points.
//! * Dijkstra: no heuristic, same optimal cost.
//! * Voronoi: the octile heuristic (still admissible: every multiplier is >= 1); entering a cell off the generalised Voronoi diagram costs
//!   `1 + VORONOI_OFF_DIAGRAM_PENALTY` times its length, so the path joins the diagram (the
//!   ridge of maximal clearance), follows it and leaves it near the goal; pruning keeps the
//!   raw path's clearance to within one cell or 20 %. (Aerostack2 instead adds `300 - distance` per cell and ignores the
//!   safety distance.)

use std::sync::Mutex;

use nalgebra::Vector3;

use crate::mapping::grid::GridSpec;

use super::search::{jump_point_search, search, SearchScratch};
use super::simplify::{polyline_min_clearance, prune};
use super::{
    PathPlanner, PlanBudget, PlanError, PlanRequest, PlannedPath, PlanningMap, UnknownPolicy,
};

/// Extra cost factor of cells off the Voronoi diagram for the Voronoi planner.
pub const VORONOI_OFF_DIAGRAM_PENALTY: f64 = 1.0;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Method {
    AStar,
    Dijkstra,
    Voronoi,
}

/// Which cells may be entered, at what cost.
struct CellRules<'a> {
    data: &'a [i8],
    dist_m: &'a [f32],
    threshold: i8,
    safety_m: f32,
    unknown_extra: Option<f64>,
}

impl CellRules<'_> {
    /// Cost multiplier from occupancy and the unknown policy, ignoring clearance.
    fn base(&self, i: usize) -> Option<f64> {
        let v = *self.data.get(i)?;
        if v >= self.threshold {
            None
        } else if v < 0 {
            self.unknown_extra.map(|c| 1.0 + c)
        } else {
            Some(1.0)
        }
    }

    fn clearance(&self, i: usize) -> f32 {
        self.dist_m.get(i).copied().unwrap_or(0.0)
    }

    /// Every enterable cell costs the same (unknown cells blocked or free of charge).
    fn uniform(&self) -> bool {
        self.unknown_extra.is_none_or(|c| c == 0.0)
    }

    /// Enterable with clearance beyond the safety distance.
    fn free(&self, i: usize) -> bool {
        self.base(i).is_some() && self.clearance(i) > self.safety_m
    }

    /// Multiplier for the move `from -> to`: outside the inflated zone, or climbing out of it
    /// (strictly increasing clearance) when already inside, as a start near a wall is.
    fn enter(&self, from: usize, to: usize) -> Option<f64> {
        let m = self.base(to)?;
        let d = self.clearance(to);
        if d > self.safety_m {
            return Some(m);
        }
        let df = self.clearance(from);
        (df <= self.safety_m && d > df).then_some(m)
    }
}

fn plan_on_grid(
    method: Method,
    scratch: &Mutex<SearchScratch>,
    req: &PlanRequest,
    map: &PlanningMap,
    budget: &PlanBudget<'_>,
) -> Result<PlannedPath, PlanError> {
    req.validate(map, budget)?;
    let spec = *map.grid().spec();
    let rules = CellRules {
        data: map.grid().data(),
        dist_m: map.field().distances_m(),
        threshold: map.occupied_threshold(),
        safety_m: req.safety_distance_m as f32,
        unknown_extra: match req.unknown {
            UnknownPolicy::Blocked => None,
            UnknownPolicy::AllowedWithCost(c) => Some(c),
        },
    };
    let start = spec
        .cell_at(req.start_enu_m.xy())
        .and_then(|c| spec.index_of(c))
        .ok_or(PlanError::StartOutsideMap)?;
    let goal = spec
        .cell_at(req.goal_enu_m.xy())
        .and_then(|c| spec.index_of(c))
        .ok_or(PlanError::GoalOutsideMap)?;
    if rules.data.get(start).is_none_or(|&v| v >= rules.threshold) {
        return Err(PlanError::StartOccupied);
    }
    if !rules.free(goal) {
        return Err(PlanError::GoalOccupied);
    }

    let voronoi = method == Method::Voronoi;
    let step = |from: usize, to: usize| {
        let m = rules.enter(from, to)?;
        Some(if voronoi && !map.is_voronoi(to) {
            m * (1.0 + VORONOI_OFF_DIAGRAM_PENALTY)
        } else {
            m
        })
    };
    let found = {
        let mut fresh = SearchScratch::default();
        let mut guard = scratch.try_lock();
        // A planner shared between threads falls back to fresh buffers instead of waiting.
        let s = match guard.as_mut() {
            Ok(g) => &mut **g,
            Err(_) => &mut fresh,
        };
        if method == Method::AStar && rules.uniform() && rules.free(start) {
            let mask = padded_free_mask(&spec, &rules);
            let pw = i64::from(spec.width_cells) + 2;
            let walkable = |x: i64, y: i64| {
                let i = (y + 1) * pw + x + 1;
                i >= 0 && mask.get(i as usize).copied().unwrap_or(false)
            };
            jump_point_search(s, &spec, start, goal, budget, walkable)?
        } else {
            search(
                s,
                &spec,
                start,
                goal,
                method != Method::Dijkstra,
                budget,
                step,
            )?
        }
    };

    let clearance = |i: usize| rules.clearance(i);
    let anchors = if voronoi {
        // A shortcut may come closer to obstacles than the stretch it replaces by one cell or
        // 20 %, whichever is less (and never inside the safety distance): the diagram's ridge
        // wiggles by a cell, and following it exactly keeps dozens of waypoints.
        let cell = spec.resolution_m as f32;
        prune(&spec, &found.cells, clearance, |c, m| {
            let d = rules.clearance(c);
            let slack = cell.min(0.2 * m);
            rules.base(c).is_some() && d >= m - slack && (d > rules.safety_m || d >= m)
        })
    } else {
        prune(&spec, &found.cells, clearance, |c, m| {
            rules.base(c).is_some()
                && (rules.clearance(c) > rules.safety_m || rules.clearance(c) >= m)
        })
    };
    let min_clearance_m = f64::from(polyline_min_clearance(&spec, &anchors, clearance));

    let z = req.flight_height_m;
    let mut waypoints_enu_m: Vec<Vector3<f64>> = anchors
        .iter()
        .skip(1)
        .filter_map(|&i| spec.cell_of_index(i))
        .map(|c| {
            let p = spec.cell_center_enu_m(c);
            Vector3::new(p.x, p.y, z)
        })
        .collect();
    let goal_point = Vector3::new(req.goal_enu_m.x, req.goal_enu_m.y, z);
    match waypoints_enu_m.last_mut() {
        Some(last) => *last = goal_point,
        None => waypoints_enu_m.push(goal_point),
    }
    Ok(PlannedPath {
        length_m: polyline_length_m(&req.start_enu_m, &waypoints_enu_m),
        waypoints_enu_m,
        raw_cells: found.cells.len(),
        cost: found.cost,
        min_clearance_m,
    })
}

/// Free cells (see [`CellRules::free`]) with a blocked one-cell border, row-major with width
/// `width + 2`. Jumps test each scanned cell and its sides, so this makes a test one byte load
/// with no range check.
fn padded_free_mask(spec: &GridSpec, rules: &CellRules<'_>) -> Vec<bool> {
    let w = spec.width_cells as usize;
    let h = spec.height_cells as usize;
    let mut mask = vec![false; (w + 2) * (h + 2)];
    let rows = mask.chunks_exact_mut(w + 2).skip(1).take(h).enumerate();
    for (row, cells) in rows {
        for (x, m) in cells.iter_mut().skip(1).take(w).enumerate() {
            *m = rules.free(row * w + x);
        }
    }
    mask
}

/// Length of start -> waypoints.
pub(crate) fn polyline_length_m(start: &Vector3<f64>, waypoints: &[Vector3<f64>]) -> f64 {
    let mut prev = *start;
    waypoints
        .iter()
        .map(|p| {
            let d = (p - prev).norm();
            prev = *p;
            d
        })
        .sum()
}

macro_rules! grid_planner {
    ($(#[$doc:meta])* $name:ident, $method:expr) => {
        $(#[$doc])*
        #[derive(Debug, Default)]
        pub struct $name {
            scratch: Mutex<SearchScratch>,
        }

        impl PathPlanner for $name {
            fn plan(
                &self,
                request: &PlanRequest,
                map: &PlanningMap,
                budget: &PlanBudget<'_>,
            ) -> Result<PlannedPath, PlanError> {
                plan_on_grid($method, &self.scratch, request, map, budget)
            }
        }
    };
}

grid_planner!(
    /// A* with the octile heuristic: the shortest 8-connected path.
    AStarPlanner,
    Method::AStar
);
grid_planner!(
    /// Dijkstra: the same optimal cost as A*, for comparison and unknown-heavy maps.
    DijkstraPlanner,
    Method::Dijkstra
);
grid_planner!(
    /// Follows the generalised Voronoi diagram to maximise clearance.
    VoronoiPlanner,
    Method::Voronoi
);

#[cfg(test)]
mod tests {
    use std::f64::consts::SQRT_2;
    use std::sync::atomic::AtomicBool;

    use nalgebra::Vector2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;
    use crate::mapping::grid::{GridSpec, OccupancyGrid};
    use crate::planning::{PlannerKind, Planners};

    const BIG: usize = 10_000_000;

    fn grid(w: u32, h: u32, res: f64, occupied: &[(u32, u32)]) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: res,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        };
        let mut data = vec![0i8; spec.cell_count()];
        for &(x, y) in occupied {
            data[(y * w + x) as usize] = 100;
        }
        OccupancyGrid::from_data(spec, data).unwrap()
    }

    /// Request between cell centres at resolution `res`.
    fn req(res: f64, from: (u32, u32), to: (u32, u32), kind: PlannerKind) -> PlanRequest {
        let c =
            |(x, y): (u32, u32)| Vector3::new((x as f64 + 0.5) * res, (y as f64 + 0.5) * res, 1.0);
        PlanRequest {
            start_enu_m: c(from),
            goal_enu_m: c(to),
            flight_height_m: 1.0,
            safety_distance_m: 0.0,
            unknown: UnknownPolicy::Blocked,
            kind,
            max_map_age_s: None,
            shadow_m: 0.0,
        }
    }

    /// Costs are fixed point (1e-6 of a cell), so comparisons allow 1e-4.
    fn plan(r: &PlanRequest, m: &PlanningMap) -> Result<PlannedPath, PlanError> {
        Planners::default().plan(r, m, &PlanBudget::expansions(BIG))
    }

    #[test]
    fn empty_grid_cost_is_octile_distance_for_a_star_and_dijkstra() {
        let m = PlanningMap::new(grid(10, 6, 0.5, &[]), 50);
        for kind in [PlannerKind::AStar, PlannerKind::Dijkstra] {
            let r = req(0.5, (1, 1), (8, 4), kind);
            let p = plan(&r, &m).unwrap();
            // dx 7, dy 3: 3 diagonal + 4 straight steps of 0.5 m.
            assert!(
                (p.cost - 0.5 * (3.0 * SQRT_2 + 4.0)).abs() < 1e-4,
                "{kind:?} {}",
                p.cost
            );
            assert_eq!(p.raw_cells, 8);
            // Line of sight everywhere: one waypoint, the goal, at flight height.
            assert_eq!(p.waypoints_enu_m, vec![Vector3::new(4.25, 2.25, 1.0)]);
            assert!((p.length_m - (3.5f64.powi(2) + 1.5f64.powi(2)).sqrt()).abs() < 1e-9);
        }
    }

    #[test]
    fn wall_with_gap_has_hand_computed_optimal_cost() {
        // Wall x = 5, y = 0..=8; the only gap is (5, 9). No corner cutting means the gap is
        // entered and left orthogonally: (1,1)->(4,9) = 3 diag + 5, (4,9)->(6,9) = 2,
        // (6,9)->(8,1) = 2 diag + 6. Total 13 + 5 sqrt 2.
        let wall: Vec<(u32, u32)> = (0..=8).map(|y| (5, y)).collect();
        let m = PlanningMap::new(grid(10, 10, 1.0, &wall), 50);
        for kind in [PlannerKind::AStar, PlannerKind::Dijkstra] {
            let p = plan(&req(1.0, (1, 1), (8, 1), kind), &m).unwrap();
            assert!(
                (p.cost - (13.0 + 5.0 * SQRT_2)).abs() < 1e-4,
                "{kind:?}: {}",
                p.cost
            );
            // Pruned to a handful of waypoints, none inside the wall.
            assert!(p.waypoints_enu_m.len() <= 4, "{:?}", p.waypoints_enu_m);
            assert!(p.min_clearance_m >= 1.0 - 1e-6);
        }
    }

    #[test]
    fn a_star_cost_matches_pathfinding_crate_on_random_grids() {
        let (w, h) = (60u32, 45u32);
        for seed in 0..5 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let occ: Vec<(u32, u32)> = (0..w * h)
                .filter(|_| rng.gen_bool(0.2))
                .map(|i| (i % w, i / w))
                .filter(|&c| c != (0, 0) && c != (w - 1, h - 1))
                .collect();
            let g = grid(w, h, 1.0, &occ);
            let blocked = |x: i64, y: i64| {
                x < 0
                    || y < 0
                    || x >= w as i64
                    || y >= h as i64
                    || g.data()[(y * w as i64 + x) as usize] >= 50
            };
            // Same moves, costs scaled to integers (1000 and 1414).
            let theirs = pathfinding::prelude::astar(
                &(0i64, 0i64),
                |&(x, y)| {
                    let mut v = Vec::new();
                    for (dx, dy) in [
                        (0, 1),
                        (1, 0),
                        (0, -1),
                        (-1, 0),
                        (1, 1),
                        (1, -1),
                        (-1, -1),
                        (-1, 1),
                    ] {
                        let diag = dx != 0 && dy != 0;
                        if blocked(x + dx, y + dy)
                            || (diag && (blocked(x + dx, y) || blocked(x, y + dy)))
                        {
                            continue;
                        }
                        v.push(((x + dx, y + dy), if diag { 1414i64 } else { 1000 }));
                    }
                    v
                },
                |&(x, y)| {
                    let (dx, dy) = ((w as i64 - 1 - x).abs(), (h as i64 - 1 - y).abs());
                    dx.max(dy) * 1000 + dx.min(dy) * 414
                },
                |&p| p == (w as i64 - 1, h as i64 - 1),
            );
            let m = PlanningMap::new(g.clone(), 50);
            let ours = plan(&req(1.0, (0, 0), (w - 1, h - 1), PlannerKind::AStar), &m);
            match (theirs, ours) {
                (Some((_, c)), Ok(p)) => {
                    assert!(
                        (p.cost - c as f64 / 1000.0).abs() < 2e-4 * p.cost,
                        "seed {seed}: {} vs {c}",
                        p.cost
                    )
                }
                (None, Err(PlanError::NoPath)) => {}
                (t, o) => panic!("seed {seed}: pathfinding {t:?}, ours {o:?}"),
            }
        }
    }

    #[test]
    fn inflation_is_round_not_square() {
        // One obstacle at (10,10), resolution 0.1 m, safety 0.25 m.
        let m = PlanningMap::new(grid(21, 21, 0.1, &[(10, 10)]), 50);
        let mut r = req(0.1, (0, 0), (12, 11), PlannerKind::AStar);
        r.safety_distance_m = 0.25;
        // (12,11): sqrt 5 * 0.1 = 0.224 m <= 0.25: blocked.
        assert_eq!(plan(&r, &m), Err(PlanError::GoalOccupied));
        // (12,12): sqrt 8 * 0.1 = 0.283 m: free, though a square (Chebyshev) inflation of
        // ceil(0.25 / 0.1) = 3 cells would block it.
        r.goal_enu_m = Vector3::new(1.25, 1.25, 1.0);
        let p = plan(&r, &m).unwrap();
        assert!(p.min_clearance_m > 0.25);
        // (13,10): 0.3 m: free; (10,12) 0.2 m: blocked.
        r.goal_enu_m = Vector3::new(1.35, 1.05, 1.0);
        assert!(plan(&r, &m).is_ok());
        r.goal_enu_m = Vector3::new(1.05, 1.25, 1.0);
        assert_eq!(plan(&r, &m), Err(PlanError::GoalOccupied));
    }

    #[test]
    fn voronoi_keeps_more_clearance_than_a_star_in_a_corridor() {
        // Corridor 60 x 21 with walls on rows 0 and 20 and a pillar x 25..=34, y 7..=12: gaps of
        // 6 cells below (y 1..=6) and 7 above (y 13..=19). A* hugs the pillar at the safety
        // distance; the Voronoi path runs through the middle of a gap.
        let mut occ: Vec<(u32, u32)> = (0..60).flat_map(|x| [(x, 0), (x, 20)]).collect();
        occ.extend((25..=34).flat_map(|x| (7..=12).map(move |y| (x, y))));
        let m = PlanningMap::new(grid(60, 21, 0.1, &occ), 50);
        let mut r = req(0.1, (3, 10), (56, 10), PlannerKind::AStar);
        r.safety_distance_m = 0.15;
        let a = plan(&r, &m).unwrap();
        r.kind = PlannerKind::Voronoi;
        let v = plan(&r, &m).unwrap();
        // Gap middles are 0.3 m (below) and 0.4 m (above) from obstacles; pruning may give up
        // 20 % of that.
        assert!(
            a.min_clearance_m < 0.21,
            "A* clearance {}",
            a.min_clearance_m
        );
        assert!(
            v.min_clearance_m >= 0.25,
            "Voronoi clearance {}",
            v.min_clearance_m
        );
        assert!(v.length_m >= a.length_m);
        assert!(v.waypoints_enu_m.len() < v.raw_cells);
    }

    #[test]
    fn voronoi_costs_on_hand_made_grids() {
        // Corridor 12 x 7, walls on rows 0 and 6: the diagram is rows 3 and 4 (row 3 is
        // equidistant and keeps the first wall as its site). Row 3 end to end is all on the
        // diagram: cost = 9 straight steps, no penalty.
        let occ: Vec<(u32, u32)> = (0..12).flat_map(|x| [(x, 0), (x, 6)]).collect();
        let m = PlanningMap::new(grid(12, 7, 1.0, &occ), 50);
        let p = plan(&req(1.0, (1, 3), (10, 3), PlannerKind::Voronoi), &m).unwrap();
        assert!((p.cost - 9.0).abs() < 1e-4, "{}", p.cost);
        assert_eq!(p.waypoints_enu_m, vec![Vector3::new(10.5, 3.5, 1.0)]);
        assert!((p.min_clearance_m - 3.0).abs() < 1e-6);
        // Row 1 is off the diagram: from (1,1) to (10,1) the cheapest is to climb to row 3
        // (2 diagonals, the first into row 2 penalised x2, the second onto row 3 not), run
        // along it (5 steps) and come down (2 diagonals, both off the diagram: x2).
        // Cost = 2 sqrt2 + sqrt2 + 5 + 2 * 2 sqrt2 = 7 sqrt2 + 5.
        let p = plan(&req(1.0, (1, 1), (10, 1), PlannerKind::Voronoi), &m).unwrap();
        assert!((p.cost - (7.0 * SQRT_2 + 5.0)).abs() < 1e-4, "{}", p.cost);
        // Staying on row 1 would cost 9 x 2 = 18 > 14.9.
        assert!(p.cost < 18.0);
    }

    #[test]
    fn unknown_policy_blocks_or_charges() {
        let spec = GridSpec {
            resolution_m: 1.0,
            width_cells: 10,
            height_cells: 3,
            origin_enu_m: Vector2::zeros(),
        };
        let mut data = vec![0i8; 30];
        for y in 0..3 {
            data[y * 10 + 5] = -1;
        }
        let m = PlanningMap::new(OccupancyGrid::from_data(spec, data).unwrap(), 50);
        let mut r = req(1.0, (0, 1), (9, 1), PlannerKind::AStar);
        assert_eq!(plan(&r, &m), Err(PlanError::NoPath));
        r.unknown = UnknownPolicy::AllowedWithCost(0.5);
        let p = plan(&r, &m).unwrap();
        // Nine straight steps, one of them into an unknown cell at 1.5x.
        assert!((p.cost - 9.5).abs() < 1e-9);
    }

    #[test]
    fn start_inside_the_inflated_zone_climbs_out() {
        // Wall along row 0; start 0.2 m from it with safety 0.35 m.
        let occ: Vec<(u32, u32)> = (0..20).map(|x| (x, 0)).collect();
        let m = PlanningMap::new(grid(20, 10, 0.1, &occ), 50);
        let mut r = req(0.1, (2, 2), (17, 6), PlannerKind::AStar);
        r.safety_distance_m = 0.35;
        let p = plan(&r, &m).unwrap();
        assert_eq!(
            p.waypoints_enu_m.last(),
            Some(&Vector3::new(1.75, 0.65, 1.0))
        );
        // A goal at the same clearance as the start is refused.
        r.goal_enu_m = Vector3::new(1.75, 0.25, 1.0);
        assert_eq!(plan(&r, &m), Err(PlanError::GoalOccupied));
    }

    #[test]
    fn scans_to_grid_to_plan_keeps_away_from_true_obstacles() {
        use crate::mapping::grid::InsertParams;
        use crate::mapping::scan::{Beam, RangeScan};
        // Three round pillars (centre, radius) in a 20 m x 20 m area.
        let pillars = [
            (Vector2::new(0.0, 0.0), 1.0),
            (Vector2::new(4.0, 3.0), 0.5),
            (Vector2::new(-3.0, -4.0), 0.7),
        ];
        let first_hit = |o: Vector2<f64>, dir: Vector2<f64>| {
            pillars
                .iter()
                .filter_map(|&(c, r)| {
                    // |o + t dir - c| = r, smallest t > 0.
                    let oc = o - c;
                    let b = oc.dot(&dir);
                    let disc = b * b - (oc.norm_squared() - r * r);
                    (disc >= 0.0).then(|| -b - disc.sqrt()).filter(|&t| t > 0.0)
                })
                .fold(None, |best: Option<f64>, t| {
                    Some(best.map_or(t, |b| b.min(t)))
                })
        };
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 200,
            height_cells: 200,
            origin_enu_m: Vector2::new(-10.0, -10.0),
        };
        let mut grid = OccupancyGrid::new(spec).unwrap();
        for k in 0..16 {
            let a = k as f64 * std::f64::consts::TAU / 16.0;
            let o = Vector2::new(6.5 * a.cos(), 6.5 * a.sin());
            let beams = (0..360)
                .map(|i| {
                    let angle_rad = (i as f64).to_radians();
                    let t = first_hit(o, Vector2::new(angle_rad.cos(), angle_rad.sin()));
                    Beam {
                        angle_rad,
                        range_m: t.filter(|&t| t < 8.0),
                    }
                })
                .collect();
            let scan = RangeScan {
                origin_enu_m: Vector3::new(o.x, o.y, 1.0),
                yaw_rad: 0.0,
                range_min_m: 0.05,
                range_max_m: 8.0,
                beams,
            };
            grid.insert_scan(&scan, &InsertParams::default()).unwrap();
        }
        let m = PlanningMap::new(grid, crate::planning::DEFAULT_OCCUPIED_THRESHOLD);
        for (from, to) in [
            ((-8.0, -8.0), (8.0, 8.0)),
            ((-6.0, 5.0), (6.0, -5.0)),
            ((0.0, -6.0), (0.0, 6.0)),
        ] {
            for kind in [PlannerKind::AStar, PlannerKind::Voronoi] {
                let r = PlanRequest {
                    start_enu_m: Vector3::new(from.0, from.1, 0.0),
                    goal_enu_m: Vector3::new(to.0, to.1, 0.0),
                    flight_height_m: 1.2,
                    safety_distance_m: 0.4,
                    unknown: UnknownPolicy::AllowedWithCost(1.0),
                    kind,
                    max_map_age_s: None,
                    shadow_m: 0.0,
                };
                let p = plan(&r, &m).unwrap();
                // Sample the flown polyline: never within the safety distance of a real pillar
                // surface, less one cell of discretisation.
                let mut prev = r.start_enu_m.xy();
                for w in &p.waypoints_enu_m {
                    assert_eq!(w.z, 1.2);
                    for i in 0..=100 {
                        let q = prev + (w.xy() - prev) * (i as f64 / 100.0);
                        for &(c, rad) in &pillars {
                            let gap = (q - c).norm() - rad;
                            assert!(
                                gap > 0.4 - 0.1,
                                "{kind:?} {from:?}->{to:?}: {gap:.2} m at {q:?}"
                            );
                        }
                    }
                    prev = w.xy();
                }
                assert!(p.min_clearance_m > 0.4);
            }
        }
    }

    #[test]
    fn typed_failures() {
        let occ = [
            (5, 5),
            (4, 4),
            (4, 5),
            (4, 6),
            (5, 4),
            (5, 6),
            (6, 4),
            (6, 6),
        ];
        let m = PlanningMap::new(grid(10, 10, 1.0, &occ[..]), 50);
        let r = |from, to| req(1.0, from, to, PlannerKind::AStar);
        let mut out = r((0, 0), (9, 9));
        out.start_enu_m.x = -0.5;
        assert_eq!(plan(&out, &m), Err(PlanError::StartOutsideMap));
        out = r((0, 0), (9, 9));
        out.goal_enu_m.y = 10.5;
        assert_eq!(plan(&out, &m), Err(PlanError::GoalOutsideMap));
        assert_eq!(plan(&r((4, 4), (9, 9)), &m), Err(PlanError::StartOccupied));
        assert_eq!(plan(&r((0, 0), (5, 6)), &m), Err(PlanError::GoalOccupied));
        // (6,5) is free but walled in by the ring (no corner cutting either).
        let ring = [
            (5, 4),
            (6, 4),
            (7, 4),
            (5, 5),
            (7, 5),
            (5, 6),
            (6, 6),
            (7, 6),
        ];
        let walled = PlanningMap::new(grid(10, 10, 1.0, &ring[..]), 50);
        assert_eq!(plan(&r((0, 0), (6, 5)), &walled), Err(PlanError::NoPath));
        let tiny = PlanBudget::expansions(3);
        let mut dijkstra = r((0, 0), (9, 0));
        dijkstra.kind = PlannerKind::Dijkstra;
        assert_eq!(
            Planners::default().plan(&dijkstra, &m, &tiny),
            Err(PlanError::Timeout { expansions: 4 })
        );
        let cancel = AtomicBool::new(true);
        let budget = PlanBudget {
            cancel: Some(&cancel),
            ..PlanBudget::expansions(BIG)
        };
        assert_eq!(
            Planners::default().plan(&r((0, 0), (9, 0)), &m, &budget),
            Err(PlanError::Cancelled)
        );
        let late = AtomicBool::new(true);
        let budget = PlanBudget {
            deadline_passed: Some(&late),
            ..PlanBudget::expansions(BIG)
        };
        assert!(matches!(
            Planners::default().plan(&r((0, 0), (9, 0)), &m, &budget),
            Err(PlanError::Timeout { .. })
        ));
        let stamped = PlanningMap::new(grid(10, 10, 1.0, &[]), 50).with_stamp(100.0);
        let mut fresh = r((0, 0), (9, 0));
        fresh.max_map_age_s = Some(5.0);
        let budget = PlanBudget {
            now_s: Some(107.5),
            ..PlanBudget::expansions(BIG)
        };
        assert_eq!(
            Planners::default().plan(&fresh, &stamped, &budget),
            Err(PlanError::StaleMap {
                age_s: 7.5,
                max_age_s: 5.0
            })
        );
        let mut bad = r((0, 0), (9, 0));
        bad.safety_distance_m = f64::NAN;
        assert!(matches!(plan(&bad, &m), Err(PlanError::InvalidRequest(_))));
        let mut graph = r((0, 0), (9, 0));
        graph.kind = PlannerKind::GraphAStar;
        assert_eq!(plan(&graph, &m), Err(PlanError::NoGraph));
    }
}
