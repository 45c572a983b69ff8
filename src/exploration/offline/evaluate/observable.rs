//! The observable set: the cells a beam of range R could reach from somewhere the drones could
//! fly, the ceiling any exploration can reach (exploration-research §4.3, `Area_obs`).
//!
//! In: the grid, the indexed obstacles, the drones' start points, the parameters (range,
//! clearance, ray spacing, altitude). Out: the observable [`CellSet`].
//!
//! Reachable space is the free cells (centre at least `free_clearance_m` from every obstacle)
//! 4-connected to a start; every reachable cell is observable (a drone can be there). Visibility
//! is symmetric, so instead of casting from every reachable point the other cells cast back:
//! a cell not inside an obstacle is observable if a ray from its centre, one every
//! `view_step_deg`, reaches a reachable cell within R before entering an obstacle cell
//! (a cell whose centre is inside an obstacle). Rays are tried spread out first and stop at
//! the first success, so the cells next to free space cost a few steps; only cells within R
//! (Chebyshev) of reachable space are tried. Obstacle cells on the surface (the cell reaches
//! outside the shape) are observable when a 4-neighbour outside the obstacle is, which is
//! where a beam hitting that surface ends. All of it is at cell resolution (0.1 m).

use super::raster::{CellSet, Raster};
use super::EvalParams;
use crate::sim::spatial::ShapeIndex;
use crate::sim::world::Shape;
use crate::types::Vec3;
use std::collections::VecDeque;

/// How far from a start to look for a free cell when the start itself is not free (m).
const SEED_SEARCH_M: f64 = 1.0;

pub fn observable(
    raster: &Raster,
    index: &ShapeIndex,
    starts: &[(f64, f64)],
    params: &EvalParams,
) -> CellSet {
    let obstacles = Obstacles::rasterize(raster, index, params);
    let reachable = reachable(raster, &obstacles, starts);
    let mut observable = reachable.clone();
    let range_cells = (params.beam_range_m / raster.cell_m).ceil() as usize;
    let near = within_chebyshev(raster, &reachable, range_cells);
    let directions = directions(params.view_step_deg);
    for iy in 0..raster.ny {
        for ix in 0..raster.nx {
            let i = iy * raster.nx + ix;
            if reachable.contains(i) || obstacles.inside.contains(i) || !near.contains(i) {
                continue;
            }
            let from = raster.centre(ix, iy);
            let sees = directions.iter().any(|&(dx, dy)| {
                let to = (
                    from.0 + params.beam_range_m * dx,
                    from.1 + params.beam_range_m * dy,
                );
                let mut found = false;
                raster.traverse(from, to, |c| {
                    if reachable.contains(c) {
                        found = true;
                    }
                    !found && !obstacles.inside.contains(c)
                });
                found
            });
            if sees {
                observable.insert(i);
            }
        }
    }
    for iy in 0..raster.ny {
        for ix in 0..raster.nx {
            let i = iy * raster.nx + ix;
            if obstacles.surface.contains(i)
                && neighbours4(raster, ix, iy)
                    .any(|n| observable.contains(n) && !obstacles.inside.contains(n))
            {
                observable.insert(i);
            }
        }
    }
    observable
}

/// Cells by their centre's distance to the nearest obstacle.
struct Obstacles {
    /// Centre inside an obstacle.
    inside: CellSet,
    /// Inside, but the cell reaches outside the shape (centre within half a diagonal).
    surface: CellSet,
    /// Centre nearer than the free-space clearance (inside included).
    near: CellSet,
}

impl Obstacles {
    fn rasterize(raster: &Raster, index: &ShapeIndex, params: &EvalParams) -> Self {
        let cells = raster.cells();
        let mut out = Self {
            inside: CellSet::new(cells),
            surface: CellSet::new(cells),
            near: CellSet::new(cells),
        };
        let mut deep = CellSet::new(cells);
        let half_diagonal_m = raster.cell_m * std::f64::consts::FRAC_1_SQRT_2;
        for shape in index.shapes() {
            let (cx, cy, r) = match *shape {
                Shape::Cylinder {
                    center, radius_m, ..
                } => (center.x, center.y, radius_m),
                Shape::Box {
                    center, half_size, ..
                } => (center.x, center.y, half_size.norm()),
            };
            let reach = r + params.free_clearance_m + raster.cell_m;
            let lo = raster.cell_clamped(cx - reach, cy - reach);
            let hi = raster.cell_clamped(cx + reach, cy + reach);
            for iy in lo.1..=hi.1 {
                for ix in lo.0..=hi.0 {
                    let (x, y) = raster.centre(ix, iy);
                    let Some(d) = shape.distance_m(&Vec3::new(x, y, params.altitude_m)) else {
                        continue;
                    };
                    let i = iy * raster.nx + ix;
                    if d < params.free_clearance_m {
                        out.near.insert(i);
                    }
                    if d < 0.0 {
                        out.inside.insert(i);
                        if d > -half_diagonal_m {
                            out.surface.insert(i);
                        } else {
                            deep.insert(i);
                        }
                    }
                }
            }
        }
        // A surface cell of one shape deep inside another stays hidden.
        out.surface.remove_all(&deep);
        out
    }
}

