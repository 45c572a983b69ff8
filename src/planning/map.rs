//! The map a planner reads: grid, distance field, Voronoi diagram and optional graph.
//!
//! In: an [`OccupancyGrid`] (and optionally a [`TopoGraph`] and the time the grid was last
//! updated). Out: a [`PlanningMap`] with everything derived once per map update, so each plan
//! only searches. Inflation is not baked in: the safety distance is per request and compared with
//! the distance field.

use crate::mapping::graph::TopoGraph;
use crate::mapping::grid::OccupancyGrid;

use super::distance::DistanceField;

pub use crate::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD;

/// A grid prepared for planning.
#[derive(Debug, Clone)]
pub struct PlanningMap {
    grid: OccupancyGrid,
    field: DistanceField,
    gvd: Vec<bool>,
    graph: Option<TopoGraph>,
    occupied_threshold: i8,
    stamp_s: Option<f64>,
    revision: Option<u64>,
}

impl PlanningMap {
    /// Computes the distance field and the Voronoi diagram (O(cells)).
    pub fn new(grid: OccupancyGrid, occupied_threshold: i8) -> Self {
        let field = DistanceField::compute(&grid, occupied_threshold);
        let gvd = voronoi_cells(&grid, &field, occupied_threshold);
        PlanningMap {
            grid,
            field,
            gvd,
            graph: None,
            occupied_threshold,
            stamp_s: None,
            revision: None,
        }
    }

    pub fn with_graph(mut self, graph: TopoGraph) -> Self {
        self.graph = Some(graph);
        self
    }

    /// Time (seconds, caller's clock) the grid was last updated, for the staleness check.
    pub fn with_stamp(mut self, stamp_s: f64) -> Self {
        self.stamp_s = Some(stamp_s);
        self
    }

    /// Unknown cells within `radius_m` of an occupied cell made occupied (O(occupied cells x
    /// disc)); the grid as it was when `radius_m` is under one cell.
    pub fn shadowed(grid: &OccupancyGrid, occupied_threshold: i8, radius_m: f64) -> OccupancyGrid {
        let spec = *grid.spec();
        let r = (radius_m / spec.resolution_m + 1e-9).floor() as i64;
        let mut out = grid.clone();
        if r < 1 {
            return out;
        }
        let (w, h) = (i64::from(spec.width_cells), i64::from(spec.height_cells));
        let data = grid.data();
        let mut grown = out.data().to_vec();
        for (i, &v) in data.iter().enumerate() {
            if v < occupied_threshold {
                continue;
            }
            let (x, y) = ((i as i64) % w, (i as i64) / w);
            for dy in -r..=r {
                for dx in -r..=r {
                    let (nx, ny) = (x + dx, y + dy);
                    if dx * dx + dy * dy > r * r || nx < 0 || ny < 0 || nx >= w || ny >= h {
                        continue;
                    }
                    let j = (ny * w + nx) as usize;
                    if grown[j] < 0 {
                        grown[j] = 100;
                    }
                }
            }
        }
        if let Ok(g) = OccupancyGrid::from_data(spec, grown) {
            out = g;
        }
        out
    }

    /// The revision of the drone map this was built from, for caches.
    pub fn with_revision(mut self, revision: u64) -> Self {
        self.revision = Some(revision);
        self
    }

    pub fn revision(&self) -> Option<u64> {
        self.revision
    }

    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
    }

    pub fn field(&self) -> &DistanceField {
        &self.field
    }

    pub fn graph(&self) -> Option<&TopoGraph> {
        self.graph.as_ref()
    }

    pub fn occupied_threshold(&self) -> i8 {
        self.occupied_threshold
    }

    pub fn stamp_s(&self) -> Option<f64> {
        self.stamp_s
    }

    /// Whether a cell lies on the generalised Voronoi diagram.
    pub fn is_voronoi(&self, index: usize) -> bool {
        self.gvd.get(index).copied().unwrap_or(false)
    }
}

/// A free cell is on the diagram when a 4-neighbour's nearest obstacle is not adjacent to its
/// own (sites more than one cell apart, diagonals included): the two are closest to different
/// parts of the obstacle boundary, so the cell sits on the ridge of the distance field.
fn voronoi_cells(grid: &OccupancyGrid, field: &DistanceField, threshold: i8) -> Vec<bool> {
    let spec = grid.spec();
    let w = spec.width_cells as usize;
    let h = spec.height_cells as usize;
    let data = grid.data();
    let free = |i: usize| data.get(i).is_some_and(|&v| v < threshold);
    let xy = |i: usize| ((i % w) as i64, (i / w) as i64);
    let mut gvd = vec![false; w * h];
    for (i, slot) in gvd.iter_mut().enumerate() {
        if !free(i) {
            continue;
        }
        let Some(si) = field.nearest_site(i) else {
            continue;
        };
        let (x, y) = xy(i);
        let (sx, sy) = xy(si);
        let neighbours = [
            (x > 0).then(|| i - 1),
            (x + 1 < w as i64).then(|| i + 1),
            (y > 0).then(|| i - w),
            (y + 1 < h as i64).then(|| i + w),
        ];
        *slot = neighbours.into_iter().flatten().any(|j| {
            free(j)
                && field.nearest_site(j).is_some_and(|sj| {
                    let (tx, ty) = xy(sj);
                    (tx - sx).pow(2) + (ty - sy).pow(2) > 2
                })
        });
    }
    gvd
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::GridSpec;
    use nalgebra::Vector2;

    #[test]
    fn unknown_cells_near_an_obstacle_are_shadowed_free_and_far_ones_are_not() {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 20,
            height_cells: 1,
            origin_enu_m: Vector2::new(0.0, 0.0),
        };
        // free | obstacle at 5 | unknown 6..20
        let data: Vec<i8> = (0..20)
            .map(|x| match x {
                0..=4 => 0,
                5 => 100,
                _ => crate::mapping::UNKNOWN,
            })
            .collect();
        let grid = OccupancyGrid::from_data(spec, data).unwrap();
        let shadowed = PlanningMap::shadowed(&grid, 31, 0.3);
        let d = shadowed.data();
        assert_eq!(&d[0..5], &[0; 5], "free cells stay free");
        assert_eq!(&d[5..9], &[100; 4], "unknown within 0.3 m becomes obstacle");
        assert!(d[9..].iter().all(|&v| v == crate::mapping::UNKNOWN));
        assert_eq!(PlanningMap::shadowed(&grid, 31, 0.05).data(), grid.data());
    }

    #[test]
    fn corridor_diagram_is_its_centre_line() {
        // 12 x 7 cells, walls on rows 0 and 6: the free rows 1..=5 have their ridge at row 3.
        let (w, h) = (12usize, 7usize);
        let mut data = vec![0i8; w * h];
        for x in 0..w {
            data[x] = 100;
            data[(h - 1) * w + x] = 100;
        }
        let spec = GridSpec {
            resolution_m: 1.0,
            width_cells: w as u32,
            height_cells: h as u32,
            origin_enu_m: Vector2::zeros(),
        };
        let m = PlanningMap::new(OccupancyGrid::from_data(spec, data).unwrap(), 50);
        for x in 0..w {
            let rows: Vec<usize> = (0..h).filter(|&y| m.is_voronoi(y * w + x)).collect();
            // Row 3 is equidistant; rows 2 and 4 border it with sites on opposite walls.
            assert!(
                rows.contains(&3) || (rows.contains(&2) && rows.contains(&4)),
                "x {x}: {rows:?}"
            );
            assert!(
                rows.iter().all(|&y| (2..=4).contains(&y)),
                "x {x}: {rows:?}"
            );
        }
    }
}
