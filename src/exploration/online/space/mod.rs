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
//! gap cannot hide an obstacle, which would have shown as hit cells. Distances are Euclidean
//! (discs, centre to centre; the thesis erodes with squares, which closes diagonal gaps between
//! poles that a drone fits through).

mod masks;

use masks::{close3, components, squared_distance};
use nalgebra::Vector2;

use crate::mapping::grid::{GridSpec, OccupancyGrid, UNKNOWN};

/// A frontier's gain is the unknown within this distance of its goal (m).
const GAIN_RADIUS_M: f64 = 2.5;

/// How the space is read.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SpaceParams {
    /// Least distance from obstacles and unknown cells (m).
    pub safety_distance_m: f64,
    /// Frontiers with fewer cells are left for the end (the thesis drops them: 15 cells).
    pub min_cells: usize,
    /// Frontiers with fewer cells are dropped for good (but for a gap: one of at least half
    /// as many with `min_gain_cells` of unknown behind it is kept, as small); those between
    /// this and `min_cells` are explored only once no frontier of `min_cells` is left (none by
    /// default, as the thesis).
    pub min_final_cells: usize,
    /// Frontiers of at least twice this many cells are split into parts of about this many.
    pub split_cells: usize,
    /// Cells at or above this value are obstacles.
    pub occupied_threshold: i8,
    /// Frontiers with fewer unknown cells behind them (the unknown region they border, counted
    /// up to this many) are marked `low_gain`: a pocket behind a pole or in a corner that a
    /// visit could add only this little to. 0: none is.
    pub min_gain_cells: usize,
    /// The unknown near each frontier is counted up to this many cells into
    /// `Frontier::gain_m2`.
    pub gain_cap_cells: usize,
}

