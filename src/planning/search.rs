//! Best-first search on an 8-connected grid (A* or Dijkstra), reusable buffers.
//!
//! In: start and goal cell indices, a per-move cost multiplier (`None` = blocked), whether to use
//! the octile heuristic, and the budget. Out: the cell path (start and goal included) and its
//! cost in metres weighted by the multipliers. Binary heap with lazy deletion; closed cells are
//! never reopened (the octile heuristic is consistent because multipliers are >= 1).
//!
//! Costs are fixed-point integers (a cell edge is 1 000 000 units, a diagonal 1 414 214, the
//! heuristic's diagonal excess rounded down so it stays consistent). Exact ties matter: with
//! floating-point `f` values the many equal-cost paths of a grid differ by rounding noise, the
//! larger-`g` tie-break stops working and A* expands far more cells.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::mapping::grid::GridSpec;

use super::{PlanBudget, PlanError};

/// How often (in expansions) the cancel and deadline flags are read.
const FLAG_CHECK_PERIOD: usize = 1024;

/// Cost units per cell edge.
const UNIT: u64 = 1_000_000;
/// Diagonal step in units, rounded up (>= the heuristic's diagonal).
const DIAG_UNITS: f64 = 1_414_214.0;
/// The heuristic's extra cost of a diagonal over a straight step, rounded down.
const H_DIAG_EXCESS: u64 = 414_213;

#[derive(Debug, Clone, Copy)]
struct Entry {
    f: u64,
    g: u64,
    idx: u32,
}

impl PartialEq for Entry {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}
impl Ord for Entry {
    /// Max-heap order: smallest `f` first, then largest `g` (deeper nodes break ties).
    fn cmp(&self, other: &Self) -> Ordering {
        other.f.cmp(&self.f).then_with(|| self.g.cmp(&other.g))
    }
}

/// Buffers kept between searches; a generation stamp avoids clearing them.
#[derive(Debug, Default)]
pub(crate) struct SearchScratch {
    /// `generation << 1` = seen this search, `| 1` = closed.
    stamp: Vec<u32>,
    generation: u32,
    g: Vec<u64>,
    parent: Vec<u32>,
    heap: BinaryHeap<Entry>,
}

impl SearchScratch {
    fn reset(&mut self, cells: usize) {
        if self.stamp.len() != cells {
            self.stamp = vec![0; cells];
            self.g = vec![0; cells];
            self.parent = vec![0; cells];
            self.generation = 0;
        }
        self.generation += 1;
        if self.generation >= 1 << 30 {
            self.stamp.iter_mut().for_each(|s| *s = 0);
            self.generation = 1;
        }
        self.heap.clear();
    }
}

/// A found path.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct SearchPath {
    pub cells: Vec<usize>,
    pub cost: f64,
    pub expansions: usize,
}

