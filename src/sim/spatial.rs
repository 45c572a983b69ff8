//! Broad phase for collisions and range sensors: the world's shapes in a uniform grid.
//!
//! In: the obstacle shapes. Out: the shapes near a point (collision checks) or within a
//! sensor's range (scans), so each physics step and each scan looks at a handful of shapes
//! instead of every pole in the world.

use super::world::Shape;
use crate::types::{Vec2, Vec3};

/// Side of a grid cell (m); about the spacing of poles in the densest thesis world.
const CELL_M: f64 = 2.0;
/// Largest number of cells; very large worlds get bigger cells instead.
const MAX_CELLS: f64 = 1_000_000.0;

/// A shape's horizontal bounding circle.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Bound {
    x: f64,
    y: f64,
    radius_m: f64,
}

impl Bound {
    fn of(shape: &Shape) -> Self {
        match *shape {
            Shape::Cylinder {
                center, radius_m, ..
            } => Self {
                x: center.x,
                y: center.y,
                radius_m,
            },
            Shape::Box {
                center, half_size, ..
            } => Self {
                x: center.x,
                y: center.y,
                radius_m: half_size.norm(),
            },
        }
    }

    /// Whether the circle comes within `reach_m` of (x, y); plain arithmetic, no sqrt.
    fn near(&self, x: f64, y: f64, reach_m: f64) -> bool {
        let (dx, dy) = (self.x - x, self.y - y);
        let r = self.radius_m + reach_m;
        dx * dx + dy * dy <= r * r
    }
}

/// Cell layout: `nx` x `ny` square cells of side `cell_m` from (`min_x`, `min_y`).
#[derive(Debug, Clone, Copy, PartialEq)]
struct Grid {
    cell_m: f64,
    min_x: f64,
    min_y: f64,
    nx: usize,
    ny: usize,
}

impl Grid {
    fn covering(bounds: &[Bound]) -> Self {
        if bounds.is_empty() {
            return Self {
                cell_m: CELL_M,
                min_x: 0.0,
                min_y: 0.0,
                nx: 0,
                ny: 0,
            };
        }
        let (mut min_x, mut min_y) = (f64::INFINITY, f64::INFINITY);
        let (mut max_x, mut max_y) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        for b in bounds {
            min_x = min_x.min(b.x - b.radius_m);
            min_y = min_y.min(b.y - b.radius_m);
            max_x = max_x.max(b.x + b.radius_m);
            max_y = max_y.max(b.y + b.radius_m);
        }
        let area = (max_x - min_x) * (max_y - min_y);
        let cell_m = CELL_M.max((area / MAX_CELLS).sqrt());
        let n = |span: f64| (span / cell_m).floor() as usize + 1;
        Self {
            cell_m,
            min_x,
            min_y,
            nx: n(max_x - min_x),
            ny: n(max_y - min_y),
        }
    }

    /// Cell indices overlapping the square of half side `reach_m` around (x, y).
    fn cells_near(&self, x: f64, y: f64, reach_m: f64) -> impl Iterator<Item = usize> {
        let cell_m = self.cell_m;
        let span = |v: f64, min: f64, n: usize| {
            let lo = ((v - reach_m - min) / cell_m).floor();
            let hi = ((v + reach_m - min) / cell_m).floor() + 1.0;
            let clamp = |c: f64| c.clamp(0.0, n as f64) as usize;
            clamp(lo)..clamp(hi)
        };
        let xs = span(x, self.min_x, self.nx);
        let nx = self.nx;
        span(y, self.min_y, self.ny).flat_map(move |iy| xs.clone().map(move |ix| iy * nx + ix))
    }
}

#[derive(Debug, Clone, PartialEq)]
pub struct ShapeIndex {
    shapes: Vec<Shape>,
    bounds: Vec<Bound>,
    grid: Grid,
    /// Shape indices per cell, row-major (`iy * nx + ix`).
    cells: Vec<Vec<usize>>,
}

impl ShapeIndex {
    pub fn new(shapes: Vec<Shape>) -> Self {
        let bounds: Vec<Bound> = shapes.iter().map(Bound::of).collect();
        let grid = Grid::covering(&bounds);
        let mut cells = vec![Vec::new(); grid.nx * grid.ny];
        for (i, b) in bounds.iter().enumerate() {
            for c in grid.cells_near(b.x, b.y, b.radius_m) {
                if let Some(cell) = cells.get_mut(c) {
                    cell.push(i);
                }
            }
        }
        Self {
            shapes,
            bounds,
            grid,
            cells,
        }
    }

