//! Multi-drone map merging: one layer per drone, fused into one global grid.
//!
//! In: per-drone [`RangeScan`]s (or whole local grids from drones that map on board).
//! Out: a [`LayeredMap`] whose `layers` hold each drone's own grid (all on the global spec) and
//! whose `global` grid is, cell by cell, the [`FuseRule`] of the layers that know the cell.
//! This keeps each contribution separate, as the thesis's multi-layer map does, instead of
//! Aerostack2's single additive global grid where one drone's stale view cannot be told apart.

use std::collections::BTreeMap;

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::grid::{Cell, CellBox, GridSpec, InsertParams, OccupancyGrid, UNKNOWN};
use super::scan::RangeScan;
use super::MapError;

/// In the cells of a region written with [`LayeredMap::set_region`]: this cell is left as it is
/// (regions from the fleet bus are coalesced, and a union of two boxes has cells neither set).
pub const KEEP: i8 = i8::MIN;

/// How layer values combine into the global grid (unknown layers are ignored).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum FuseRule {
    /// The most occupied value wins: conservative, an obstacle seen by any drone stays.
    #[default]
    Max,
    /// Rounded mean of the known values.
    MeanKnown,
}

/// Per-drone layers plus their fusion.
#[derive(Debug, Clone, PartialEq)]
pub struct LayeredMap {
    pub global: OccupancyGrid,
    /// Drone id -> that drone's grid, on the same spec as `global`.
    pub layers: BTreeMap<String, OccupancyGrid>,
    pub rule: FuseRule,
    pub params: InsertParams,
}

impl LayeredMap {
    pub fn new(spec: GridSpec, rule: FuseRule, params: InsertParams) -> Result<Self, MapError> {
        Ok(LayeredMap {
            global: OccupancyGrid::new(spec)?,
            layers: BTreeMap::new(),
            rule,
            params,
        })
    }

    fn layer_mut(&mut self, drone: &str) -> Result<&mut OccupancyGrid, MapError> {
        if !self.layers.contains_key(drone) {
            let fresh = OccupancyGrid::new(*self.global.spec())?;
            self.layers.insert(drone.to_owned(), fresh);
        }
        self.layers
            .get_mut(drone)
            .ok_or_else(|| MapError::InvalidSpec("layer vanished".into()))
    }

    /// Inserts a drone's scan into its layer and re-fuses the changed cells. Returns the changed
    /// box of the global grid (`None` if nothing changed).
    pub fn insert(&mut self, drone: &str, scan: &RangeScan) -> Result<Option<CellBox>, MapError> {
        Ok(self.insert_both(drone, scan)?.1)
    }

    /// As [`Self::insert`], returning the changed box of the drone's layer as well:
    /// `(layer, global)`.
    pub fn insert_both(
        &mut self,
        drone: &str,
        scan: &RangeScan,
    ) -> Result<(Option<CellBox>, Option<CellBox>), MapError> {
        let params = self.params;
        let changed = self.layer_mut(drone)?.insert_scan(scan, &params)?;
        Ok((changed, changed.and_then(|b| self.refuse(b))))
    }

    /// Writes a region of a drone's layer (row-major `cells` from `region.min`, on the global
    /// spec; [`KEEP`] leaves a cell as it is) and re-fuses the cells that changed. Returns the
    /// changed box of the global grid.
    pub fn set_region(
        &mut self,
        drone: &str,
        region: CellBox,
        cells: &[i8],
    ) -> Result<Option<CellBox>, MapError> {
        let full = self.global.spec().full_box();
        let w = region.width_cells() as usize;
        if region.intersect(full) != Some(region)
            || cells.len() != w * region.height_cells() as usize
        {
            return Err(MapError::InvalidSpec(
                "a layer region must lie inside the grid and match its cells".into(),
            ));
        }
        let layer = self.layer_mut(drone)?;
        let mut changed: Option<CellBox> = None;
        for (k, &v) in cells.iter().enumerate() {
            let c = Cell {
                x: region.min.x + (k % w) as u32,
                y: region.min.y + (k / w) as u32,
            };
            if v != KEEP && layer.get(c) != Some(v) {
                layer.set(c, v)?;
                match changed.as_mut() {
                    Some(b) => b.include(c),
                    None => changed = Some(CellBox::of_cell(c)),
                }
            }
        }
        Ok(changed.and_then(|b| self.refuse(b)))
    }

