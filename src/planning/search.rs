//! Best-first search on an 8-connected grid (A* or Dijkstra), reusable buffers.
//!
//! In: start and goal cell indices, a per-move cost multiplier (`None` = blocked), whether to use
//! the octile heuristic, and the budget. Out: the cell path (start and goal included) and its
//! cost in metres weighted by the multipliers. Binary heap with lazy deletion; closed cells are
//! never reopened (the octile heuristic is consistent because multipliers are >= 1).
//!
//! Costs are fixed-point integers (a cell edge is 65 536 units, a diagonal 92 682, the
//! heuristic's diagonal excess rounded down so it stays consistent; reported costs are within
//! 2e-6 per diagonal step of the exact value). Exact ties matter: with floating-point `f` values
//! the many equal-cost paths of a grid differ by rounding noise and a tie-break cannot work.
//! Ties on `f` go to the smaller heuristic (the deeper node), packed into one `u64` heap key.

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use crate::mapping::grid::GridSpec;

use super::{PlanBudget, PlanError};

/// How often (in expansions) the cancel and deadline flags are read.
const FLAG_CHECK_PERIOD: usize = 1024;

/// Cost units per cell edge.
const UNIT: u64 = 1 << 16;
/// Diagonal step in units (sqrt 2 * 65 536 = 92 681.9, rounded up).
const DIAG_UNITS: f64 = 92_682.0;
/// The heuristic's extra cost of a diagonal over a straight step (27 145.7, rounded down).
const H_DIAG_EXCESS: u64 = 27_145;
/// Low key bits holding the tie-break (the heuristic, coarsened and saturated).
const TIE_BITS: u32 = 20;
const TIE_SHIFT: u32 = 6;

/// Open list: a binary min-heap of `(key, cell)` with lazy deletion (stale duplicates are
/// skipped when popped because their cell is already closed).
#[derive(Debug, Default)]
struct OpenList(BinaryHeap<Reverse<(u64, u32)>>);

impl OpenList {
    fn clear(&mut self) {
        self.0.clear();
    }

    fn push(&mut self, key: u64, cell: u32) {
        self.0.push(Reverse((key, cell)));
    }

    fn pop(&mut self) -> Option<u32> {
        self.0.pop().map(|Reverse((_, cell))| cell)
    }
}

fn heap_key(g: u64, h: u64) -> u64 {
    let tie = (h >> TIE_SHIFT).min((1 << TIE_BITS) - 1);
    g.saturating_add(h).saturating_mul(1 << TIE_BITS) | tie
}

/// Per-cell search state, kept together for locality.
#[derive(Debug, Clone, Copy, Default)]
struct Node {
    g: u64,
    parent: u32,
    /// `generation << 1` = seen in this search, `| 1` = closed.
    stamp: u32,
}

/// Buffers kept between searches; a generation stamp avoids clearing them.
#[derive(Debug, Default)]
pub(crate) struct SearchScratch {
    nodes: Vec<Node>,
    generation: u32,
    heap: OpenList,
}