    pub fn shapes(&self) -> &[Shape] {
        &self.shapes
    }

    /// Indices of the shapes whose bounding circle comes within `reach_m` of (x, y), each once,
    /// in ascending order.
    pub fn near(&self, x: f64, y: f64, reach_m: f64) -> Vec<usize> {
        let mut out = Vec::new();
        for c in self.grid.cells_near(x, y, reach_m) {
            if let Some(cell) = self.cells.get(c) {
                out.extend(
                    cell.iter()
                        .copied()
                        .filter(|&i| self.bounds.get(i).is_some_and(|b| b.near(x, y, reach_m))),
                );
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The first shape (lowest index) whose surface is closer than `radius_m` to `p`.
    pub fn touching(&self, p: &Vec3, radius_m: f64) -> Option<usize> {
        self.near(p.x, p.y, radius_m).into_iter().find(|&i| {
            self.shapes
                .get(i)
                .and_then(|s| s.distance_m(p))
                .is_some_and(|d| d < radius_m)
        })
    }

    /// Distance along a horizontal ray to the nearest shape among `candidates` (from
    /// [`Self::near`]), if any is hit.
    pub fn ray_m(&self, candidates: &[usize], origin: &Vec3, dir: &Vec2) -> Option<f64> {
        candidates
            .iter()
            .filter(|&&i| {
                // Skip shapes whose bounding circle the ray's line misses or that lie behind it.
                self.bounds.get(i).is_some_and(|b| {
                    let (cx, cy) = (b.x - origin.x, b.y - origin.y);
                    let along = cx * dir.x + cy * dir.y;
                    let across = cx * dir.y - cy * dir.x;
                    along >= -b.radius_m && across.abs() <= b.radius_m
                })
            })
            .filter_map(|&i| self.shapes.get(i).and_then(|s| s.ray_hit_m(origin, dir)))
            .reduce(f64::min)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pole(x: f64, y: f64) -> Shape {
        Shape::Cylinder {
            center: Vec2::new(x, y),
            radius_m: 0.25,
            height_m: 5.0,
        }
    }

    #[test]
    fn near_finds_the_same_shapes_as_a_full_scan() {
        let shapes: Vec<Shape> = (0..200)
            .map(|i| {
                let t = f64::from(i);
                pole((t * 7.3) % 40.0 - 20.0, (t * 3.1) % 40.0 - 20.0)
            })
            .collect();
        let index = ShapeIndex::new(shapes.clone());
        for &(x, y, reach) in &[(0.0, 0.0, 4.0), (-19.0, 18.0, 1.0), (30.0, 0.0, 10.0)] {
            let brute: Vec<usize> = shapes
                .iter()
                .enumerate()
                .filter(|(_, s)| {
                    s.distance_m(&Vec3::new(x, y, 0.0))
                        .is_some_and(|d| d <= reach)
                })
                .map(|(i, _)| i)
                .collect();
            let got = index.near(x, y, reach);
            assert!(
                brute.iter().all(|i| got.contains(i)),
                "missed some near ({x}, {y})"
            );
        }
    }

    #[test]
    fn touching_and_ray_agree_with_the_shapes() {
        let index = ShapeIndex::new(vec![pole(5.0, 0.0), pole(10.0, 0.0)]);
        assert_eq!(index.touching(&Vec3::new(4.7, 0.0, 1.0), 0.15), Some(0));
        assert_eq!(index.touching(&Vec3::new(4.0, 0.0, 1.0), 0.15), None);
        let candidates = index.near(0.0, 0.0, 20.0);
        let hit = index.ray_m(&candidates, &Vec3::new(0.0, 0.0, 1.0), &Vec2::new(1.0, 0.0));
        assert!((hit.unwrap() - 4.75).abs() < 1e-9);
        let back = index.ray_m(
            &candidates,
            &Vec3::new(0.0, 0.0, 1.0),
            &Vec2::new(-1.0, 0.0),
        );
        assert_eq!(back, None);
    }

    #[test]
    fn an_empty_world_has_nothing_near() {
        let index = ShapeIndex::new(Vec::new());
        assert!(index.near(0.0, 0.0, 100.0).is_empty());
        assert_eq!(index.touching(&Vec3::zeros(), 1.0), None);
    }
}
