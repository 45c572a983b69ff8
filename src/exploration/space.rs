//! The space an explorer may fly and the frontiers at its edge (thesis Algorithm 1), read off
//! an occupancy grid.
//!
//! In: an [`OccupancyGrid`] (the fleet's merged map) and [`SpaceParams`]. Out: a [`Space`]:
//! which cells are *navigable* (known free, and at least the safety distance from every
//! obstacle, every unknown cell and the map's edge) and the [`Frontier`]s: 8-connected runs of
//! navigable cells at the edge of the navigable space where what lies beyond is unknown (not an
//! obstacle), dropped below `min_cells`, split above `2 * split_cells`, each with its centroid,
//! orientation, length and a goal cell (the frontier cell nearest the centroid, navigable by
//! construction).
//!
//! Unknown space counts as an obstacle, so anything flown through this space was seen free with
//! the safety distance all around: a drone with sparse beams never enters space it has not
//! observed. One-cell gaps between beams are closed first (a 3 x 3 morphological closing of the
//! free cells, as the thesis's map filter does), so ray gaps do not fence the drone in; a closed
//! gap cannot hide an obstacle, which would have shown as hit cells. Distances are Chebyshev
//! (square neighbourhoods), the thesis's erosion.

use nalgebra::Vector2;

use crate::mapping::grid::{GridSpec, OccupancyGrid, UNKNOWN};

/// How the space is read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceParams {
    /// Least distance from obstacles and unknown cells (m).
    pub safety_distance_m: f64,
    /// Frontiers with fewer cells are dropped (the thesis: 15 cells).
    pub min_cells: usize,
    /// Frontiers of at least twice this many cells are split into parts of about this many.
    pub split_cells: usize,
    /// Cells at or above this value are obstacles.
    pub occupied_threshold: i8,
}

impl Default for SpaceParams {
    fn default() -> Self {
        SpaceParams {
            safety_distance_m: 0.4,
            min_cells: 15,
            split_cells: 35,
            occupied_threshold: crate::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD,
        }
    }
}

impl SpaceParams {
    /// The safety distance in whole cells (at least one).
    pub fn safety_cells(&self, resolution_m: f64) -> usize {
        ((self.safety_distance_m / resolution_m) - 1e-9)
            .ceil()
            .max(1.0) as usize
    }
}

/// One frontier.
#[derive(Debug, Clone, PartialEq)]
pub struct Frontier {
    pub centroid_enu_m: Vector2<f64>,
    /// Direction of its long axis (rad, ENU, in -pi/2..pi/2).
    pub orientation_rad: f64,
    /// Number of cells.
    pub cells: usize,
    /// Length (m): cells times the resolution.
    pub size_m: f64,
    /// Index of the goal cell (navigable, nearest the centroid).
    pub goal_index: usize,
    pub goal_enu_m: Vector2<f64>,
}

/// The navigable cells and the frontiers of one grid.
#[derive(Debug, Clone)]
pub struct Space {
    spec: GridSpec,
    navigable: Vec<bool>,
    /// Cells that are not obstacles (free or unknown), to start a drone's search from where it is.
    clear: Vec<bool>,
    safety_cells: usize,
    pub frontiers: Vec<Frontier>,
}

