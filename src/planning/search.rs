//! Best-first search on an 8-connected grid (A* or Dijkstra), reusable buffers.
//!
//! In: start and goal cell indices, a per-move cost multiplier (`None` = blocked), whether to use
//! the octile heuristic, and the budget. Out: the cell path (start and goal included) and its
//! cost in metres weighted by the multipliers. Binary heap with lazy deletion; closed cells are
//! never reopened (the octile heuristic is consistent because multipliers are >= 1).

use std::cmp::Ordering;
use std::collections::BinaryHeap;
use std::f64::consts::SQRT_2;

use crate::mapping::grid::GridSpec;

use super::{PlanBudget, PlanError};

/// How often (in expansions) the cancel and deadline flags are read.
const FLAG_CHECK_PERIOD: usize = 1024;

#[derive(Debug, Clone, Copy)]
struct Entry {
    f: f64,
    g: f64,
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
        other
            .f
            .total_cmp(&self.f)
            .then_with(|| self.g.total_cmp(&other.g))
    }
}

/// Buffers kept between searches; a generation stamp avoids clearing them.
#[derive(Debug, Default)]
pub(crate) struct SearchScratch {
    /// `generation << 1` = seen this search, `| 1` = closed.
    stamp: Vec<u32>,
    generation: u32,
    g: Vec<f64>,
    parent: Vec<u32>,
    heap: BinaryHeap<Entry>,
}

impl SearchScratch {
    fn reset(&mut self, cells: usize) {
        if self.stamp.len() != cells {
            self.stamp = vec![0; cells];
            self.g = vec![0.0; cells];
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

/// Octile distance in metres between two flat indices.
pub(crate) fn octile_m(spec: &GridSpec, a: usize, b: usize) -> f64 {
    let w = spec.width_cells as usize;
    let dx = (a % w).abs_diff(b % w) as f64;
    let dy = (a / w).abs_diff(b / w) as f64;
    let (lo, hi) = if dx < dy { (dx, dy) } else { (dy, dx) };
    (hi + (SQRT_2 - 1.0) * lo) * spec.resolution_m
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
    let res = spec.resolution_m;
    let diag = res * SQRT_2;
    let w = spec.width_cells as usize;
    let h = spec.height_cells as usize;
    let heuristic = |i: usize| {
        if use_heuristic {
            octile_m(spec, i, goal)
        } else {
            0.0
        }
    };

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
    *gs = 0.0;
    if let Some(p) = parent.get_mut(start) {
        *p = start as u32;
    }
    heap.push(Entry {
        f: heuristic(start),
        g: 0.0,
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
                cost: g_cur,
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
        // Orthogonal neighbours: north, east, south, west.
        let ortho = [
            (y + 1 < h).then(|| cur + w),
            (x + 1 < w).then(|| cur + 1),
            (y > 0).then(|| cur - w),
            (x > 0).then(|| cur - 1),
        ];
        let mult = ortho.map(|o| o.and_then(|j| step(cur, j).map(|m| (j, m))));
        // Diagonals: NE (N, E), SE (S, E), SW (S, W), NW (N, W).
        let diagonal = [(0, 1), (2, 1), (2, 3), (0, 3)].map(|(a, b)| {
            let (Some((ja, _)), Some((jb, _))) = (mult[a], mult[b]) else {
                return None;
            };
            let j = ja + jb - cur;
            step(cur, j).map(|m| (j, m * diag))
        });
        let moves = mult
            .into_iter()
            .map(|o| o.map(|(j, m)| (j, m * res)))
            .chain(diagonal);
        for (j, cost) in moves.flatten() {
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
                f: g_new + heuristic(j),
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
