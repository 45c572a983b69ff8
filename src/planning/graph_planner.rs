//! A* on the topological graph.
//!
//! In: a [`PlanRequest`] and a [`PlanningMap`] holding a [`crate::mapping::TopoGraph`].
//! Out: a [`PlannedPath`] through the graph nodes nearest the start and the goal. Waypoints are
//! the nodes' own positions (graphs are 3D: a farm has levels), then the goal at the flight
//! height. The legs start -> first node and last node -> goal are straight and not checked
//! against the grid. The heuristic is the straight-line distance scaled by the smallest
//! weight/length ratio of the graph's edges, so it stays admissible for any weights.

use std::collections::BinaryHeap;

use nalgebra::Vector3;

use super::grid_planners::polyline_length_m;
use super::{PathPlanner, PlanBudget, PlanError, PlanRequest, PlannedPath, PlanningMap};

/// A* over [`crate::mapping::TopoGraph`] nodes.
#[derive(Debug, Default)]
pub struct GraphAStarPlanner;

#[derive(Debug, Clone, Copy, PartialEq)]
struct Entry {
    f: f64,
    g: f64,
    node: usize,
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        other
            .f
            .total_cmp(&self.f)
            .then_with(|| self.g.total_cmp(&other.g))
    }
}

impl PathPlanner for GraphAStarPlanner {
    fn plan(
        &self,
        req: &PlanRequest,
        map: &PlanningMap,
        budget: &PlanBudget<'_>,
    ) -> Result<PlannedPath, PlanError> {
        req.validate(map, budget)?;
        let graph = map.graph().ok_or(PlanError::NoGraph)?;
        let nodes = graph.nodes();
        let start = graph
            .nearest_node(&req.start_enu_m)
            .ok_or(PlanError::StartOutsideMap)?;
        let goal = graph
            .nearest_node(&req.goal_enu_m)
            .ok_or(PlanError::GoalOutsideMap)?;
        let pos = |i: usize| nodes.get(i).map(|n| n.position_enu_m);
        let goal_pos = pos(goal).ok_or(PlanError::GoalOutsideMap)?;

        let scale = admissible_scale(graph);
        let h = |i: usize| pos(i).map_or(0.0, |p| (p - goal_pos).norm() * scale);

        let mut g = vec![f64::INFINITY; nodes.len()];
        let mut parent = vec![usize::MAX; nodes.len()];
        let mut closed = vec![false; nodes.len()];
        let mut heap = BinaryHeap::new();
        if let Some(gs) = g.get_mut(start) {
            *gs = 0.0;
        }
        heap.push(Entry {
            f: h(start),
            g: 0.0,
            node: start,
        });
        let mut expansions = 0usize;
        let mut found = None;
        while let Some(Entry { g: gc, node, .. }) = heap.pop() {
            if closed.get(node).copied().unwrap_or(true) || g.get(node).is_some_and(|&b| gc > b) {
                continue;
            }
            if let Some(c) = closed.get_mut(node) {
                *c = true;
            }
            if node == goal {
                found = Some(gc);
                break;
            }
            expansions += 1;
            if expansions > budget.max_expansions {
                return Err(PlanError::Timeout { expansions });
            }
            budget.check_flags(expansions)?;
            for &(next, w) in graph.neighbors(node) {
                let gn = gc + w;
                if let Some(slot) = g.get_mut(next) {
                    if gn < *slot {
                        *slot = gn;
                        if let Some(p) = parent.get_mut(next) {
                            *p = node;
                        }
                        heap.push(Entry {
                            f: gn + h(next),
                            g: gn,
                            node: next,
                        });
                    }
                }
            }
        }
        let cost = found.ok_or(PlanError::NoPath)?;
        let mut chain = vec![goal];
        let mut cur = goal;
        while cur != start {
            match parent.get(cur) {
                Some(&p) if p != usize::MAX && chain.len() <= nodes.len() => {
                    chain.push(p);
                    cur = p;
                }
                _ => return Err(PlanError::NoPath),
            }
        }
        chain.reverse();

        let mut waypoints_enu_m: Vec<Vector3<f64>> = chain
            .iter()
            .filter_map(|&i| pos(i))
            .skip_while(|p| (p - req.start_enu_m).norm() < 1e-6)
            .collect();
        let goal_point = Vector3::new(req.goal_enu_m.x, req.goal_enu_m.y, req.flight_height_m);
        if waypoints_enu_m
            .last()
            .is_none_or(|p| (p - goal_point).norm() > 1e-6)
        {
            waypoints_enu_m.push(goal_point);
        }
        let min_clearance = min_clearance_m(map, &req.start_enu_m, &waypoints_enu_m);
        Ok(PlannedPath {
            length_m: polyline_length_m(&req.start_enu_m, &waypoints_enu_m),
            waypoints_enu_m,
            raw_cells: chain.len(),
            cost,
            min_clearance_m: min_clearance,
        })
    }
}

