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
        let mut mask = obstacle
            .get(..n)
            .map_or_else(|| obstacle.to_vec(), <[bool]>::to_vec);
        mask.resize(n, false);

        // Column pass, row by row for locality: nearest obstacle row above and below per column.
        let mut col_dist = vec![u32::MAX; n];
        let mut col_site_y = vec![NO_SITE; n];
        let mut last = vec![NO_SITE; w];
        let rows = mask
            .chunks_exact(w)
            .zip(col_dist.chunks_exact_mut(w))
            .zip(col_site_y.chunks_exact_mut(w))
            .enumerate();
        for (y, ((obs, dist), site)) in rows {
            let y = y as u32;
            for (((&o, d), s), l) in obs.iter().zip(dist).zip(site).zip(last.iter_mut()) {
                if o {
                    *l = y;
                }
                if *l != NO_SITE {
                    *d = y - *l;
                    *s = *l;
                }
            }
        }
        last.fill(NO_SITE);
        let rows = mask
            .chunks_exact(w)
            .zip(col_dist.chunks_exact_mut(w))
            .zip(col_site_y.chunks_exact_mut(w))
            .enumerate()
            .rev();
        for (y, ((obs, dist), site)) in rows {
            let y = y as u32;
            for (((&o, d), s), l) in obs.iter().zip(dist).zip(site).zip(last.iter_mut()) {
                if o {
                    *l = y;
                }
                if *l != NO_SITE && *l - y < *d {
                    *d = *l - y;
                    *s = *l;
                }
            }
        }

        // Row pass: lower envelope of the parabolas (x - q)^2 + f(q) rooted at columns q that
        // see an obstacle; `bounds[k]` separates `roots[k]` and `roots[k + 1]`. Intersections
        // are kept as exact fractions `num / den` (den > 0) and compared by cross-multiplying,
        // so the pass has no division (values stay below 2^50 for the largest grids).
        let res = spec.resolution_m;
        let max_distance_m = ((w * w + h * h) as f64).sqrt() * res;
        let res32 = res as f32;
        let max32 = max_distance_m as f32;
        let mut dist_m = vec![max32; n];
        let mut site = vec![NO_SITE; n];
        let mut roots: Vec<(i64, i64, u32)> = Vec::with_capacity(w); // (q, f(q), site y)
        let mut bounds: Vec<(i64, i64)> = Vec::with_capacity(w);
        let rows = col_dist
            .chunks_exact(w)
            .zip(col_site_y.chunks_exact(w))
            .zip(dist_m.chunks_exact_mut(w))
            .zip(site.chunks_exact_mut(w));
        for (((cdist, csite), out_d), out_s) in rows {
            roots.clear();
            bounds.clear();
            for (q, (&d, &sy)) in cdist.iter().zip(csite).enumerate() {
                if sy == NO_SITE {
                    continue;
                }
                let (q, fq) = (q as i64, i64::from(d) * i64::from(d));
                while let Some(&(v, fv, _)) = roots.last() {
                    let num = (fq + q * q) - (fv + v * v);
                    let den = 2 * (q - v);
                    if bounds.last().is_some_and(|&(bn, bd)| num * bd <= bn * den) {
                        roots.pop();
                        bounds.pop();
                    } else {
                        bounds.push((num, den));
                        break;
                    }
                }
                roots.push((q, fq, sy));
            }
            if roots.is_empty() {
                continue;
            }
            let mut k = 0;
            for (x, (d, s)) in out_d.iter_mut().zip(out_s.iter_mut()).enumerate() {
                let x = x as i64;
                while bounds.get(k).is_some_and(|&(bn, bd)| bn < x * bd) {
                    k += 1;
                }
                let Some(&(q, fq, sy)) = roots.get(k) else {
                    break;
                };
                let d2 = (x - q) * (x - q) + fq;
                *d = ((d2 as f32).sqrt() * res32).min(max32);
                *s = sy * w as u32 + q as u32;
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