    /// Copies a box of a drone's own grid (on the global spec) into its layer and re-fuses it:
    /// the scans were ray-cast once, by the drone's map server. Returns the changed box of the
    /// global grid.
    pub fn copy_region(
        &mut self,
        drone: &str,
        own: &OccupancyGrid,
        region: CellBox,
    ) -> Result<Option<CellBox>, MapError> {
        if own.spec() != self.global.spec() {
            return Err(MapError::InvalidSpec(
                "a drone grid copied into its layer must be on the global spec".into(),
            ));
        }
        let Some(region) = region.intersect(self.global.spec().full_box()) else {
            return Ok(None);
        };
        let layer = self.layer_mut(drone)?;
        for y in region.min.y..=region.max.y {
            for x in region.min.x..=region.max.x {
                let c = Cell { x, y };
                if let Some(v) = own.get(c) {
                    layer.set(c, v)?;
                }
            }
        }
        Ok(self.refuse(region))
    }

    /// Replaces a drone's layer with its own local grid, resampled (nearest cell centre) onto the
    /// global spec; global cells outside the local grid keep the layer's previous values.
    /// Returns the changed box of the global grid.
    pub fn merge_local(
        &mut self,
        drone: &str,
        local: &OccupancyGrid,
    ) -> Result<Option<CellBox>, MapError> {
        let spec = *self.global.spec();
        // Global cells whose centres can fall inside the local grid.
        let ls = local.spec();
        let lo = (ls.origin_enu_m - spec.origin_enu_m) / spec.resolution_m;
        let hi = lo
            + Vector2::new(f64::from(ls.width_cells), f64::from(ls.height_cells)) * ls.resolution_m
                / spec.resolution_m;
        let range = |a: f64, b: f64, n: u32| {
            let first = (a.floor().max(0.0) as u32).min(n);
            let end = ((b.ceil().max(0.0)) as u32).min(n);
            first..end
        };
        let (xs, ys) = (
            range(lo.x, hi.x, spec.width_cells),
            range(lo.y, hi.y, spec.height_cells),
        );
        let layer = self.layer_mut(drone)?;
        let mut covered: Option<CellBox> = None;
        for y in ys {
            for x in xs.clone() {
                let c = Cell { x, y };
                let Some(v) = local.get_at(spec.cell_center_enu_m(c)) else {
                    continue;
                };
                layer.set(c, v)?;
                match covered.as_mut() {
                    Some(b) => b.include(c),
                    None => covered = Some(CellBox::of_cell(c)),
                }
            }
        }
        Ok(covered.and_then(|b| self.refuse(b)))
    }

    /// Recomputes `global` over a box from the layers; returns the box of changed cells. Row by
    /// row over the layers' cells (a hot path: every map update of every drone comes here).
    fn refuse(&mut self, region: CellBox) -> Option<CellBox> {
        let region = region.intersect(self.global.spec().full_box())?;
        let w = self.global.spec().width_cells as usize;
        let (x0, x1) = (region.min.x as usize, region.max.x as usize + 1);
        let mut fused = vec![UNKNOWN; x1 - x0];
        let mut sums = vec![(0i32, 0i32); x1 - x0];
        let mut changed: Option<CellBox> = None;
        for y in region.min.y..=region.max.y {
            let row = y as usize * w;
            let span = row + x0..row + x1;
            match self.rule {
                // Unknown (-1) is below every known value: the most occupied known value, or
                // unknown where no layer knows the cell.
                FuseRule::Max => {
                    fused.fill(UNKNOWN);
                    for layer in self.layers.values() {
                        for (f, &v) in fused.iter_mut().zip(&layer.data()[span.clone()]) {
                            *f = (*f).max(v);
                        }
                    }
                }
                FuseRule::MeanKnown => {
                    sums.fill((0, 0));
                    for layer in self.layers.values() {
                        for (s, &v) in sums.iter_mut().zip(&layer.data()[span.clone()]) {
                            if v != UNKNOWN {
                                *s = (s.0 + i32::from(v), s.1 + 1);
                            }
                        }
                    }
                    for (f, &(sum, n)) in fused.iter_mut().zip(&sums) {
                        *f = if n == 0 {
                            UNKNOWN
                        } else {
                            ((sum + n / 2) / n) as i8
                        };
                    }
                }
            }
            for (k, &f) in fused.iter().enumerate() {
                if self.global.data()[row + x0 + k] == f {
                    continue;
                }
                let c = Cell {
                    x: (x0 + k) as u32,
                    y,
                };
                if self.global.set(c, f).is_ok() {
                    match changed.as_mut() {
                        Some(b) => b.include(c),
                        None => changed = Some(CellBox::of_cell(c)),
                    }
                }
            }
        }
        changed
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::scan::Beam;
    use nalgebra::Vector3;

    fn spec(w: u32, h: u32, res: f64, ox: f64) -> GridSpec {
        GridSpec {
            resolution_m: res,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::new(ox, 0.0),
        }
    }

    fn beam_scan(x: f64, range: f64) -> RangeScan {
        RangeScan {
            origin_enu_m: Vector3::new(x, 0.5, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.0,
            range_max_m: 10.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(range),
            }],
        }
    }