impl Space {
    /// Reads `grid` (O(cells)).
    pub fn new(grid: &OccupancyGrid, params: &SpaceParams) -> Self {
        let spec = *grid.spec();
        let (w, h) = (spec.width_cells as usize, spec.height_cells as usize);
        let data = grid.data();
        let occupied: Vec<bool> = data
            .iter()
            .map(|&v| v >= params.occupied_threshold)
            .collect();
        let free: Vec<bool> = data
            .iter()
            .map(|&v| v != UNKNOWN && v < params.occupied_threshold)
            .collect();
        let closed_free = close3(&free, &occupied, w, h);
        let unknown: Vec<bool> = data
            .iter()
            .zip(&closed_free)
            .map(|(&v, &c)| v == UNKNOWN && !c)
            .collect();
        let s = params.safety_cells(spec.resolution_m);
        let occ_s = dilate(&occupied, w, h, s, true);
        let occ_s1 = dilate(&occupied, w, h, s + 1, true);
        let unk_s = dilate(&unknown, w, h, s, false);
        let unk_s1 = dilate(&unknown, w, h, s + 1, false);
        let navigable: Vec<bool> = (0..w * h)
            .map(|i| closed_free[i] && !occ_s[i] && !unk_s[i])
            .collect();
        let frontier: Vec<bool> = (0..w * h)
            .map(|i| navigable[i] && unk_s1[i] && !occ_s1[i])
            .collect();
        let frontiers = components(&frontier, w, h)
            .into_iter()
            .filter(|c| c.len() >= params.min_cells)
            .flat_map(|c| split(c, &spec, params.split_cells))
            .collect();
        Space {
            spec,
            navigable,
            clear: occupied.iter().map(|o| !o).collect(),
            safety_cells: s,
            frontiers,
        }
    }

    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    pub fn is_navigable(&self, index: usize) -> bool {
        self.navigable.get(index).copied().unwrap_or(false)
    }

    /// Not an obstacle (free or unknown).
    pub fn is_clear(&self, index: usize) -> bool {
        self.clear.get(index).copied().unwrap_or(false)
    }

    pub fn safety_cells(&self) -> usize {
        self.safety_cells
    }

    /// Index of the cell holding `p`, if inside the grid.
    pub fn index_at(&self, p: Vector2<f64>) -> Option<usize> {
        self.spec.cell_at(p).and_then(|c| self.spec.index_of(c))
    }

    pub fn center_of(&self, index: usize) -> Option<Vector2<f64>> {
        self.spec
            .cell_of_index(index)
            .map(|c| self.spec.cell_center_enu_m(c))
    }

    /// Navigable cells (for metrics and tests).
    pub fn navigable_count(&self) -> usize {
        self.navigable.iter().filter(|&&n| n).count()
    }
}

/// `mask` grown by `r` cells in every direction (a (2r+1)^2 square), by two sliding-window
/// passes over prefix counts. With `edge_set`, cells within `r` of the grid's edge are set too
/// (the outside counts as set).
pub(crate) fn dilate(mask: &[bool], w: usize, h: usize, r: usize, edge_set: bool) -> Vec<bool> {
    let mut rows = vec![false; w * h];
    let mut prefix = vec![0u32; w.max(h) + 1];
    for y in 0..h {
        let row = &mask[y * w..(y + 1) * w];
        for (x, &m) in row.iter().enumerate() {
            prefix[x + 1] = prefix[x] + u32::from(m);
        }
        for x in 0..w {
            let lo = x.saturating_sub(r);
            let hi = (x + r + 1).min(w);
            let out_of_grid = x < r || x + r >= w;
            rows[y * w + x] = prefix[hi] > prefix[lo] || (edge_set && out_of_grid);
        }
    }
    let mut out = vec![false; w * h];
    for x in 0..w {
        for y in 0..h {
            prefix[y + 1] = prefix[y] + u32::from(rows[y * w + x]);
        }
        for y in 0..h {
            let lo = y.saturating_sub(r);
            let hi = (y + r + 1).min(h);
            let out_of_grid = y < r || y + r >= h;
            out[y * w + x] = prefix[hi] > prefix[lo] || (edge_set && out_of_grid);
        }
    }
    out
}

/// 3 x 3 closing of the free cells (dilate, then erode), never across an obstacle: one-cell
/// gaps between observed rays become free.
fn close3(free: &[bool], occupied: &[bool], w: usize, h: usize) -> Vec<bool> {
    let grown = dilate(free, w, h, 1, false);
    let not_grown: Vec<bool> = grown.iter().map(|g| !g).collect();
    let shrunk = dilate(&not_grown, w, h, 1, false);
    (0..w * h)
        .map(|i| free[i] || (!shrunk[i] && !occupied[i]))
        .collect()
}

