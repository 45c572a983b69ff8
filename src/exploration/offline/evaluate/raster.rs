//! The evaluation grid: square cells over the world's bounds, cell sets as bitsets, and the
//! cells a segment crosses (Amanatides-Woo traversal).
//!
//! In: bounds and a cell size; segments in world coordinates (ENU m). Out: cell indices
//! (row-major, `iy * nx + ix`), [`CellSet`]s, and the 3x3 closing of a set.

use super::EvalError;
use crate::sim::world::Bounds;

/// Most cells the evaluation grid may have (a 1 km square at 0.1 m).
const MAX_CELLS: u64 = 100_000_000;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Raster {
    pub min_x: f64,
    pub min_y: f64,
    pub cell_m: f64,
    pub nx: usize,
    pub ny: usize,
}

impl Raster {
    /// The grid covering `bounds` (sides rounded to whole cells).
    pub fn over(bounds: &Bounds, cell_m: f64) -> Result<Self, EvalError> {
        let nx = ((bounds.x[1] - bounds.x[0]) / cell_m).round().max(1.0);
        let ny = ((bounds.y[1] - bounds.y[0]) / cell_m).round().max(1.0);
        let cells = nx * ny;
        if !cells.is_finite() || cells > MAX_CELLS as f64 {
            return Err(EvalError::GridTooLarge(cells.min(u64::MAX as f64) as u64));
        }
        Ok(Self {
            min_x: bounds.x[0],
            min_y: bounds.y[0],
            cell_m,
            nx: nx as usize,
            ny: ny as usize,
        })
    }

    pub fn cells(&self) -> usize {
        self.nx * self.ny
    }

    pub fn area_m2(&self) -> f64 {
        self.cells() as f64 * self.cell_m * self.cell_m
    }

    /// Centre of cell (ix, iy) (m).
    pub fn centre(&self, ix: usize, iy: usize) -> (f64, f64) {
        (
            self.min_x + (ix as f64 + 0.5) * self.cell_m,
            self.min_y + (iy as f64 + 0.5) * self.cell_m,
        )
    }

    /// The cell holding (x, y), if inside the grid.
    pub fn cell_of(&self, x: f64, y: f64) -> Option<(usize, usize)> {
        let fx = (x - self.min_x) / self.cell_m;
        let fy = (y - self.min_y) / self.cell_m;
        let inside = fx >= 0.0 && fy >= 0.0 && fx < self.nx as f64 && fy < self.ny as f64;
        inside.then_some((fx as usize, fy as usize))
    }

    /// The cell holding (x, y), clamped into the grid.
    pub fn cell_clamped(&self, x: f64, y: f64) -> (usize, usize) {
        let f = |v: f64, lo: f64, n: usize| {
            (((v - lo) / self.cell_m).floor().max(0.0) as usize).min(n - 1)
        };
        (f(x, self.min_x, self.nx), f(y, self.min_y, self.ny))
    }

    /// Calls `visit(index)` for every cell the segment from `a` to `b` crosses, in order from
    /// `a`, including the cells holding `a` and `b`; the parts outside the grid are skipped.
    /// `visit` returns `false` to stop early.
    pub fn traverse(&self, a: (f64, f64), b: (f64, f64), mut visit: impl FnMut(usize) -> bool) {
        let (dx, dy) = (b.0 - a.0, b.1 - a.1);
        let Some((t0, t1)) = self.clip(a, dx, dy) else {
            return;
        };
        // Grid units from here on.
        let gx = (a.0 + t0 * dx - self.min_x) / self.cell_m;
        let gy = (a.1 + t0 * dy - self.min_y) / self.cell_m;
        let (gdx, gdy) = (dx / self.cell_m, dy / self.cell_m);
        let mut ix = (gx.floor().max(0.0) as usize).min(self.nx - 1);
        let mut iy = (gy.floor().max(0.0) as usize).min(self.ny - 1);
        let axis = |g: f64, i: usize, d: f64| -> (f64, f64) {
            // (parameter of the next boundary crossing, parameter per cell) along one axis.
            if d > 0.0 {
                ((i as f64 + 1.0 - g) / d, 1.0 / d)
            } else if d < 0.0 {
                ((i as f64 - g) / d, -1.0 / d)
            } else {
                (f64::INFINITY, f64::INFINITY)
            }
        };
        let (mut next_x, step_x) = axis(gx, ix, gdx);
        let (mut next_y, step_y) = axis(gy, iy, gdy);
        let span = t1 - t0;
        loop {
            if !visit(iy * self.nx + ix) {
                return;
            }
            if next_x <= next_y {
                if next_x > span {
                    return;
                }
                next_x += step_x;
                if gdx > 0.0 {
                    ix += 1;
                    if ix >= self.nx {
                        return;
                    }
                } else {
                    let Some(i) = ix.checked_sub(1) else { return };
                    ix = i;
                }
            } else {
                if next_y > span {
                    return;
                }
                next_y += step_y;
                if gdy > 0.0 {
                    iy += 1;
                    if iy >= self.ny {
                        return;
                    }
                } else {
                    let Some(i) = iy.checked_sub(1) else { return };
                    iy = i;
                }
            }
        }
    }