impl Default for SpaceParams {
    fn default() -> Self {
        SpaceParams {
            safety_distance_m: 0.4,
            min_cells: 15,
            min_final_cells: 15,
            split_cells: 35,
            occupied_threshold: crate::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD,
            min_gain_cells: 0,
            gain_cap_cells: 0,
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
    /// Indices of its two end cells along the long axis (navigable, as every frontier cell).
    pub end_indices: [usize; 2],
    /// Shorter than `min_cells`: explored only once no longer frontier is left.
    pub small: bool,
    /// Borders fewer than `min_gain_cells` unknown cells: a small enclosed pocket.
    pub low_gain: bool,
    /// The unknown within 2.5 m of its goal (m^2), counted up to `gain_cap_cells`.
    pub gain_m2: f64,
}

/// The navigable cells and the frontiers of one grid.
#[derive(Debug, Clone)]
pub struct Space {
    spec: GridSpec,
    params: SpaceParams,
    /// The grid this was read from, to find what changed.
    data: Vec<i8>,
    navigable: Vec<bool>,
    /// How far each cell is from the nearest obstacle or unknown cell: 0 within half the
    /// safety distance, 1 within it, 2 beyond.
    margin: Vec<u8>,
    frontier: Vec<bool>,
    safety_cells: usize,
    pub frontiers: Vec<Frontier>,
}

/// A rectangle of cells, `x0..x1` by `y0..y1`.
/// Side of the tiles a map update is read in (cells): changed tiles that touch are read
/// together.
const TILE: usize = 32;

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct Rect {
    x0: usize,
    y0: usize,
    x1: usize,
    y1: usize,
}

impl Space {
    /// Reads `grid` (O(cells)).
    pub fn new(grid: &OccupancyGrid, params: &SpaceParams) -> Self {
        let spec = *grid.spec();
        let (w, h) = (spec.width_cells as usize, spec.height_cells as usize);
        let mut space = Space {
            spec,
            params: *params,
            data: grid.data().to_vec(),
            navigable: vec![false; w * h],
            margin: vec![0; w * h],
            frontier: vec![false; w * h],
            safety_cells: params.safety_cells(spec.resolution_m),
            frontiers: Vec::new(),
        };
        space.derive(Rect {
            x0: 0,
            y0: 0,
            x1: w,
            y1: h,
        });
        space.find_frontiers();
        space
    }

    /// Brings the space up to date with `grid`, re-reading only around the cells that changed,
    /// group by group of changed [`TILE`]s (everything read here depends on cells at most
    /// `safety + 3` away); a grid of another
    /// shape or other parameters are read whole. Returns whether anything changed.
    pub fn update(&mut self, grid: &OccupancyGrid, params: &SpaceParams) -> bool {
        if *grid.spec() != self.spec || *params != self.params {
            *self = Space::new(grid, params);
            return true;
        }
        let (w, h) = (
            self.spec.width_cells as usize,
            self.spec.height_cells as usize,
        );
        let new = grid.data();
        // The changed tiles: several drones change the map in places far apart, and one box
        // round them all would be most of the map.
        let (tw, th) = (w.div_ceil(TILE), h.div_ceil(TILE));
        let mut dirty = vec![false; tw * th];
        for (y, (old_row, new_row)) in self.data.chunks(w).zip(new.chunks(w)).enumerate() {
            if old_row == new_row {
                continue;
            }
            for (t, (a, b)) in old_row.chunks(TILE).zip(new_row.chunks(TILE)).enumerate() {
                if a != b {
                    dirty[(y / TILE) * tw + t] = true;
                }
            }
        }
        let groups = components(&dirty, tw, th);
        if groups.is_empty() {
            return false;
        }
        self.data.copy_from_slice(new);
        let m = self.safety_cells + 3;
        for tiles in groups {
            let (tx0, tx1) = tiles
                .iter()
                .fold((usize::MAX, 0), |(a, b), &t| (a.min(t % tw), b.max(t % tw)));
            let (ty0, ty1) = tiles
                .iter()
                .fold((usize::MAX, 0), |(a, b), &t| (a.min(t / tw), b.max(t / tw)));
            self.derive(Rect {
                x0: (tx0 * TILE).saturating_sub(m),
                y0: (ty0 * TILE).saturating_sub(m),
                x1: ((tx1 + 1) * TILE + m).min(w),
                y1: ((ty1 + 1) * TILE + m).min(h),
            });
        }
        self.find_frontiers();
        true
    }

    /// Recomputes the navigable and frontier cells inside `rect`, from the grid around it.
    fn derive(&mut self, rect: Rect) {
        let (w, h) = (
            self.spec.width_cells as usize,
            self.spec.height_cells as usize,
        );
        let s = self.safety_cells;
        let m = s + 3;
        // The rectangle with the context its cells depend on.
        let c = Rect {
            x0: rect.x0.saturating_sub(m),
            y0: rect.y0.saturating_sub(m),
            x1: (rect.x1 + m).min(w),
            y1: (rect.y1 + m).min(h),
        };
        let (cw, ch) = (c.x1 - c.x0, c.y1 - c.y0);
        let cells = || (c.y0..c.y1).flat_map(move |y| (c.x0..c.x1).map(move |x| y * w + x));
        let threshold = self.params.occupied_threshold;
        let occupied: Vec<bool> = cells().map(|i| self.data[i] >= threshold).collect();
        let free: Vec<bool> = cells()
            .map(|i| self.data[i] != UNKNOWN && self.data[i] < threshold)
            .collect();
        let closed_free = close3(&free, &occupied, cw, ch);
        let unknown: Vec<bool> = cells()
            .zip(&closed_free)
            .map(|(i, &cf)| self.data[i] == UNKNOWN && !cf)
            .collect();
        // Each mask grown by a disc of each radius: within it, by the squared distance.
        let (occ_d2, unk_d2) = (
            squared_distance(&occupied, cw, ch),
            squared_distance(&unknown, cw, ch),
        );
        let within = |d2: &[u32], j: usize, r: usize| u64::from(d2[j]) <= (r * r) as u64;
        let half = s.div_ceil(2);
        // The map's edge counts as an obstacle.
        let edge_within = |x: usize, y: usize, r: usize| x < r || y < r || x + r >= w || y + r >= h;
        for y in rect.y0..rect.y1 {
            for x in rect.x0..rect.x1 {
                let j = (y - c.y0) * cw + (x - c.x0);
                let (occ_s, unk_s) = (within(&occ_d2, j, s), within(&unk_d2, j, s));
                let navigable = closed_free[j] && !occ_s && !unk_s && !edge_within(x, y, s);
                self.navigable[y * w + x] = navigable;
                self.margin[y * w + x] = if within(&occ_d2, j, half) || within(&unk_d2, j, half) {
                    0
                } else if occ_s || unk_s {
                    1
                } else {
                    2
                };
                // The edge is no obstacle to see past: unknown cells along it make frontiers.
                self.frontier[y * w + x] =
                    navigable && within(&unk_d2, j, s + 1) && !within(&occ_d2, j, s + 1);
            }
        }
    }

    fn find_frontiers(&mut self) {
        let (w, h) = (
            self.spec.width_cells as usize,
            self.spec.height_cells as usize,
        );
        let components = components(&self.frontier, w, h);
        let least = self.params.min_final_cells.min(self.params.min_cells);
        let gain = self.params.min_gain_cells;
        self.frontiers = components
            .into_iter()
            // Shorter than the least length, a frontier is kept only when a large unknown
            // region lies behind it (a gap between obstacles that leads on), down to half that.
            .filter(|c| {
                c.len() >= least
                    || (gain > 0 && 2 * c.len() >= least && self.unknown_behind(c, gain) >= gain)
            })
            .flat_map(|c| {
                let small = c.len() < self.params.min_cells;
                let low_gain = gain > 0 && self.unknown_behind(&c, gain) < gain;
                let mut parts = split(c, &self.spec, self.params.split_cells);
                let cell_m2 = self.spec.resolution_m * self.spec.resolution_m;
                for p in &mut parts {
                    p.small = small;
                    p.low_gain = low_gain;
                    p.gain_m2 = self.unknown_near(p.goal_index, self.params.gain_cap_cells) as f64
                        * cell_m2;
                }
                parts
            })
            .collect();
    }

    /// How many unknown cells lie within `GAIN_RADIUS_M` of cell `center`, counted up to
    /// `cap`: what a visit could add. A disc, not the connected unknown region: the rays that
    /// crossed a large unknown region cut it into pieces that each look small.
    fn unknown_near(&self, center: usize, cap: usize) -> usize {
        let w = self.spec.width_cells as i64;
        let h = self.spec.height_cells as i64;
        let r = (GAIN_RADIUS_M / self.spec.resolution_m).round() as i64;
        let (cx, cy) = (center as i64 % w, center as i64 / w);
        let mut count = 0;
        for y in (cy - r).max(0)..=(cy + r).min(h - 1) {
            let dy = y - cy;
            let half = ((r * r - dy * dy) as f64).sqrt() as i64;
            let row = (y * w) as usize;
            for x in (cx - half).max(0)..=(cx + half).min(w - 1) {
                if self.data[row + x as usize] == UNKNOWN {
                    count += 1;
                    if count >= cap {
                        return count;
                    }
                }
            }
        }
        count
    }

    /// How many unknown cells the frontier `cells` borders, counted up to `cap`: the unknown
    /// cells within the safety distance (plus one cell) of it and every unknown cell 8-connected
    /// to those. One-cell gaps between rays count too, so this errs on the side of exploring.
    fn unknown_behind(&self, cells: &[usize], cap: usize) -> usize {
        let (w, h) = (
            self.spec.width_cells as usize,
            self.spec.height_cells as usize,
        );
        let r = (self.safety_cells + 1) as i64;
        let unknown = |x: i64, y: i64| {
            x >= 0
                && y >= 0
                && (x as usize) < w
                && (y as usize) < h
                && self.data[y as usize * w + x as usize] == UNKNOWN
        };
        let mut seen = rustc_hash::FxHashSet::default();
        let mut stack = Vec::new();
        for &i in cells {
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -r..=r {
                for dx in -r..=r {
                    if unknown(x + dx, y + dy) && seen.insert((x + dx, y + dy)) {
                        stack.push((x + dx, y + dy));
                    }
                }
            }
        }
        while let Some((x, y)) = stack.pop() {
            if seen.len() >= cap {
                break;
            }
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    if unknown(x + dx, y + dy) && seen.insert((x + dx, y + dy)) {
                        stack.push((x + dx, y + dy));
                    }
                }
            }
        }
        seen.len().min(cap)
    }

    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Unit vector from `frontier` toward the unknown it borders (from its middle and its
    /// ends: the mean offset to the unknown cells within the safety distance plus two cells);
    /// `None` when none is found.
    pub fn unknown_side(&self, frontier: &Frontier) -> Option<Vector2<f64>> {
        let w = self.spec.width_cells as i64;
        let h = self.spec.height_cells as i64;
        let r = self.safety_cells as i64 + 2;
        let mut sum = Vector2::zeros();
        for i in [
            frontier.goal_index,
            frontier.end_indices[0],
            frontier.end_indices[1],
        ] {
            let (x, y) = ((i as i64) % w, (i as i64) / w);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx >= 0
                        && ny >= 0
                        && nx < w
                        && ny < h
                        && self.data[(ny * w + nx) as usize] == UNKNOWN
                    {
                        sum += Vector2::new(dx as f64, dy as f64);
                    }
                }
            }
        }
        (sum.norm() > 0.0).then(|| sum.normalize())
    }

    pub fn is_navigable(&self, index: usize) -> bool {
        self.navigable.get(index).copied().unwrap_or(false)
    }

    /// Every cell's [`Self::is_navigable`], row-major.
    pub fn navigable_cells(&self) -> &[bool] {
        &self.navigable
    }

    /// Not an obstacle (free or unknown).
    pub fn is_clear(&self, index: usize) -> bool {
        self.data
            .get(index)
            .is_some_and(|&v| v < self.params.occupied_threshold)
    }

    /// How far cell `index` is from obstacles and unknown cells (a pole no beam has hit yet
    /// shows only as unknown): 0 within half the safety distance, 1 within it, 2 beyond.
    pub fn clearance_level(&self, index: usize) -> u8 {
        self.margin.get(index).copied().unwrap_or(0)
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
            let ends = [chunk.first()?.1, chunk.last()?.1];
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
                end_indices: ends,
                small: false,
                low_gain: false,
                gain_m2: 0.0,
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
pub(crate) mod tests {
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
    fn a_frontier_around_a_small_unknown_pocket_is_low_gain_and_one_at_open_unknown_is_not() {
        // 100 x 60 cells: x >= 80 unknown (open), a 5 x 5 unknown pocket at (30..35, 28..33),
        // the rest known free.
        let g = grid(100, 60, |x, y| {
            if x >= 80 || ((30..35).contains(&x) && (28..33).contains(&y)) {
                UNKNOWN
            } else {
                0
            }
        });
        let params = SpaceParams {
            min_gain_cells: 50,
            ..SpaceParams::default()
        };
        let space = Space::new(&g, &params);
        let near_pocket =
            |f: &&Frontier| (f.centroid_enu_m - Vector2::new(3.25, 3.05)).norm() < 1.0;
        let pocket: Vec<_> = space.frontiers.iter().filter(near_pocket).collect();
        let open: Vec<_> = space
            .frontiers
            .iter()
            .filter(|f| f.centroid_enu_m.x > 7.0)
            .collect();
        assert!(
            !pocket.is_empty() && !open.is_empty(),
            "{:?}",
            space.frontiers
        );
        assert!(pocket.iter().all(|f| f.low_gain), "{pocket:?}");
        assert!(open.iter().all(|f| !f.low_gain), "{open:?}");
        // With no least gain, nothing is low gain.
        let all = Space::new(&g, &SpaceParams::default());
        assert!(all.frontiers.iter().all(|f| !f.low_gain));
    }

    #[test]
    fn a_known_half_has_one_straight_frontier_at_the_safety_distance_from_the_unknown() {
        // 60 x 40 cells; x < 30 known free, the rest unknown.
        let g = grid(60, 40, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let space = Space::new(&g, &SpaceParams::default());
        assert_eq!(space.frontiers.len(), 1, "{:?}", space.frontiers);
        let f = &space.frontiers[0];
        // Navigable up to x = 25 (4 cells clear of x = 30) and 4 cells clear of the map's edge;
        // the frontier is that column.
        let col = 25;
        assert!(
            (f.centroid_enu_m.x - (col as f64 + 0.5) * 0.1).abs() < 1e-9,
            "{f:?}"
        );
        assert_eq!(f.cells, 40 - 2 * 4);
        assert!((f.orientation_rad.abs() - std::f64::consts::FRAC_PI_2).abs() < 1e-6);
        assert!(space.is_navigable(f.goal_index));
        // Its ends are the column's first and last cells; the unknown lies east.
        let [a, b] = f.end_indices.map(|i| space.center_of(i).unwrap());
        assert!((a.y - b.y).abs() > 3.0, "{a:?} {b:?}");
        assert!((a.x - f.goal_enu_m.x).abs() < 1e-9 && (b.x - f.goal_enu_m.x).abs() < 1e-9);
        assert!(f.end_indices.iter().all(|&i| space.is_navigable(i)));
        let u = space.unknown_side(f).unwrap();
        assert!(u.x > 0.9, "{u:?}");
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
        // 22 rows: 14 frontier cells once the rows near the map's edge are left out: dropped
        // (the thesis), or kept for the end when asked.
        let short = grid(60, 22, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let s = Space::new(&short, &SpaceParams::default());
        assert!(s.frontiers.is_empty(), "{:?}", s.frontiers);
        let for_the_end = SpaceParams {
            min_final_cells: 5,
            ..SpaceParams::default()
        };
        let s = Space::new(&short, &for_the_end);
        assert!(s.frontiers.iter().all(|f| f.small), "{:?}", s.frontiers);
        assert_eq!(s.frontiers.len(), 1);
        // A 200-row map: the 192-cell frontier column is split into 192 / 35 = 5 parts.
        let long = grid(60, 200, |x, _| if x < 30 { 0 } else { UNKNOWN });
        let l = Space::new(&long, &SpaceParams::default());
        assert_eq!(l.frontiers.len(), 5, "{:?}", l.frontiers);
        assert_eq!(l.frontiers.iter().map(|f| f.cells).sum::<usize>(), 192);
        assert!(l.frontiers.iter().all(|f| (36..=39).contains(&f.cells)));
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

    #[test]
    fn an_update_reads_only_what_changed_and_matches_a_fresh_read() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let mut g = grid(120, 90, |x, y| if x + y < 80 { 0 } else { UNKNOWN });
        let params = SpaceParams::default();
        let mut space = Space::new(&g, &params);
        assert!(!space.update(&g, &params), "nothing changed");
        for round in 0..30 {
            // A patch of new observations: free cells, some obstacles, somewhere.
            let (cx, cy) = (rng.gen_range(0..120u32), rng.gen_range(0..90u32));
            for _ in 0..200 {
                let x = (cx + rng.gen_range(0..15)).min(119);
                let y = (cy + rng.gen_range(0..15)).min(89);
                let v = if rng.gen_bool(0.05) { 100 } else { 0 };
                let cell = crate::mapping::grid::Cell { x, y };
                g.set(cell, v).unwrap();
            }
            assert!(space.update(&g, &params), "round {round}");
            let fresh = Space::new(&g, &params);
            assert_eq!(space.navigable, fresh.navigable, "round {round}");
            assert_eq!(space.frontier, fresh.frontier, "round {round}");
            assert_eq!(space.frontiers, fresh.frontiers, "round {round}");
        }
    }

    #[test]
    fn a_short_frontier_is_kept_only_where_a_large_unknown_lies_behind_it() {
        // Known free west of a wall at x = 50 with a 1.6 m gap (y 22..38); unknown east of it.
        let g = grid(100, 60, |x, y| match x {
            50 if !(22..38).contains(&y) => 100,
            x if x > 50 => UNKNOWN,
            _ => 0,
        });
        let params = |min_gain_cells| SpaceParams {
            min_gain_cells,
            ..SpaceParams::default()
        };
        let in_gap = |space: &Space| {
            space
                .frontiers
                .iter()
                .filter(|f| (f.centroid_enu_m - Vector2::new(4.65, 3.0)).norm() < 0.6)
                .count()
        };
        // The gap's frontier is shorter than the least length (15 cells)...
        assert_eq!(in_gap(&Space::new(&g, &params(0))), 0);
        // ...but leads on to a large unknown region, so it is kept (as small: explored last).
        let space = Space::new(&g, &params(50));
        assert_eq!(in_gap(&space), 1, "{:?}", space.frontiers);
        assert!(space.frontiers.iter().all(|f| f.small));
    }
}