impl SearchScratch {
    fn reset(&mut self, cells: usize) {
        if self.nodes.len() != cells {
            self.nodes = vec![Node::default(); cells];
            self.generation = 0;
        }
        self.generation += 1;
        if self.generation >= 1 << 30 {
            self.nodes.iter_mut().for_each(|n| n.stamp = 0);
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
    // `+ 0.5` then truncation: `f64::round` is a libm call in this hot loop.
    let units = |multiplier: f64, base: f64| (multiplier * base + 0.5) as u64;

    let SearchScratch { nodes, heap, .. } = scratch;
    let Some(s) = nodes.get_mut(start) else {
        return Err(PlanError::NoPath);
    };
    *s = Node {
        g: 0,
        parent: start as u32,
        stamp: gen << 1,
    };
    heap.push(heap_key(0, heuristic(start % w, start / w)), start as u32);

    let mut expansions = 0usize;
    while let Some(idx) = heap.pop() {
        let cur = idx as usize;
        let Some(node) = nodes.get_mut(cur) else {
            continue;
        };
        if node.stamp & 1 == 1 {
            continue; // stale duplicate of a closed cell
        }
        node.stamp |= 1;
        let g_cur = node.g;
        if cur == goal {
            return Ok(SearchPath {
                cells: walk_back(nodes, start, goal),
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
        // Orthogonal neighbours (north, east, south, west) with their coordinates.
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
            let g_new = g_cur.saturating_add(cost);
            let Some(nj) = nodes.get_mut(j) else {
                continue;
            };
            if nj.stamp >> 1 == gen && (nj.stamp & 1 == 1 || g_new >= nj.g) {
                continue;
            }
            *nj = Node {
                g: g_new,
                parent: cur as u32,
                stamp: gen << 1,
            };
            heap.push(heap_key(g_new, heuristic(jx, jy)), j as u32);
        }
    }
    Err(PlanError::NoPath)
}

fn walk_back(nodes: &[Node], start: usize, goal: usize) -> Vec<usize> {
    let mut cells = vec![goal];
    let mut cur = goal;
    // A parent chain is at most as long as the number of cells.
    for _ in 0..nodes.len() {
        if cur == start {
            break;
        }
        match nodes.get(cur) {
            Some(node) => {
                cur = node.parent as usize;
                cells.push(cur);
            }
            None => break,
        }
    }
    cells.reverse();
    cells
}

/// Jump point search (Harabor and Grastien) for uniform-cost grids, with the same moves as
/// [`search`] (8-connected, no corner cutting) and the same fixed-point costs, so it returns the
/// same optimal cost while pushing only jump points on the heap. `walkable(x, y)` must be false
/// outside the grid. Pruning and forced-neighbour rules are those of the no-corner-cutting
/// variant: a straight move is forced to turn where a side cell is open but the side cell behind
/// is blocked; a diagonal move stops where a straight jump along either component finds a jump
/// point. The returned cells are the full cell path (segments between jump points filled in).
pub(crate) fn jump_point_search(
    scratch: &mut SearchScratch,
    spec: &GridSpec,
    start: usize,
    goal: usize,
    budget: &PlanBudget<'_>,
    walkable: impl Fn(i64, i64) -> bool,
) -> Result<SearchPath, PlanError> {
    let n = spec.cell_count();
    if start >= n || goal >= n {
        return Err(PlanError::NoPath);
    }
    budget.check_flags(0)?;
    scratch.reset(n);
    let gen = scratch.generation;
    let w = spec.width_cells as i64;
    let (gx, gy) = ((goal as i64) % w, (goal as i64) / w);
    let heuristic = |x: i64, y: i64| -> u64 {
        let dx = x.abs_diff(gx);
        let dy = y.abs_diff(gy);
        dx.max(dy) * UNIT + dx.min(dy) * H_DIAG_EXCESS
    };
    let index = |x: i64, y: i64| (y * w + x) as usize;

    let goal_xy = (gx, gy);

    let SearchScratch { nodes, heap, .. } = scratch;
    let Some(s) = nodes.get_mut(start) else {
        return Err(PlanError::NoPath);
    };
    *s = Node {
        g: 0,
        parent: start as u32,
        stamp: gen << 1,
    };
    let (sx, sy) = ((start as i64) % w, (start as i64) / w);
    heap.push(heap_key(0, heuristic(sx, sy)), start as u32);

    let mut expansions = 0usize;
    let mut dirs: Vec<(i64, i64)> = Vec::with_capacity(8);
    while let Some(idx) = heap.pop() {
        let cur = idx as usize;
        let Some(node) = nodes.get_mut(cur) else {
            continue;
        };
        if node.stamp & 1 == 1 {
            continue;
        }
        node.stamp |= 1;
        let (g_cur, parent) = (node.g, node.parent as usize);
        if cur == goal {
            return Ok(SearchPath {
                cells: fill_segments(&walk_back(nodes, start, goal), spec.width_cells as usize),
                cost: g_cur as f64 / UNIT as f64 * spec.resolution_m,
                expansions,
            });
        }
        expansions += 1;
        if expansions > budget.max_expansions {
            return Err(PlanError::Timeout { expansions });
        }
        if expansions.is_multiple_of(FLAG_CHECK_PERIOD / 16) {
            budget.check_flags(expansions)?;
        }

        let (x, y) = ((cur as i64) % w, (cur as i64) / w);
        let from = (cur != start).then(|| ((parent as i64) % w, (parent as i64) / w));
        pruned_directions(&walkable, (x, y), from, &mut dirs);
        for &(dx, dy) in &dirs {
            let Some((jx, jy)) = jump(&walkable, goal_xy, (x + dx, y + dy), (dx, dy)) else {
                continue;
            };
            let steps = (jx - x).unsigned_abs().max((jy - y).unsigned_abs());
            let cost = if dx != 0 && dy != 0 {
                steps * DIAG_UNITS as u64
            } else {
                steps * UNIT
            };
            let g_new = g_cur.saturating_add(cost);
            let j = index(jx, jy);
            let Some(nj) = nodes.get_mut(j) else {
                continue;
            };
            if nj.stamp >> 1 == gen && (nj.stamp & 1 == 1 || g_new >= nj.g) {
                continue;
            }
            *nj = Node {
                g: g_new,
                parent: cur as u32,
                stamp: gen << 1,
            };
            heap.push(heap_key(g_new, heuristic(jx, jy)), j as u32);
        }
    }
    Err(PlanError::NoPath)
}

/// Straight jump from `at` along `(dx, 0)` or `(0, dy)`: the first cell that is the goal or has
/// a forced neighbour, `None` at a blocked cell.
fn jump_straight(
    walkable: &impl Fn(i64, i64) -> bool,
    goal: (i64, i64),
    (mut x, mut y): (i64, i64),
    (dx, dy): (i64, i64),
) -> Option<(i64, i64)> {
    loop {
        if !walkable(x, y) {
            return None;
        }
        if (x, y) == goal {
            return Some((x, y));
        }
        let forced = if dx != 0 {
            (walkable(x, y - 1) && !walkable(x - dx, y - 1))
                || (walkable(x, y + 1) && !walkable(x - dx, y + 1))
        } else {
            (walkable(x - 1, y) && !walkable(x - 1, y - dy))
                || (walkable(x + 1, y) && !walkable(x + 1, y - dy))
        };
        if forced {
            return Some((x, y));
        }
        x += dx;
        y += dy;
    }
}

/// Jump from `at` along `step`: straight as [`jump_straight`]; diagonal until the goal, a cell
/// from which a straight jump along either component finds a jump point, or a corner it may not
/// cut.
fn jump(
    walkable: &impl Fn(i64, i64) -> bool,
    goal: (i64, i64),
    (mut x, mut y): (i64, i64),
    (dx, dy): (i64, i64),
) -> Option<(i64, i64)> {
    if dx == 0 || dy == 0 {
        return jump_straight(walkable, goal, (x, y), (dx, dy));
    }
    loop {
        if !walkable(x, y) {
            return None;
        }
        if (x, y) == goal {
            return Some((x, y));
        }
        if jump_straight(walkable, goal, (x + dx, y), (dx, 0)).is_some()
            || jump_straight(walkable, goal, (x, y + dy), (0, dy)).is_some()
        {
            return Some((x, y));
        }
        if !(walkable(x + dx, y) && walkable(x, y + dy)) {
            return None;
        }
        x += dx;
        y += dy;
    }
}

/// The directions worth searching from `(x, y)`, reached from `from` (`None` at the start:
/// every straight direction and every diagonal whose corners are open), into `dirs`.
fn pruned_directions(
    walkable: &impl Fn(i64, i64) -> bool,
    (x, y): (i64, i64),
    from: Option<(i64, i64)>,
    dirs: &mut Vec<(i64, i64)>,
) {
    dirs.clear();
    let Some((px, py)) = from else {
        for (dx, dy) in [(0, 1), (1, 0), (0, -1), (-1, 0)] {
            dirs.push((dx, dy));
        }
        for (dx, dy) in [(1, 1), (1, -1), (-1, -1), (-1, 1)] {
            if walkable(x + dx, y) && walkable(x, y + dy) {
                dirs.push((dx, dy));
            }
        }
        return;
    };
    let (dx, dy) = ((x - px).signum(), (y - py).signum());
    if dx != 0 && dy != 0 {
        let (h_open, v_open) = (walkable(x + dx, y), walkable(x, y + dy));
        if v_open {
            dirs.push((0, dy));
        }
        if h_open {
            dirs.push((dx, 0));
        }
        if h_open && v_open {
            dirs.push((dx, dy));
        }
    } else if dx != 0 {
        let (next, up, down) = (walkable(x + dx, y), walkable(x, y + 1), walkable(x, y - 1));
        if next {
            dirs.push((dx, 0));
            if up {
                dirs.push((dx, 1));
            }
            if down {
                dirs.push((dx, -1));
            }
        }
        if up {
            dirs.push((0, 1));
        }
        if down {
            dirs.push((0, -1));
        }
    } else {
        let (next, right, left) = (walkable(x, y + dy), walkable(x + 1, y), walkable(x - 1, y));
        if next {
            dirs.push((0, dy));
            if right {
                dirs.push((1, dy));
            }
            if left {
                dirs.push((-1, dy));
            }
        }
        if right {
            dirs.push((1, 0));
        }
        if left {
            dirs.push((-1, 0));
        }
    }
}

/// Expands a chain of jump points (each pair on a straight or diagonal line) into every cell.
fn fill_segments(points: &[usize], w: usize) -> Vec<usize> {
    let mut cells: Vec<usize> = points.first().copied().into_iter().collect();
    for pair in points.windows(2) {
        let (ax, ay) = ((pair[0] % w) as i64, (pair[0] / w) as i64);
        let (bx, by) = ((pair[1] % w) as i64, (pair[1] / w) as i64);
        let (dx, dy) = ((bx - ax).signum(), (by - ay).signum());
        let steps = (bx - ax).abs().max((by - ay).abs());
        for k in 1..=steps {
            cells.push(((ay + dy * k) * w as i64 + ax + dx * k) as usize);
        }
    }
    cells
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    use super::*;

    fn spec(w: u32, h: u32) -> GridSpec {
        GridSpec {
            resolution_m: 1.0,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        }
    }

    /// Whether consecutive cells are 8-neighbours with no corner cut through a blocked cell.
    fn valid_path(cells: &[usize], w: usize, blocked: &[bool]) -> bool {
        cells.iter().all(|&c| !blocked[c])
            && cells.windows(2).all(|p| {
                let (ax, ay) = ((p[0] % w) as i64, (p[0] / w) as i64);
                let (bx, by) = ((p[1] % w) as i64, (p[1] / w) as i64);
                let (dx, dy) = (bx - ax, by - ay);
                dx.abs() <= 1
                    && dy.abs() <= 1
                    && (dx, dy) != (0, 0)
                    && (dx == 0
                        || dy == 0
                        || (!blocked[(ay * w as i64 + bx) as usize]
                            && !blocked[(by * w as i64 + ax) as usize]))
            })
    }

    #[test]
    fn jump_point_search_matches_a_star_on_random_grids() {
        let (w, h) = (47usize, 39usize);
        let s = spec(w as u32, h as u32);
        let budget = PlanBudget::expansions(usize::MAX);
        let mut scratch = SearchScratch::default();
        for density in [0.0, 0.05, 0.2, 0.35] {
            for seed in 0..40 {
                let mut rng = ChaCha8Rng::seed_from_u64(seed);
                let blocked: Vec<bool> = (0..w * h).map(|_| rng.gen_bool(density)).collect();
                let start = rng.gen_range(0..w * h);
                let goal = rng.gen_range(0..w * h);
                if blocked[start] || blocked[goal] {
                    continue;
                }
                let a = search(&mut scratch, &s, start, goal, true, &budget, |_, j| {
                    (!blocked[j]).then_some(1.0)
                });
                let walk = |x: i64, y: i64| {
                    x >= 0
                        && y >= 0
                        && x < w as i64
                        && y < h as i64
                        && !blocked[y as usize * w + x as usize]
                };
                let j = jump_point_search(&mut scratch, &s, start, goal, &budget, walk);
                match (a, j) {
                    (Ok(a), Ok(j)) => {
                        assert_eq!(a.cost, j.cost, "density {density} seed {seed}");
                        assert!(
                            valid_path(&j.cells, w, &blocked),
                            "density {density} seed {seed}"
                        );
                        assert_eq!(j.cells.first(), Some(&start));
                        assert_eq!(j.cells.last(), Some(&goal));
                    }
                    (Err(PlanError::NoPath), Err(PlanError::NoPath)) => {}
                    (a, j) => panic!("density {density} seed {seed}: A* {a:?}, JPS {j:?}"),
                }
            }
        }
    }

    #[test]
    fn dijkstra_and_a_star_agree() {
        let s = spec(30, 30);
        let budget = PlanBudget::expansions(usize::MAX);
        let mut scratch = SearchScratch::default();
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let blocked: Vec<bool> = (0..900)
            .map(|i| i != 0 && i != 899 && rng.gen_bool(0.25))
            .collect();
        let step = |_: usize, j: usize| (!blocked[j]).then_some(1.0);
        let a = search(&mut scratch, &s, 0, 899, true, &budget, step);
        let d = search(&mut scratch, &s, 0, 899, false, &budget, step);
        match (a, d) {
            (Ok(a), Ok(d)) => {
                assert_eq!(a.cost, d.cost);
                assert!(a.expansions < d.expansions);
            }
            (a, d) => assert_eq!(a.map(|p| p.cost), d.map(|p| p.cost)),
        }
    }
}
