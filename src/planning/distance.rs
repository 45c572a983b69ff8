//! Exact Euclidean distance transform with nearest-obstacle sites (Felzenszwalb–Huttenlocher).
//!
//! In: an occupancy grid and the occupied threshold. Out: a [`DistanceField`]: for each cell the
//! distance (metres, centre to centre) to the nearest occupied cell and which cell that is. The
//! planners use it for round inflation (blocked iff distance <= safety distance), clearance
//! reporting and the Voronoi diagram (cells whose neighbours have far-apart nearest obstacles).
//!
//! Method: a column pass finds each cell's nearest obstacle in its column (two linear sweeps);
//! a row pass takes the lower envelope of the parabolas `(x - q)^2 + d_col(q)^2`, which gives the
//! exact squared distance and the column `q` (hence the site) of the minimum. O(cells).

use crate::mapping::grid::{GridSpec, OccupancyGrid};

/// Marker for "no obstacle anywhere in reach".
const NO_SITE: u32 = u32::MAX;

/// Distance to the nearest occupied cell for every cell of a grid.
#[derive(Debug, Clone, PartialEq)]
pub struct DistanceField {
    spec: GridSpec,
    /// Metres, centre to centre; capped at `max_distance_m` when the grid has no obstacle.
    dist_m: Vec<f32>,
    /// Flat index of the nearest occupied cell, `NO_SITE` if none.
    site: Vec<u32>,
    max_distance_m: f32,
}

impl DistanceField {
    /// Cells with value `>= occupied_threshold` are obstacles; unknown (`-1`) cells are not.
    pub fn compute(grid: &OccupancyGrid, occupied_threshold: i8) -> Self {
        let spec = *grid.spec();
        let obstacle: Vec<bool> = grid
            .data()
            .iter()
            .map(|&v| v >= occupied_threshold)
            .collect();
        Self::from_obstacles(spec, &obstacle)
    }

    /// Same, from an obstacle mask (row-major, one flag per cell; missing flags count as free).
    pub fn from_obstacles(spec: GridSpec, obstacle: &[bool]) -> Self {
        let w = spec.width_cells as usize;
        let h = spec.height_cells as usize;
        let n = w * h;
        let is_obstacle = |i: usize| obstacle.get(i).copied().unwrap_or(false);

        // Column pass: vertical distance (cells) and row of the nearest obstacle in the column.
        let far = (w + h) as u32 + 1;
        let mut col_dist = vec![far; n];
        let mut col_site_y = vec![NO_SITE; n];
        for x in 0..w {
            let mut last: Option<usize> = None;
            for y in 0..h {
                let i = y * w + x;
                if is_obstacle(i) {
                    last = Some(y);
                }
                if let (Some(ly), Some(d), Some(s)) =
                    (last, col_dist.get_mut(i), col_site_y.get_mut(i))
                {
                    *d = (y - ly) as u32;
                    *s = ly as u32;
                }
            }
            let mut last: Option<usize> = None;
            for y in (0..h).rev() {
                let i = y * w + x;
                if is_obstacle(i) {
                    last = Some(y);
                }
                if let (Some(ly), Some(d), Some(s)) =
                    (last, col_dist.get_mut(i), col_site_y.get_mut(i))
                {
                    let dy = (ly - y) as u32;
                    if dy < *d {
                        *d = dy;
                        *s = ly as u32;
                    }
                }
            }
        }

        // Row pass: lower envelope of parabolas rooted at columns that see an obstacle.
        let mut dist_m = vec![0.0f32; n];
        let mut site = vec![NO_SITE; n];
        let mut roots: Vec<usize> = Vec::with_capacity(w);
        let mut bounds: Vec<f64> = Vec::with_capacity(w + 1);
        let res = spec.resolution_m;
        let max_distance_m = ((w * w + h * h) as f64).sqrt() * res;
        for y in 0..h {
            let row = y * w;
            let f = |q: usize| -> Option<f64> {
                let i = row + q;
                let s = *col_site_y.get(i)?;
                (s != NO_SITE).then(|| f64::from(*col_dist.get(i).unwrap_or(&far)).powi(2))
            };
            roots.clear();
            bounds.clear();
            for q in 0..w {
                let Some(fq) = f(q) else { continue };
                // Pop parabolas hidden by the new one.
                while let Some(&v) = roots.last() {
                    let fv = f(v).unwrap_or(f64::INFINITY);
                    let qf = q as f64;
                    let vf = v as f64;
                    let s = ((fq + qf * qf) - (fv + vf * vf)) / (2.0 * (qf - vf));
                    if bounds.last().is_some_and(|&b| s <= b) {
                        roots.pop();
                        bounds.pop();
                    } else {
                        bounds.push(s);
                        break;
                    }
                }
                roots.push(q);
            }
            // bounds[k] separates roots[k] and roots[k + 1].
            let mut k = 0;
            for x in 0..w {
                let i = row + x;
                while bounds.get(k).is_some_and(|&b| b < x as f64) {
                    k += 1;
                }
                let Some(&q) = roots.get(k) else { break };
                let Some(fq) = f(q) else { break };
                let dx = x as f64 - q as f64;
                let d2 = dx * dx + fq;
                if let (Some(d), Some(s), Some(&sy)) =
                    (dist_m.get_mut(i), site.get_mut(i), col_site_y.get(row + q))
                {
                    *d = (d2.sqrt() * res).min(max_distance_m) as f32;
                    *s = sy * w as u32 + q as u32;
                }
            }
            if roots.is_empty() {
                for d in dist_m.get_mut(row..row + w).into_iter().flatten() {
                    *d = max_distance_m as f32;
                }
            }
        }
        DistanceField {
            spec,
            dist_m,
            site,
            max_distance_m: max_distance_m as f32,
        }
    }

    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Distance (m) from a cell to the nearest obstacle; `None` outside the grid.
    pub fn distance_m(&self, index: usize) -> Option<f32> {
        self.dist_m.get(index).copied()
    }

