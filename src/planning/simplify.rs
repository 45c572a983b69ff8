//! Raw cell path to a short waypoint list: greedy line-of-sight pruning.
//!
//! In: the raw cell path, each cell's clearance and a predicate saying whether a cell may be
//! crossed by a shortcut whose replaced stretch of raw path had a given minimum clearance.
//! Out: the anchor cells kept (first and last raw cells included). Planners pass "passable, and
//! either outside the safety distance or no closer than the replaced stretch" for shortest paths
//! (shortcuts may cut corners down to the safety distance, and never deeper into the inflated zone
//! than the raw path went when escaping it), and "no closer than the replaced stretch" for the
//! Voronoi planner (its clearance is kept).

use nalgebra::Vector2;

use crate::mapping::grid::GridSpec;
use crate::mapping::raycast::{trace_segment, TraceEnd};

fn center(spec: &GridSpec, i: usize) -> Option<Vector2<f64>> {
    spec.cell_of_index(i).map(|c| spec.cell_center_enu_m(c))
}

/// Whether every cell on the segment between two cell centres satisfies `ok`.
pub(crate) fn visible(spec: &GridSpec, a: usize, b: usize, ok: impl Fn(usize) -> bool) -> bool {
    let (Some(pa), Some(pb)) = (center(spec, a), center(spec, b)) else {
        return false;
    };
    trace_segment(spec, pa, pb, ok) == TraceEnd::EndInside
}

/// Smallest clearance over the cells crossed by the polyline through `anchors`.
pub(crate) fn polyline_min_clearance(
    spec: &GridSpec,
    anchors: &[usize],
    clearance: impl Fn(usize) -> f32,
) -> f32 {
    let mut min = anchors.first().map_or(f32::INFINITY, |&a| clearance(a));
    for pair in anchors.windows(2) {
        if let (Some(pa), Some(pb)) = (center(spec, pair[0]), center(spec, pair[1])) {
            trace_segment(spec, pa, pb, |i| {
                min = min.min(clearance(i));
                true
            });
        }
    }
    min
}

/// Greedy pruning: from each anchor, extend the shortcut along the raw path until it first
/// fails, then anchor at the last raw cell it reached. A second pass drops any anchor whose two
/// neighbours see each other (the first pass stops at the first failure, so a later cell may
/// still have been visible).
pub(crate) fn prune(
    spec: &GridSpec,
    cells: &[usize],
    clearance: impl Fn(usize) -> f32,
    ok: impl Fn(usize, f32) -> bool,
) -> Vec<usize> {
    if cells.is_empty() {
        return Vec::new();
    }
    // Positions in `cells` of the anchors.
    let mut kept = vec![0usize];
    let mut a = 0;
    while let (Some(&from), Some(&next)) = (cells.get(a), cells.get(a + 1)) {
        let mut sub_min = clearance(from).min(clearance(next));
        let mut best = a + 1;
        while let Some(&to) = cells.get(best + 1) {
            let m = sub_min.min(clearance(to));
            if !visible(spec, from, to, |c| ok(c, m)) {
                break;
            }
            sub_min = m;
            best += 1;
        }
        kept.push(best);
        a = best;
    }
    let mut k = 1;
    while let (Some(&i), Some(&j)) = (kept.get(k - 1), kept.get(k + 1)) {
        let stretch = cells.get(i..=j).unwrap_or_default();
        let m = stretch
            .iter()
            .map(|&c| clearance(c))
            .fold(f32::INFINITY, f32::min);
        let (Some(&from), Some(&to)) = (cells.get(i), cells.get(j)) else {
            break;
        };
        if visible(spec, from, to, |c| ok(c, m)) {
            kept.remove(k);
        } else {
            k += 1;
        }
    }
    kept.iter().filter_map(|&i| cells.get(i).copied()).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn straight_and_l_shaped_paths_keep_only_corners() {
        let spec = GridSpec {
            resolution_m: 1.0,
            width_cells: 5,
            height_cells: 5,
            origin_enu_m: Vector2::zeros(),
        };
        // Wall at (1..=4, 1): an L path from (0,0) up to (0,4) then right to (4,4)... the
        // straight line (0,0)->(4,4) crosses the wall, so one corner remains.
        let blocked = |i: usize| (6..=9).contains(&i);
        let path: Vec<usize> = vec![0, 5, 10, 15, 20, 21, 22, 23, 24];
        let anchors = prune(&spec, &path, |_| 1.0, |c, _| !blocked(c));
        assert_eq!(anchors.first(), Some(&0));
        assert_eq!(anchors.last(), Some(&24));
        assert!(anchors.len() <= 3, "{anchors:?}");
        for pair in anchors.windows(2) {
            assert!(visible(&spec, pair[0], pair[1], |c| !blocked(c)));
        }
        let straight: Vec<usize> = vec![0, 1, 2, 3, 4];
        assert_eq!(prune(&spec, &straight, |_| 1.0, |_, _| true), vec![0, 4]);
    }
}