/// 8-connected components of the set cells, each as its cell indices.
fn components(mask: &[bool], w: usize, h: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut cells = Vec::new();
        while let Some(i) = stack.pop() {
            cells.push(i);
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if mask[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        out.push(cells);
    }
    out
}

/// Splits a component of `n` cells into `n / split_cells` parts along its long axis (when that
/// is more than one), and describes each part.
fn split(cells: Vec<usize>, spec: &GridSpec, split_cells: usize) -> Vec<Frontier> {
    let center = |i: usize| {
        let w = spec.width_cells as usize;
        let c = crate::mapping::grid::Cell {
            x: (i % w) as u32,
            y: (i / w) as u32,
        };
        spec.cell_center_enu_m(c)
    };
    let parts = cells.len().checked_div(split_cells).unwrap_or(1).max(1);
    let (_, axis) = principal_axis(&cells.iter().map(|&i| center(i)).collect::<Vec<_>>());
    let mut ordered: Vec<(f64, usize)> = cells.iter().map(|&i| (center(i).dot(&axis), i)).collect();
    ordered.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)));
    let per_part = ordered.len().div_ceil(parts);
    ordered
        .chunks(per_part.max(1))
        .filter_map(|chunk| {
            let points: Vec<Vector2<f64>> = chunk.iter().map(|&(_, i)| center(i)).collect();
            let (centroid, axis) = principal_axis(&points);
            let &(_, goal_index) = chunk.iter().min_by(|a, b| {
                (center(a.1) - centroid)
                    .norm_squared()
                    .total_cmp(&(center(b.1) - centroid).norm_squared())
                    .then(a.1.cmp(&b.1))
            })?;
            let mut orientation = axis.y.atan2(axis.x);
            if orientation > std::f64::consts::FRAC_PI_2 {
                orientation -= std::f64::consts::PI;
            } else if orientation <= -std::f64::consts::FRAC_PI_2 {
                orientation += std::f64::consts::PI;
            }
            Some(Frontier {
                centroid_enu_m: centroid,
                orientation_rad: orientation,
                cells: chunk.len(),
                size_m: chunk.len() as f64 * spec.resolution_m,
                goal_index,
                goal_enu_m: center(goal_index),
            })
        })
        .collect()
}