    /// All distances, row-major.
    pub fn distances_m(&self) -> &[f32] {
        &self.dist_m
    }

    /// Flat index of the nearest obstacle; `None` if the grid has no obstacle (or bad index).
    pub fn nearest_site(&self, index: usize) -> Option<usize> {
        self.site
            .get(index)
            .filter(|&&s| s != NO_SITE)
            .map(|&s| s as usize)
    }

    /// The value reported when the grid has no obstacle (the grid's diagonal).
    pub fn max_distance_m(&self) -> f32 {
        self.max_distance_m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector2;
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;

    fn spec(w: u32, h: u32, res: f64) -> GridSpec {
        GridSpec {
            resolution_m: res,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        }
    }

    #[test]
    fn single_obstacle_gives_round_distances() {
        let s = spec(7, 7, 0.1);
        let mut obs = vec![false; 49];
        obs[3 * 7 + 3] = true;
        let f = DistanceField::from_obstacles(s, &obs);
        let d = |x: usize, y: usize| f.distance_m(y * 7 + x).unwrap_or(-1.0);
        assert_eq!(d(3, 3), 0.0);
        assert!((d(4, 3) - 0.1).abs() < 1e-6);
        assert!((d(5, 4) - 0.05f32.sqrt() * 1.0).abs() < 1e-6); // sqrt(5) * 0.1
        assert!((d(6, 6) - (18f32).sqrt() * 0.1).abs() < 1e-6);
        assert_eq!(f.nearest_site(0), Some(3 * 7 + 3));
    }

    #[test]
    fn matches_brute_force_on_random_grid() {
        let (w, h) = (23usize, 17usize);
        let s = spec(w as u32, h as u32, 1.0);
        let mut rng = ChaCha8Rng::seed_from_u64(7);
        let obs: Vec<bool> = (0..w * h).map(|_| rng.gen_bool(0.08)).collect();
        let f = DistanceField::from_obstacles(s, &obs);
        for i in 0..w * h {
            let (x, y) = ((i % w) as f64, (i / w) as f64);
            let best = (0..w * h)
                .filter(|&j| obs[j])
                .map(|j| ((j % w) as f64 - x).hypot((j / w) as f64 - y))
                .fold(f64::INFINITY, f64::min);
            let got = f64::from(f.distance_m(i).unwrap_or(-1.0));
            assert!((got - best).abs() < 1e-4, "cell {i}: {got} vs {best}");
            let site = f.nearest_site(i).unwrap_or(usize::MAX);
            let sd = ((site % w) as f64 - x).hypot((site / w) as f64 - y);
            assert!(obs[site] && (sd - best).abs() < 1e-4);
        }
    }

    #[test]
    fn empty_grid_reports_the_diagonal() {
        let f = DistanceField::from_obstacles(spec(3, 4, 1.0), &[false; 12]);
        assert_eq!(f.distance_m(5), Some(5.0));
        assert_eq!(f.nearest_site(5), None);
    }
}