fn neighbours4(raster: &Raster, ix: usize, iy: usize) -> impl Iterator<Item = usize> {
    let (nx, ny) = (raster.nx, raster.ny);
    [
        (ix.checked_sub(1), Some(iy)),
        ((ix + 1 < nx).then_some(ix + 1), Some(iy)),
        (Some(ix), iy.checked_sub(1)),
        (Some(ix), (iy + 1 < ny).then_some(iy + 1)),
    ]
    .into_iter()
    .filter_map(move |(x, y)| Some(y? * nx + x?))
}

/// Free cells 4-connected to the starts (a start in an obstacle's margin seeds from the
/// nearest free cell within [`SEED_SEARCH_M`]).
fn reachable(raster: &Raster, obstacles: &Obstacles, starts: &[(f64, f64)]) -> CellSet {
    let mut seen = CellSet::new(raster.cells());
    let mut queue = VecDeque::new();
    let search = (SEED_SEARCH_M / raster.cell_m).ceil() as i64;
    for &(x, y) in starts {
        let Some((sx, sy)) = raster.cell_of(x, y) else {
            continue;
        };
        let mut best: Option<(i64, usize)> = None;
        for dy in -search..=search {
            for dx in -search..=search {
                let (cx, cy) = (sx as i64 + dx, sy as i64 + dy);
                if cx < 0 || cy < 0 || cx >= raster.nx as i64 || cy >= raster.ny as i64 {
                    continue;
                }
                let i = cy as usize * raster.nx + cx as usize;
                let d2 = dx * dx + dy * dy;
                if !obstacles.near.contains(i) && best.is_none_or(|(b, _)| d2 < b) {
                    best = Some((d2, i));
                }
            }
        }
        if let Some((_, i)) = best {
            if seen.insert(i) {
                queue.push_back(i);
            }
        }
    }
    while let Some(i) = queue.pop_front() {
        for n in neighbours4(raster, i % raster.nx, i / raster.nx) {
            if !obstacles.near.contains(n) && seen.insert(n) {
                queue.push_back(n);
            }
        }
    }
    seen
}

/// Cells within `steps` cells (Chebyshev) of `set`.
fn within_chebyshev(raster: &Raster, set: &CellSet, steps: usize) -> CellSet {
    let mut out = set.clone();
    let mut frontier: Vec<usize> = (0..raster.cells()).filter(|&i| set.contains(i)).collect();
    for _ in 0..steps {
        let mut next = Vec::new();
        for i in frontier {
            let (ix, iy) = (i % raster.nx, i / raster.nx);
            for y in iy.saturating_sub(1)..=(iy + 1).min(raster.ny - 1) {
                for x in ix.saturating_sub(1)..=(ix + 1).min(raster.nx - 1) {
                    let n = y * raster.nx + x;
                    if out.insert(n) {
                        next.push(n);
                    }
                }
            }
        }
        if next.is_empty() {
            break;
        }
        frontier = next;
    }
    out
}

/// Unit directions every `step_deg`, ordered so that consecutive ones are spread around the
/// circle (by bit-reversed index).
fn directions(step_deg: f64) -> Vec<(f64, f64)> {
    let n = (360.0 / step_deg).round().max(4.0) as u32;
    let mut ks: Vec<u32> = (0..n).collect();
    ks.sort_by_key(|k| k.reverse_bits());
    ks.into_iter()
        .map(|k| {
            let a = f64::from(k) * std::f64::consts::TAU / f64::from(n);
            (a.cos(), a.sin())
        })
        .collect()
}
