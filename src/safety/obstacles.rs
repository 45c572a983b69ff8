//! The obstacles the safety stage keeps off when it moves a vehicle itself: a separation's
//! slide along another drone's kept sphere or its push apart must never carry the vehicle into
//! something the drone has mapped (an exploration once slid a climbing drone sideways into a
//! pole while it gave way).
//!
//! In: the drone's own occupancy grid and, when the drone is one of a fleet, the fleet's merged
//! map (what the other drones mapped too), each with its occupied threshold; the vehicle's
//! position. Out: the occupied cells within reach, each as the horizontal direction from the
//! cell to the vehicle and its distance; the separation caps the closing speed along each.

use crate::mapping::grid::OccupancyGrid;
use crate::types::{FleetView, Vec3};
use nalgebra::Vector2;

/// The maps as the stage reads them: in each, cells at or above its `occupied` threshold are
/// obstacles. The drone's own map first, then the fleet's merged one if there is one.
#[derive(Debug, Clone, Copy)]
pub struct Obstacles<'a> {
    grids: [Option<(&'a OccupancyGrid, i8)>; 2],
}

/// What the stage sees around the vehicle: the fleet, and the drone's map when it has one.
#[derive(Debug, Clone, Copy)]
pub struct Around<'a> {
    pub fleet: &'a FleetView,
    pub obstacles: Option<Obstacles<'a>>,
    /// What the range sensor hit lately, for a drone whose estimate drifts.
    pub seen: Option<super::Seen<'a>>,
}

impl<'a> From<&'a FleetView> for Around<'a> {
    /// The fleet alone (a drone without a map).
    fn from(fleet: &'a FleetView) -> Self {
        Self {
            fleet,
            obstacles: None,
            seen: None,
        }
    }
}

/// One mapped obstacle cell near the vehicle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Near {
    /// Horizontal unit vector from the cell's centre to the vehicle.
    pub away: Vec3,
    /// Horizontal distance from the cell's centre to the vehicle (m).
    pub distance_m: f64,
}

impl<'a> Obstacles<'a> {
    pub fn new(grid: &'a OccupancyGrid, occupied: i8) -> Self {
        Self {
            grids: [Some((grid, occupied)), None],
        }
    }

    /// These and the obstacles of `grid` too (the fleet's merged map: a pole another drone
    /// mapped, which this one has not seen).
    pub fn and(self, grid: &'a OccupancyGrid, occupied: i8) -> Self {
        Self {
            grids: [self.grids[0], Some((grid, occupied))],
        }
    }

    /// The occupied cells whose centres lie within `reach_m` of `here`, horizontally (the map
    /// is a plane at flight height; an obstacle in it stands at every height).
    pub(super) fn within(&self, here: Vec3, reach_m: f64) -> Vec<Near> {
        let mut near = Vec::new();
        if !(reach_m > 0.0 && here.x.is_finite() && here.y.is_finite()) {
            return near;
        }
        for (grid, occupied) in self.grids.iter().flatten() {
            near_in(grid, *occupied, here, reach_m, &mut near);
        }
        near
    }
}

/// The occupied cells of `grid` within `reach_m` of `here`, horizontally, onto `near`.
fn near_in(grid: &OccupancyGrid, occupied: i8, here: Vec3, reach_m: f64, near: &mut Vec<Near>) {
    let spec = grid.spec();
    let at = Vector2::new(here.x, here.y);
    let span = (reach_m / spec.resolution_m).ceil() as i64;
    let centre = ((at - spec.origin_enu_m) / spec.resolution_m).map(|c| c.floor() as i64);
    let (w, h) = (i64::from(spec.width_cells), i64::from(spec.height_cells));
    for y in (centre.y - span).max(0)..=(centre.y + span).min(h - 1) {
        for x in (centre.x - span).max(0)..=(centre.x + span).min(w - 1) {
            let cell = crate::mapping::grid::Cell {
                x: x as u32,
                y: y as u32,
            };
            if grid.get(cell).is_none_or(|v| v < occupied) {
                continue;
            }
            let offset = at - spec.cell_center_enu_m(cell);
            let distance_m = offset.norm();
            if distance_m > reach_m {
                continue;
            }
            let away = if distance_m > 1e-6 {
                offset / distance_m
            } else {
                Vector2::new(1.0, 0.0)
            };
            near.push(Near {
                away: Vec3::new(away.x, away.y, 0.0),
                distance_m,
            });
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::{Cell, GridSpec};

    fn grid_with(cells: &[(u32, u32)]) -> OccupancyGrid {
        let mut g = OccupancyGrid::new(GridSpec {
            resolution_m: 0.1,
            width_cells: 40,
            height_cells: 40,
            origin_enu_m: Vector2::new(-2.0, -2.0),
        })
        .unwrap();
        for &(x, y) in cells {
            g.set(Cell { x, y }, 100).unwrap();
        }
        g
    }

    #[test]
    fn only_occupied_cells_within_reach_count_with_their_direction() {
        // Cell (25, 20) has its centre at (0.55, 0.05); (39, 39) is 2.6 m away.
        let mut g = grid_with(&[(25, 20), (39, 39)]);
        g.set(Cell { x: 15, y: 20 }, 20).unwrap(); // seen, but under the threshold
        let near = Obstacles::new(&g, 31).within(Vec3::new(0.0, 0.05, 1.0), 1.0);
        assert_eq!(near.len(), 1);
        assert!((near[0].distance_m - 0.55).abs() < 1e-9);
        assert!((near[0].away - Vec3::new(-1.0, 0.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn a_cell_only_the_fleet_mapped_counts_as_well_as_the_drones_own() {
        let own = grid_with(&[(25, 20)]);
        let fleet = grid_with(&[(15, 20)]);
        let here = Vec3::new(0.0, 0.05, 1.0);
        assert_eq!(Obstacles::new(&own, 31).within(here, 1.0).len(), 1);
        let both = Obstacles::new(&own, 31).and(&fleet, 31).within(here, 1.0);
        let mut directions: Vec<f64> = both.iter().map(|n| n.away.x).collect();
        directions.sort_by(f64::total_cmp);
        assert_eq!(directions, vec![-1.0, 1.0], "{both:?}");
    }

    #[test]
    fn a_vehicle_off_the_grid_or_not_finite_sees_nothing_and_does_not_panic() {
        let g = grid_with(&[(0, 0)]);
        let o = Obstacles::new(&g, 31);
        assert!(o.within(Vec3::new(100.0, 100.0, 1.0), 1.0).is_empty());
        assert!(o.within(Vec3::new(f64::NAN, 0.0, 1.0), 1.0).is_empty());
        assert_eq!(o.within(Vec3::new(-2.3, -2.3, 1.0), 1.0).len(), 1);
    }
}