/// The heuristic's scale: no edge of `graph` is cheaper per metre than this (at most 1), so the
/// scaled straight-line distance never overestimates.
fn admissible_scale(graph: &crate::mapping::TopoGraph) -> f64 {
    let nodes = graph.nodes();
    let pos = |i: usize| nodes.get(i).map(|n| n.position_enu_m);
    let mut scale = 1.0f64;
    for i in 0..nodes.len() {
        for &(j, w) in graph.neighbors(i) {
            if let (Some(a), Some(b)) = (pos(i), pos(j)) {
                let len = (a - b).norm();
                if len > 1e-9 {
                    scale = scale.min(w / len);
                }
            }
        }
    }
    scale
}

/// The least distance to a mapped obstacle along the legs from `start` through `waypoints`.
fn min_clearance_m(map: &PlanningMap, start: &Vector3<f64>, waypoints: &[Vector3<f64>]) -> f64 {
    let field = map.field();
    let spec = map.grid().spec();
    let mut min_clearance = f64::from(field.max_distance_m());
    let mut prev = start.xy();
    for p in waypoints {
        crate::mapping::raycast::trace_segment(spec, prev, p.xy(), |i| {
            if let Some(d) = field.distance_m(i) {
                min_clearance = min_clearance.min(f64::from(d));
            }
            true
        });
        prev = p.xy();
    }
    min_clearance
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;

    use super::*;
    use crate::mapping::graph::{FarmSpec, TopoGraph};
    use crate::mapping::grid::{GridSpec, OccupancyGrid};
    use crate::planning::{PlannerKind, UnknownPolicy};

    fn farm_map(levels: Vec<f64>) -> PlanningMap {
        let farm = FarmSpec {
            rows: 2,
            beds_per_row: 3,
            bed_length_m: 2.0,
            bed_width_m: 1.0,
            aisle_width_m: 1.0,
            origin_enu_m: Vector2::zeros(),
            level_heights_m: levels,
        };
        let spec = GridSpec {
            resolution_m: 0.5,
            width_cells: 16,
            height_cells: 10,
            origin_enu_m: Vector2::zeros(),
        };
        PlanningMap::new(OccupancyGrid::new(spec).unwrap(), 50)
            .with_graph(TopoGraph::from_indoor_farm(&farm).unwrap())
    }

    fn req(start: Vector3<f64>, goal: Vector3<f64>) -> PlanRequest {
        PlanRequest {
            start_enu_m: start,
            goal_enu_m: goal,
            flight_height_m: goal.z,
            safety_distance_m: 0.0,
            unknown: UnknownPolicy::Blocked,
            kind: PlannerKind::GraphAStar,
            max_map_age_s: None,
            shadow_m: 0.0,
        }
    }

    #[test]
    fn farm_route_goes_round_the_west_head_corridor() {
        // Aisles at y 0.5, 2.5, 4.5; bed 0 centre x 2, west ends x 0.5. Bed 0 of aisle 0 to bed
        // 0 of aisle 2: 1.5 + 2 + 2 + 1.5 = 7 m (the east way is 5.5 + 4 + 5.5).
        let m = farm_map(vec![1.0]);
        let r = req(Vector3::new(2.0, 0.5, 1.0), Vector3::new(2.0, 4.5, 1.0));
        let p = GraphAStarPlanner
            .plan(&r, &m, &PlanBudget::expansions(1000))
            .unwrap();
        assert!((p.cost - 7.0).abs() < 1e-9);
        assert_eq!(p.raw_cells, 5);
        assert_eq!(
            p.waypoints_enu_m,
            vec![
                Vector3::new(0.5, 0.5, 1.0),
                Vector3::new(0.5, 2.5, 1.0),
                Vector3::new(0.5, 4.5, 1.0),
                Vector3::new(2.0, 4.5, 1.0),
            ]
        );
        assert!((p.length_m - 7.0).abs() < 1e-9);
    }

    #[test]
    fn level_change_uses_a_vertical_edge_at_an_aisle_end() {
        let m = farm_map(vec![1.0, 3.0]);
        // Bed 2 of aisle 1 (x 6) on level 0 to the same bed on level 1: via the east end
        // (x 7.5): 1.5 + 2 + 1.5.
        let r = req(Vector3::new(6.0, 2.5, 1.0), Vector3::new(6.0, 2.5, 3.0));
        let p = GraphAStarPlanner
            .plan(&r, &m, &PlanBudget::expansions(1000))
            .unwrap();
        assert!((p.cost - 5.0).abs() < 1e-9);
        assert_eq!(
            p.waypoints_enu_m.first(),
            Some(&Vector3::new(7.5, 2.5, 1.0))
        );
        let tiny = PlanBudget::expansions(1);
        assert!(matches!(
            GraphAStarPlanner.plan(&r, &m, &tiny),
            Err(PlanError::Timeout { .. })
        ));
    }
}
