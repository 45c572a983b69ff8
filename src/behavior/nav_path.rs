//! Geometry of a planned path for `navigate_to`: how far along it the vehicle is, what is left,
//! and whether new map data blocks what is left.
//!
//! In: the path (start + waypoints, `earth` ENU m), the vehicle position, and for the blockage
//! check an occupancy grid, its obstacle threshold and a clearance radius. Out: the index of the
//! segment being flown, the remaining length, the first blocked point ahead if any, and how far
//! ahead the path has been seen free. Only the cells within the radius of the remaining path are
//! read.

use crate::mapping::raycast::trace_segment;
use crate::mapping::OccupancyGrid;
use crate::types::Vec3;
use nalgebra::Vector2;

/// The part of the path ahead seen free (see [`NavPath::clear_ahead`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ClearAhead {
    /// Length (m) from the vehicle along the path.
    pub clear_m: f64,
    /// Whether it reaches the goal.
    pub to_goal: bool,
}

const NEIGHBOURS: [(i64, i64); 8] = [
    (-1, -1),
    (0, -1),
    (1, -1),
    (-1, 0),
    (1, 0),
    (-1, 1),
    (0, 1),
    (1, 1),
];

/// Cell offsets within `radius_m` (centre to centre) of a cell.
fn disc_offsets(radius_m: f64, resolution_m: f64) -> Vec<(i64, i64)> {
    let r = (radius_m / resolution_m + 1e-9).floor() as i64;
    let r2 = radius_m * radius_m;
    let mut out = Vec::new();
    for dy in -r..=r {
        for dx in -r..=r {
            if ((dx * dx + dy * dy) as f64) * resolution_m * resolution_m <= r2 {
                out.push((dx, dy));
            }
        }
    }
    out
}

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

    /// The waypoints not yet reached (the goal last).
    pub fn ahead(&self) -> &[Vec3] {
        self.points.get(self.segment + 1..).unwrap_or(&[])
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

    /// Point at `s_m` along the rest of the path from `position` (the goal if beyond it).
    pub fn point_ahead(&self, position: &Vec3, s_m: f64) -> Vec3 {
        let rest = self.remaining_points(position);
        let mut left = s_m.max(0.0);
        for w in rest.windows(2) {
            let len = (w[1] - w[0]).norm();
            if left <= len && len > 1e-12 {
                return w[0] + (w[1] - w[0]) * (left / len);
            }
            left -= len;
        }
        rest.last().copied().unwrap_or(*position)
    }

    /// How far the rest of the path has been seen well enough to fly: the length from
    /// `position` along which every cell within `radius_m` is observed free, looked at up to
    /// `max_m`. An unknown cell with at least 6 of its 8 neighbours free counts as seen: rays
    /// leave such one-cell gaps and lines between them, and an obstacle there would have shown as
    /// hit cells; a 2 x 2 hole does not.
    pub fn clear_ahead(
        &self,
        position: &Vec3,
        grid: &OccupancyGrid,
        occupied_threshold: i8,
        radius_m: f64,
        max_m: f64,
    ) -> ClearAhead {
        let spec = *grid.spec();
        let step_m = spec.resolution_m / 2.0;
        let disc = disc_offsets(radius_m, spec.resolution_m);
        let free = |x: i64, y: i64| -> bool {
            u32::try_from(x)
                .ok()
                .zip(u32::try_from(y).ok())
                .and_then(|(x, y)| grid.get(crate::mapping::Cell { x, y }))
                .is_some_and(|v| (0..occupied_threshold).contains(&v))
        };
        let seen_free = |x: i64, y: i64| -> bool {
            let Some(v) = u32::try_from(x)
                .ok()
                .zip(u32::try_from(y).ok())
                .and_then(|(cx, cy)| grid.get(crate::mapping::Cell { x: cx, y: cy }))
            else {
                return false;
            };
            if v >= occupied_threshold {
                return false;
            }
            v >= 0
                || NEIGHBOURS
                    .iter()
                    .filter(|(dx, dy)| free(x + dx, y + dy))
                    .count()
                    >= 6
        };
        let mut last_cell = None;
        let mut point_clear = |p: &Vec3| -> bool {
            let Some(c) = spec.cell_at(p.xy()) else {
                return false;
            };
            if last_cell == Some(c) {
                return true;
            }
            last_cell = Some(c);
            let (cx, cy) = (i64::from(c.x), i64::from(c.y));
            disc.iter().all(|&(dx, dy)| seen_free(cx + dx, cy + dy))
        };
        let rest = self.remaining_points(position);
        let mut travelled_m = 0.0;
        if rest.first().is_some_and(|p| !point_clear(p)) {
            return ClearAhead {
                clear_m: 0.0,
                to_goal: false,
            };
        }
        for w in rest.windows(2) {
            let len = (w[1] - w[0]).norm();
            let steps = (len / step_m).ceil().max(1.0) as usize;
            for k in 1..=steps {
                let s = travelled_m + len * k as f64 / steps as f64;
                if !point_clear(&(w[0] + (w[1] - w[0]) * (k as f64 / steps as f64))) {
                    return ClearAhead {
                        clear_m: (s - step_m).max(0.0),
                        to_goal: false,
                    };
                }
                if s >= max_m {
                    return ClearAhead {
                        clear_m: s,
                        to_goal: false,
                    };
                }
            }
            travelled_m += len;
        }
        ClearAhead {
            clear_m: travelled_m,
            to_goal: true,
        }
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

    /// 10 m x 4 m at 0.1 m around y = 0, known free for x < `seen_to_m`, unknown beyond.
    fn seen_up_to(seen_to_m: f64) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 100,
            height_cells: 40,
            origin_enu_m: Vector2::new(-1.0, -2.0),
        };
        let data = (0..spec.cell_count())
            .map(|i| {
                let c = spec.cell_of_index(i).unwrap();
                if spec.cell_center_enu_m(c).x < seen_to_m {
                    0
                } else {
                    UNKNOWN
                }
            })
            .collect();
        OccupancyGrid::from_data(spec, data).unwrap()
    }

    #[test]
    fn the_path_is_clear_as_far_as_it_was_seen_free_with_the_radius_around() {
        let p = NavPath::new(Vec3::new(0.0, 0.0, 1.0), &[Vec3::new(8.0, 0.0, 1.0)]);
        let here = Vec3::new(0.0, 0.0, 1.0);
        let grid = seen_up_to(3.0);
        let clear = p.clear_ahead(&here, &grid, 31, 0.5, 10.0);
        assert!(!clear.to_goal);
        assert!((2.35..=2.5).contains(&clear.clear_m), "{clear:?}");
        let short = p.clear_ahead(&here, &grid, 31, 0.5, 1.0);
        assert!(
            (1.0..1.1).contains(&short.clear_m),
            "looked only 1 m: {short:?}"
        );
        let all = p.clear_ahead(&here, &seen_up_to(20.0), 31, 0.5, 20.0);
        assert!(all.to_goal && (all.clear_m - 8.0).abs() < 1e-9, "{all:?}");
        let p2 = p.point_ahead(&here, 2.0);
        assert!((p2 - Vec3::new(2.0, 0.0, 1.0)).norm() < 1e-9);
    }

    #[test]
    fn a_ray_gap_counts_as_seen_a_hole_or_an_obstacle_does_not() {
        let p = NavPath::new(Vec3::new(0.0, 0.0, 1.0), &[Vec3::new(8.0, 0.0, 1.0)]);
        let here = Vec3::new(0.0, 0.0, 1.0);
        let mut grid = seen_up_to(20.0);
        let spec = *grid.spec();
        let gap = spec.cell_at(Vector2::new(2.05, 0.35)).unwrap();
        grid.set(gap, UNKNOWN).unwrap();
        let clear = p.clear_ahead(&here, &grid, 31, 0.5, 20.0);
        assert!(
            clear.to_goal,
            "a one-cell gap between free cells: {clear:?}"
        );
        let mut line = seen_up_to(20.0);
        for x in [1.05, 1.15, 1.25, 1.35] {
            line.set(spec.cell_at(Vector2::new(x, 0.35)).unwrap(), UNKNOWN)
                .unwrap();
        }
        let between_rays = p.clear_ahead(&here, &line, 31, 0.5, 20.0);
        assert!(
            between_rays.to_goal,
            "a line between two rays: {between_rays:?}"
        );
        let next = spec.cell_at(Vector2::new(2.15, 0.35)).unwrap();
        grid.set(next, UNKNOWN).unwrap();
        let below = spec.cell_at(Vector2::new(2.05, 0.25)).unwrap();
        grid.set(below, UNKNOWN).unwrap();
        let below_next = spec.cell_at(Vector2::new(2.15, 0.25)).unwrap();
        grid.set(below_next, UNKNOWN).unwrap();
        let hole = p.clear_ahead(&here, &grid, 31, 0.5, 20.0);
        assert!(
            !hole.to_goal && hole.clear_m < 2.0,
            "a 2 x 2 hole: {hole:?}"
        );
        let mut walled = seen_up_to(20.0);
        walled.set(gap, 100).unwrap();
        let wall = p.clear_ahead(&here, &walled, 31, 0.5, 20.0);
        assert!(!wall.to_goal && wall.clear_m < 2.0, "{wall:?}");
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