/// Searches from `start` to `goal`. `step(from, to)` returns the cost multiplier (>= 1) of
/// entering `to` from `from`, or `None` if blocked. Diagonal moves also need both side cells
/// enterable (no corner cutting).
pub(crate) fn search(
    scratch: &mut SearchScratch,
    spec: &GridSpec,
    start: usize,
    goal: usize,
    use_heuristic: bool,
    budget: &PlanBudget<'_>,
    step: impl Fn(usize, usize) -> Option<f64>,
) -> Result<SearchPath, PlanError> {
    let n = spec.cell_count();
    if start >= n || goal >= n {
        return Err(PlanError::NoPath);
    }
    budget.check_flags(0)?;
    scratch.reset(n);
    let gen = scratch.generation;
    let w = spec.width_cells as usize;
    let h = spec.height_cells as usize;
    let (goal_x, goal_y) = (goal % w, goal / w);
    let heuristic = |x: usize, y: usize| -> u64 {
        if !use_heuristic {
            return 0;
        }
        let dx = x.abs_diff(goal_x) as u64;
        let dy = y.abs_diff(goal_y) as u64;
        dx.max(dy) * UNIT + dx.min(dy) * H_DIAG_EXCESS
    };
    let units = |multiplier: f64, base: f64| (multiplier * base).round() as u64;

    let SearchScratch {
        stamp,
        g,
        parent,
        heap,
        ..
    } = scratch;
    let (Some(s), Some(gs)) = (stamp.get_mut(start), g.get_mut(start)) else {
        return Err(PlanError::NoPath);
    };
    *s = gen << 1;
    *gs = 0;
    if let Some(p) = parent.get_mut(start) {
        *p = start as u32;
    }
    heap.push(Entry {
        f: heuristic(start % w, start / w),
        g: 0,
        idx: start as u32,
    });

    let mut expansions = 0usize;
    while let Some(Entry { g: g_cur, idx, .. }) = heap.pop() {
        let cur = idx as usize;
        let Some(st) = stamp.get_mut(cur) else {
            continue;
        };
        if *st & 1 == 1 || g.get(cur).is_some_and(|&best| g_cur > best) {
            continue; // stale heap entry
        }
        *st |= 1;
        if cur == goal {
            return Ok(SearchPath {
                cells: walk_back(parent, start, goal),
                cost: g_cur as f64 / UNIT as f64 * spec.resolution_m,
                expansions,
            });
        }
        expansions += 1;
        if expansions > budget.max_expansions {
            return Err(PlanError::Timeout { expansions });
        }
        if expansions.is_multiple_of(FLAG_CHECK_PERIOD) {
            budget.check_flags(expansions)?;
        }

        let x = cur % w;
        let y = cur / w;
        // Orthogonal neighbours: north, east, south, west, with their coordinates.
        let ortho = [
            (y + 1 < h).then(|| (cur + w, x, y + 1)),
            (x + 1 < w).then(|| (cur + 1, x + 1, y)),
            (y > 0).then(|| (cur - w, x, y - 1)),
            (x > 0).then(|| (cur - 1, x - 1, y)),
        ];
        let open = ortho.map(|o| o.and_then(|(j, jx, jy)| step(cur, j).map(|m| (j, jx, jy, m))));
        // Diagonals: NE (N, E), SE (S, E), SW (S, W), NW (N, W).
        let diagonal = [(0, 1), (2, 1), (2, 3), (0, 3)].map(|(a, b)| {
            let (Some((ja, _, ya, _)), Some((jb, xb, _, _))) = (open[a], open[b]) else {
                return None;
            };
            let j = ja + jb - cur;
            step(cur, j).map(|m| (j, xb, ya, units(m, DIAG_UNITS)))
        });
        let moves = open
            .into_iter()
            .map(|o| o.map(|(j, jx, jy, m)| (j, jx, jy, units(m, UNIT as f64))))
            .chain(diagonal);
        for (j, jx, jy, cost) in moves.flatten() {
            let g_new = g_cur + cost;
            let (Some(sj), Some(gj)) = (stamp.get_mut(j), g.get_mut(j)) else {
                continue;
            };
            if *sj >> 1 == gen {
                if *sj & 1 == 1 || g_new >= *gj {
                    continue;
                }
            } else {
                *sj = gen << 1;
            }
            *gj = g_new;
            if let Some(p) = parent.get_mut(j) {
                *p = cur as u32;
            }
            heap.push(Entry {
                f: g_new + heuristic(jx, jy),
                g: g_new,
                idx: j as u32,
            });
        }
    }
    Err(PlanError::NoPath)
}

fn walk_back(parent: &[u32], start: usize, goal: usize) -> Vec<usize> {
    let mut cells = vec![goal];
    let mut cur = goal;
    // A parent chain is at most as long as the number of cells.
    for _ in 0..parent.len() {
        if cur == start {
            break;
        }
        match parent.get(cur) {
            Some(&p) => {
                cur = p as usize;
                cells.push(cur);
            }
            None => break,
        }
    }
    cells.reverse();
    cells
}
