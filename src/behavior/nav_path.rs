//! Geometry of a planned path for `navigate_to`: how far along it the vehicle is, what is left,
//! and whether new map data blocks what is left.
//!
//! In: the path (start + waypoints, `earth` ENU m), the vehicle position, and for the blockage
//! check an occupancy grid, its obstacle threshold and a clearance radius. Out: the index of the
//! segment being flown, the remaining length, and the first blocked point ahead if any. Only the
//! cells within the radius of the remaining path are read.

use crate::mapping::raycast::trace_segment;
use crate::mapping::OccupancyGrid;
use crate::types::Vec3;
use nalgebra::Vector2;

/// A path being flown.
#[derive(Debug, Clone, PartialEq)]
pub struct NavPath {
    /// Where the plan started, then every waypoint (the last one is the goal).
    points: Vec<Vec3>,
    /// Index of the segment `points[segment] -> points[segment + 1]` being flown.
    segment: usize,
}

/// Segments looked at beyond the current one when locating the vehicle: a vehicle never skips
/// more, and a path that comes back near itself is not mistaken for progress.
const LOOKAHEAD_SEGMENTS: usize = 3;

/// Closest point of segment `a -> b` to `p`, as the fraction along it.
fn projection(a: &Vec3, b: &Vec3, p: &Vec3) -> f64 {
    let d = b - a;
    let len2 = d.norm_squared();
    if len2 < 1e-12 {
        return 0.0;
    }
    ((p - a).dot(&d) / len2).clamp(0.0, 1.0)
}

impl NavPath {
    pub fn new(start: Vec3, waypoints: &[Vec3]) -> Self {
        let mut points = Vec::with_capacity(waypoints.len() + 1);
        points.push(start);
        points.extend_from_slice(waypoints);
        NavPath { points, segment: 0 }
    }

    /// Start and waypoints, as `[x, y, z]` for feedback.
    pub fn points_json(&self) -> Vec<[f64; 3]> {
        self.points.iter().map(|p| [p.x, p.y, p.z]).collect()
    }

    /// Moves the current segment forward to the one nearest `position`.
    pub fn advance(&mut self, position: &Vec3) {
        let last = self.points.len().saturating_sub(2);
        let mut best = (f64::INFINITY, self.segment);
        for k in self.segment..=(self.segment + LOOKAHEAD_SEGMENTS).min(last) {
            let (Some(a), Some(b)) = (self.points.get(k), self.points.get(k + 1)) else {
                break;
            };
            let t = projection(a, b, position);
            let d = (a + (b - a) * t - position).norm();
            if d < best.0 - 1e-9 {
                best = (d, k);
            }
        }
        self.segment = best.1;
    }

    /// The rest of the path from `position`: its projection on the current segment, then the
    /// remaining waypoints.
    fn remaining_points(&self, position: &Vec3) -> Vec<Vec3> {
        let mut out = Vec::new();
        if let (Some(a), Some(b)) = (
            self.points.get(self.segment),
            self.points.get(self.segment + 1),
        ) {
            out.push(a + (b - a) * projection(a, b, position));
        }
        out.extend(self.points.iter().skip(self.segment + 1));
        out
    }

    /// Length left (m): to the path, then along it to the goal.
    pub fn remaining_m(&self, position: &Vec3) -> f64 {
        let rest = self.remaining_points(position);
        let to_path = rest.first().map_or(0.0, |p| (p - position).norm());
        to_path + rest.windows(2).map(|w| (w[1] - w[0]).norm()).sum::<f64>()
    }

    /// The first point of the remaining path (beyond `skip_m` of `position`, where the vehicle
    /// already is) with an obstacle cell within `radius_m` (cell centre to cell centre).
    pub fn first_blocked(
        &self,
        position: &Vec3,
        grid: &OccupancyGrid,
        occupied_threshold: i8,
        radius_m: f64,
        skip_m: f64,
    ) -> Option<Vector2<f64>> {
        let spec = *grid.spec();
        let r_cells = (radius_m / spec.resolution_m).floor() as i64;
        let r2 = radius_m * radius_m;
        let blocked_near = |index: usize| -> bool {
            let Some(c) = spec.cell_of_index(index) else {
                return false;
            };
            for dy in -r_cells..=r_cells {
                for dx in -r_cells..=r_cells {
                    let d2 = ((dx * dx + dy * dy) as f64) * spec.resolution_m * spec.resolution_m;
                    let (x, y) = (i64::from(c.x) + dx, i64::from(c.y) + dy);
                    if d2 > r2 || x < 0 || y < 0 {
                        continue;
                    }
                    let cell = crate::mapping::Cell {
                        x: x as u32,
                        y: y as u32,
                    };
                    if grid.get(cell).is_some_and(|v| v >= occupied_threshold) {
                        return true;
                    }
                }
            }
            false
        };
        let here = position.xy();
        let mut found = None;
        for w in self.remaining_points(position).windows(2) {
            let (a, b) = (w[0].xy(), w[1].xy());
            trace_segment(&spec, a, b, |index| {
                let Some(c) = spec.cell_of_index(index) else {
                    return true;
                };
                let centre = spec.cell_center_enu_m(c);
                if (centre - here).norm() <= skip_m || !blocked_near(index) {
                    return true;
                }
                found = Some(centre);
                false
            });
            if found.is_some() {
                break;
            }
        }
        found
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::{GridSpec, UNKNOWN};

    fn l_path() -> NavPath {
        NavPath::new(
            Vec3::new(0.0, 0.0, 1.0),
            &[Vec3::new(4.0, 0.0, 1.0), Vec3::new(4.0, 4.0, 1.0)],
        )
    }

    #[test]
    fn progress_and_remaining_length_follow_the_vehicle() {
        let mut p = l_path();
        let here = Vec3::new(1.0, 0.5, 1.0);
        p.advance(&here);
        assert!((p.remaining_m(&here) - (0.5 + 3.0 + 4.0)).abs() < 1e-9);
        let later = Vec3::new(4.1, 2.0, 1.0);
        p.advance(&later);
        assert!((p.remaining_m(&later) - 2.1).abs() < 1e-9);
        p.advance(&Vec3::new(0.0, 0.0, 1.0));
        assert!(
            (p.remaining_m(&later) - 2.1).abs() < 1e-9,
            "never goes back"
        );
    }

    #[test]
    fn an_obstacle_near_the_path_ahead_blocks_it_one_behind_does_not() {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 100,
            height_cells: 100,
            origin_enu_m: Vector2::new(-2.0, -2.0),
        };
        let mut grid = OccupancyGrid::from_data(spec, vec![UNKNOWN; 10_000]).unwrap();
        let p = l_path();
        let start = Vec3::new(0.0, 0.0, 1.0);
        assert_eq!(p.first_blocked(&start, &grid, 31, 0.3, 0.0), None);
        // 0.25 m beside the second leg.
        let c = spec.cell_at(Vector2::new(4.25, 2.05)).unwrap();
        grid.set(c, 100).unwrap();
        let hit = p.first_blocked(&start, &grid, 31, 0.3, 0.0).unwrap();
        assert!((1.8..2.1).contains(&hit.y), "{hit:?}");
        assert_eq!(p.first_blocked(&start, &grid, 31, 0.1, 0.0), None);
        let mut passed = l_path();
        let beyond = Vec3::new(4.0, 3.0, 1.0);
        passed.advance(&beyond);
        assert_eq!(passed.first_blocked(&beyond, &grid, 31, 0.3, 0.0), None);
    }
}