/// Centroid and unit long axis of a point set (the axis of largest spread; x for one point).
fn principal_axis(points: &[Vector2<f64>]) -> (Vector2<f64>, Vector2<f64>) {
    let n = points.len().max(1) as f64;
    let centroid = points.iter().fold(Vector2::zeros(), |a, p| a + p) / n;
    let (mut sxx, mut syy, mut sxy) = (0.0, 0.0, 0.0);
    for p in points {
        let d = p - centroid;
        sxx += d.x * d.x;
        syy += d.y * d.y;
        sxy += d.x * d.y;
    }
    let angle = 0.5 * (2.0 * sxy).atan2(sxx - syy);
    (centroid, Vector2::new(angle.cos(), angle.sin()))
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    /// A `w` x `h` grid at 0.1 m, origin (0, 0), filled by `f(x, y)`.
    pub(crate) fn grid(w: u32, h: u32, f: impl Fn(u32, u32) -> i8) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        };
        let data = (0..h)
            .flat_map(|y| (0..w).map(move |x| (x, y)))
            .map(|(x, y)| f(x, y));
        OccupancyGrid::from_data(spec, data.collect()).unwrap()
    }

    #[test]
    fn a_known_half_has_one_straight_frontier_at_the_safety_distance_from_the_unknown() {
        // 60 x 40 cells; x < 30 known free, the rest unknown.
        let g = grid(60, 40, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let space = Space::new(&g, &SpaceParams::default());
        assert_eq!(space.frontiers.len(), 1, "{:?}", space.frontiers);
        let f = &space.frontiers[0];
        // Navigable up to x = 25 (4 cells clear of x = 30); the frontier is that column, minus
        // the rows within 5 cells of the map's edge.
        let col = 25;
        assert!(
            (f.centroid_enu_m.x - (col as f64 + 0.5) * 0.1).abs() < 1e-9,
            "{f:?}"
        );
        assert_eq!(f.cells, 40 - 2 * 5);
        assert!((f.orientation_rad.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(space.is_navigable(f.goal_index));
        // Nothing navigable within the safety distance of the unknown half.
        for y in 0..40 {
            for x in 26..60 {
                assert!(!space.is_navigable(y * 60 + x), "({x}, {y})");
            }
        }
    }

    #[test]
    fn frontiers_next_to_obstacles_only_are_not_frontiers() {
        // Known free everywhere, a wall of obstacles at x = 30: no unknown, no frontier.
        let g = grid(60, 40, |x, _| if x == 30 { 100 } else { 0 });
        let space = Space::new(&g, &SpaceParams::default());
        assert!(space.frontiers.is_empty(), "{:?}", space.frontiers);
        assert!(
            !space.is_navigable(20 * 60 + 27),
            "within 0.4 m of the wall"
        );
        assert!(space.is_navigable(20 * 60 + 20));
    }

    #[test]
    fn short_frontiers_are_dropped_and_long_ones_split() {
        // 24 rows: 14 frontier cells once the rows near the map's edge are left out: dropped.
        let short = grid(60, 24, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let s = Space::new(&short, &SpaceParams::default());
        assert!(s.frontiers.is_empty(), "{:?}", s.frontiers);
        // A 200-row map: the 190-cell frontier column is split into 190 / 35 = 5 parts.
        let long = grid(60, 200, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let l = Space::new(&long, &SpaceParams::default());
        assert_eq!(l.frontiers.len(), 5, "{:?}", l.frontiers);
        assert_eq!(l.frontiers.iter().map(|f| f.cells).sum::<usize>(), 190);
        assert!(l.frontiers.iter().all(|f| (f.cells as i64 - 38).abs() <= 1));
        let mut ys: Vec<f64> = l.frontiers.iter().map(|f| f.centroid_enu_m.y).collect();
        ys.sort_by(f64::total_cmp);
        assert!(
            ys.windows(2).all(|p| p[1] - p[0] > 3.0),
            "parts along the frontier: {ys:?}"
        );
    }

    #[test]
    fn one_cell_gaps_between_rays_do_not_block_the_space() {
        // Known free with every 4th cell of every 3rd row unknown (ray gaps): still navigable.
        let g = grid(
            60,
            60,
            |x, y| if x % 4 == 0 && y % 3 == 0 { UNKNOWN } else { 0 },
        );
        let space = Space::new(&g, &SpaceParams::default());
        assert!(space.is_navigable(30 * 60 + 30));
        assert!(space.frontiers.is_empty());
        // A 3 x 3 unknown hole is not a ray gap: it stays unknown and blocks around it.
        let hole = grid(60, 60, |x, y| {
            if (29..32).contains(&x) && (29..32).contains(&y) {
                UNKNOWN
            } else {
                0
            }
        });
        let space = Space::new(&hole, &SpaceParams::default());
        assert!(!space.is_navigable(30 * 60 + 34));
        assert!(space.is_navigable(30 * 60 + 36));
    }

    #[test]
    fn goals_keep_the_safety_distance_from_obstacles_and_unknown() {
        // Known free room with a pole (3 x 3 occupied) near the frontier.
        let g = grid(80, 80, |x, y| {
            if x >= 50 {
                UNKNOWN
            } else if (40..43).contains(&x) && (38..41).contains(&y) {
                100
            } else {
                0
            }
        });
        let space = Space::new(&g, &SpaceParams::default());
        assert!(!space.frontiers.is_empty());
        for f in &space.frontiers {
            let c = space.center_of(f.goal_index).unwrap();
            let pole = Vector2::new(4.15, 3.95);
            assert!((c - pole).abs().max() > 0.45, "goal {c:?} near the pole");
            assert!(c.x < 4.56, "goal {c:?} within 0.4 m of the unknown");
        }
    }
}