    fn row0(g: &OccupancyGrid) -> Vec<i8> {
        g.data()[..g.spec().width_cells as usize].to_vec()
    }

    #[test]
    fn layers_stay_separate_and_global_takes_max() {
        let mut m =
            LayeredMap::new(spec(6, 1, 1.0, 0.0), FuseRule::Max, InsertParams::default()).unwrap();
        m.insert("cf1", &beam_scan(0.5, 3.0)).unwrap(); // hit at cell 3
        let mut s = beam_scan(5.5, 4.0);
        s.yaw_rad = std::f64::consts::PI; // west, from cell 5 to cell 1: misses 5..2, hit at 1
        m.insert("cf2", &s).unwrap();
        assert_eq!(row0(&m.layers["cf1"]), vec![0, 0, 0, 40, -1, -1]);
        assert_eq!(row0(&m.layers["cf2"]), vec![-1, 40, 0, 0, 0, 0]);
        assert_eq!(row0(&m.global), vec![0, 40, 0, 40, 0, 0]);
    }

    #[test]
    fn mean_rule_averages_known_values() {
        let mut m = LayeredMap::new(
            spec(6, 1, 1.0, 0.0),
            FuseRule::MeanKnown,
            InsertParams::default(),
        )
        .unwrap();
        m.insert("a", &beam_scan(0.5, 3.0)).unwrap();
        m.insert("b", &beam_scan(0.5, 4.0)).unwrap();
        // Cell 3: a says 40, b says 0 -> 20; cell 4: only b, 40.
        assert_eq!(row0(&m.global), vec![0, 0, 0, 20, 40, -1]);
    }

    #[test]
    fn merge_local_clips_a_grid_hanging_over_the_edge() {
        let mut m =
            LayeredMap::new(spec(4, 1, 1.0, 0.0), FuseRule::Max, InsertParams::default()).unwrap();
        // Local grid covers x in [-2, 2): only global cells 0 and 1 are inside it.
        let local = OccupancyGrid::from_data(spec(4, 1, 1.0, -2.0), vec![100, 100, 30, 0]).unwrap();
        m.merge_local("cf4", &local).unwrap();
        assert_eq!(row0(&m.global), vec![30, 0, -1, -1]);
        // A grid entirely outside changes nothing.
        let far = OccupancyGrid::from_data(spec(2, 1, 1.0, 50.0), vec![100, 100]).unwrap();
        assert_eq!(m.merge_local("cf4", &far).unwrap(), None);
    }

    #[test]
    fn merge_local_resamples_a_finer_offset_grid() {
        let mut m =
            LayeredMap::new(spec(4, 1, 1.0, 0.0), FuseRule::Max, InsertParams::default()).unwrap();
        // Local grid at 0.5 m covering x in [1, 3): global cells 1 and 2 (centres 1.5, 2.5).
        let local =
            OccupancyGrid::from_data(spec(4, 2, 0.5, 1.0), vec![0, 0, 90, 90, 0, 0, 90, 90])
                .unwrap();
        let changed = m.merge_local("cf3", &local).unwrap();
        assert_eq!(row0(&m.global), vec![-1, 0, 90, -1]);
        assert_eq!(
            changed,
            Some(CellBox {
                min: Cell { x: 1, y: 0 },
                max: Cell { x: 2, y: 0 }
            })
        );
    }
}
