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

        // Admissible scale: no edge is cheaper per metre than this.
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

        let mut waypoints_enu_m: Vec<Vector3<f64>> = chain.iter().filter_map(|&i| pos(i)).collect();
        let goal_point = Vector3::new(req.goal_enu_m.x, req.goal_enu_m.y, req.flight_height_m);
        if waypoints_enu_m
            .last()
            .is_none_or(|p| (p - goal_point).norm() > 1e-6)
        {
            waypoints_enu_m.push(goal_point);
        }
        let field = map.field();
        let spec = map.grid().spec();
        let mut min_clearance = f64::from(field.max_distance_m());
        let mut prev = req.start_enu_m.xy();
        for p in &waypoints_enu_m {
            crate::mapping::raycast::trace_segment(spec, prev, p.xy(), |i| {
                if let Some(d) = field.distance_m(i) {
                    min_clearance = min_clearance.min(f64::from(d));
                }
                true
            });
            prev = p.xy();
        }
        Ok(PlannedPath {
            length_m: polyline_length_m(&req.start_enu_m, &waypoints_enu_m),
            waypoints_enu_m,
            raw_cells: chain.len(),
            cost,
            min_clearance_m: min_clearance,
        })
    }
}