    /// The part [t0, t1] of the segment `a + t (dx, dy)`, t in [0, 1], inside the grid.
    fn clip(&self, a: (f64, f64), dx: f64, dy: f64) -> Option<(f64, f64)> {
        let max_x = self.min_x + self.nx as f64 * self.cell_m;
        let max_y = self.min_y + self.ny as f64 * self.cell_m;
        let (mut t0, mut t1) = (0.0f64, 1.0f64);
        for (p, d, lo, hi) in [(a.0, dx, self.min_x, max_x), (a.1, dy, self.min_y, max_y)] {
            if d.abs() < 1e-15 {
                if p < lo || p >= hi {
                    return None;
                }
            } else {
                let (u, v) = ((lo - p) / d, (hi - p) / d);
                t0 = t0.max(u.min(v));
                t1 = t1.min(u.max(v));
            }
        }
        (t0 <= t1).then_some((t0, t1))
    }

    /// The 3x3 closing (dilate, then erode) of `set`; outside the grid counts as set for the
    /// erosion, so the border is not eaten away.
    pub fn closed(&self, set: &CellSet) -> CellSet {
        let dilated = self.morph(set, true);
        self.morph(&dilated, false)
    }

    fn morph(&self, set: &CellSet, dilate: bool) -> CellSet {
        let mut out = CellSet::new(self.cells());
        for iy in 0..self.ny {
            for ix in 0..self.nx {
                let mut hit = !dilate;
                for ny in iy.saturating_sub(1)..=(iy + 1).min(self.ny - 1) {
                    for nx in ix.saturating_sub(1)..=(ix + 1).min(self.nx - 1) {
                        let v = set.contains(ny * self.nx + nx);
                        if dilate && v {
                            hit = true;
                        } else if !dilate && !v {
                            hit = false;
                        }
                    }
                }
                if hit {
                    out.insert(iy * self.nx + ix);
                }
            }
        }
        out
    }
}

/// A set of grid cells.
#[derive(Debug, Clone, PartialEq)]
pub struct CellSet {
    words: Vec<u64>,
}

impl CellSet {
    pub fn new(cells: usize) -> Self {
        Self {
            words: vec![0; cells.div_ceil(64)],
        }
    }

    /// Adds `i`; true if it was not in the set.
    pub fn insert(&mut self, i: usize) -> bool {
        match self.words.get_mut(i / 64) {
            Some(w) => {
                let bit = 1u64 << (i % 64);
                let new = *w & bit == 0;
                *w |= bit;
                new
            }
            None => false,
        }
    }

    pub fn contains(&self, i: usize) -> bool {
        self.words
            .get(i / 64)
            .is_some_and(|w| w & (1u64 << (i % 64)) != 0)
    }

    pub fn count(&self) -> usize {
        self.words.iter().map(|w| w.count_ones() as usize).sum()
    }

    pub fn intersection_count(&self, other: &CellSet) -> usize {
        self.words
            .iter()
            .zip(&other.words)
            .map(|(a, b)| (a & b).count_ones() as usize)
            .sum()
    }

    /// Removes every cell of `other`.
    pub fn remove_all(&mut self, other: &CellSet) {
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a &= !b;
        }
    }

    pub fn union_with(&mut self, other: &CellSet) {
        for (a, b) in self.words.iter_mut().zip(&other.words) {
            *a |= b;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn raster() -> Raster {
        Raster::over(
            &Bounds {
                x: [-1.0, 1.0],
                y: [-1.0, 1.0],
            },
            0.1,
        )
        .unwrap()
    }

    fn cells(r: &Raster, a: (f64, f64), b: (f64, f64)) -> Vec<(usize, usize)> {
        let mut out = Vec::new();
        r.traverse(a, b, |i| {
            out.push((i % r.nx, i / r.nx));
            true
        });
        out
    }

    #[test]
    fn traversal_visits_each_crossed_cell_once_in_order() {
        let r = raster();
        let row = cells(&r, (0.05, 0.05), (0.45, 0.05));
        assert_eq!(row, (10..15).map(|x| (x, 10)).collect::<Vec<_>>());
        let back = cells(&r, (0.05, 0.05), (-0.25, 0.05));
        assert_eq!(back, vec![(10, 10), (9, 10), (8, 10), (7, 10)]);
        let diag = cells(&r, (0.01, 0.02), (0.29, 0.28));
        assert_eq!(diag.first(), Some(&(10, 10)));
        assert_eq!(diag.last(), Some(&(12, 12)));
        for w in diag.windows(2) {
            let step = w[1].0.abs_diff(w[0].0) + w[1].1.abs_diff(w[0].1);
            assert_eq!(step, 1, "4-connected: {diag:?}");
        }
    }

    #[test]
    fn traversal_clips_to_the_grid() {
        let r = raster();
        let through = cells(&r, (-5.0, 0.05), (5.0, 0.05));
        assert_eq!(through.len(), 20);
        assert_eq!(through.first(), Some(&(0, 10)));
        assert!(cells(&r, (-5.0, 3.0), (5.0, 3.0)).is_empty());
        let out = cells(&r, (0.95, 0.95), (3.0, 0.95));
        assert_eq!(out, vec![(19, 19)]);
    }

    #[test]
    fn closing_fills_single_holes_and_keeps_the_border() {
        let r = raster();
        let mut s = CellSet::new(r.cells());
        for i in 0..r.cells() {
            if i != 5 * r.nx + 5 {
                s.insert(i);
            }
        }
        assert_eq!(r.closed(&s).count(), r.cells());
        let mut dot = CellSet::new(r.cells());
        dot.insert(0);
        assert_eq!(r.closed(&dot).count(), 1);
    }
}
