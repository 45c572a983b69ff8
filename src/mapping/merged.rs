//! The fleet's merged map: every drone's scans in a layer of its own, fused into one global
//! grid, and the changed regions waiting to be sent to clients.
//!
//! In: a [`MapConfig`] (the known map becomes the `known` layer), then each drone's scans.
//! Out: the merged grid, each layer, and [`MapPatch`]es: one per drone that changed the
//! merged grid since the last [`FleetMap::take_patches`], covering only the changed cells.

use std::collections::BTreeMap;
use std::time::Duration;

use nalgebra::Vector2;
use serde::Serialize;

use super::config::MapConfig;
use super::grid::{CellBox, GridPatch, GridSpec, OccupancyGrid};
use super::layers::LayeredMap;
use super::scan::RangeScan;
use super::MapError;

/// Name of the layer holding the known map.
pub const KNOWN_LAYER: &str = "known";

/// A changed region of the merged grid, as the `map_update` message carries it.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct MapPatch {
    /// The drone whose scans changed it.
    pub drone: String,
    /// `[x_min, y_min, x_max, y_max]` (ENU m) of the region.
    pub bbox_enu_m: [f64; 4],
    /// The region as a grid of its own (origin = its south-west corner).
    pub spec: GridSpec,
    /// Row-major from the south-west cell: -1 unknown, else occupancy 0..=100.
    pub data: Vec<i8>,
}

/// Per-drone layers, their fusion and the regions not yet published.
#[derive(Debug, Clone)]
pub struct FleetMap {
    layers: LayeredMap,
    pending: BTreeMap<String, CellBox>,
    /// Changed regions not yet taken by [`FleetMap::take_unsynced`] (a copy kept elsewhere).
    unsynced: BTreeMap<String, CellBox>,
    update_period: Duration,
}

impl FleetMap {
    pub fn new(config: &MapConfig) -> Result<Self, MapError> {
        let spec = *config.initial.spec();
        let mut layers = LayeredMap::new(spec, config.fuse, config.params)?;
        if config.initial.data().iter().any(|&v| v != super::UNKNOWN) {
            layers.merge_local(KNOWN_LAYER, &config.initial)?;
        }
        Ok(FleetMap {
            layers,
            pending: BTreeMap::new(),
            unsynced: BTreeMap::new(),
            update_period: config.update_period,
        })
    }

    /// Shortest time between two batches of patches sent to clients.
    pub fn update_period(&self) -> Duration {
        self.update_period
    }

    /// Inserts one of `drone`'s scans into its layer and the merged grid.
    pub fn insert(&mut self, drone: &str, scan: &RangeScan) -> Result<(), MapError> {
        if let Some(changed) = self.layers.insert(drone, scan)? {
            self.changed(drone, changed);
        }
        Ok(())
    }

    /// Whether a drone grid on `spec` can be copied in as is (see [`Self::copy_from_drone`]).
    pub fn same_spec(&self, spec: &GridSpec) -> bool {
        self.layers.global.spec() == spec
    }

    /// Takes a region the drone's own map server changed into the drone's layer: the drone's
    /// scans are ray-cast once, by its own map server. The grid must be on the merged spec.
    pub fn copy_from_drone(
        &mut self,
        drone: &str,
        own: &OccupancyGrid,
        region: CellBox,
    ) -> Result<(), MapError> {
        if let Some(changed) = self.layers.copy_region(drone, own, region)? {
            self.changed(drone, changed);
        }
        Ok(())
    }

    fn changed(&mut self, drone: &str, region: CellBox) {
        for regions in [&mut self.pending, &mut self.unsynced] {
            let slot = regions.entry(drone.to_string()).or_insert(region);
            *slot = slot.union(region);
        }
    }

    /// The merged grid's regions changed since the last call, one patch per drone, for a copy
    /// of the grid kept in step elsewhere (the frontier allocator's thread); independent of
    /// [`FleetMap::take_patches`].
    pub fn take_unsynced(&mut self) -> Vec<GridPatch> {
        let grid = &self.layers.global;
        std::mem::take(&mut self.unsynced)
            .into_values()
            .filter_map(|region| grid.patch(region))
            .collect()
    }

    /// Inserts a drone's scans; invalid ones are skipped (the drone's own map counts them).
    pub fn insert_all(&mut self, drone: &str, scans: &[RangeScan]) {
        for scan in scans {
            // Rejections are counted once, by the drone's own map server.
            let _ = self.insert(drone, scan);
        }
    }

    pub fn merged(&self) -> &OccupancyGrid {
        &self.layers.global
    }

    /// One layer: a drone's scans, or [`KNOWN_LAYER`].
    pub fn layer(&self, name: &str) -> Option<&OccupancyGrid> {
        self.layers.layers.get(name)
    }

    pub fn layer_names(&self) -> Vec<String> {
        self.layers.layers.keys().cloned().collect()
    }

    /// The regions of the merged grid changed since the last call, one per drone.
    pub fn take_patches(&mut self) -> Vec<MapPatch> {
        let grid = &self.layers.global;
        std::mem::take(&mut self.pending)
            .into_iter()
            .filter_map(|(drone, region)| {
                let patch = grid.patch(region)?;
                let spec = grid.spec();
                let lo = spec.origin_enu_m
                    + Vector2::new(f64::from(patch.region.min.x), f64::from(patch.region.min.y))
                        * spec.resolution_m;
                let size = Vector2::new(
                    f64::from(patch.region.width_cells()),
                    f64::from(patch.region.height_cells()),
                ) * spec.resolution_m;
                Some(MapPatch {
                    drone,
                    bbox_enu_m: [lo.x, lo.y, lo.x + size.x, lo.y + size.y],
                    spec: GridSpec {
                        resolution_m: spec.resolution_m,
                        width_cells: patch.region.width_cells(),
                        height_cells: patch.region.height_cells(),
                        origin_enu_m: lo,
                    },
                    data: patch.data,
                })
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::Cell;
    use crate::mapping::scan::Beam;
    use nalgebra::Vector3;
    use std::sync::Arc;

    fn scan_from(x: f64, y: f64, range_m: f64) -> RangeScan {
        RangeScan {
            origin_enu_m: Vector3::new(x, y, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(range_m),
            }],
        }
    }

    #[test]
    fn each_drone_has_a_layer_and_patches_cover_only_what_changed() {
        let config = MapConfig::open_field().unwrap();
        let mut m = FleetMap::new(&config).unwrap();
        m.insert("drone_0", &scan_from(0.05, 0.05, 1.0)).unwrap();
        m.insert("drone_1", &scan_from(0.05, 5.05, 2.0)).unwrap();
        assert_eq!(m.layer_names(), ["drone_0", "drone_1"]);
        let patches = m.take_patches();
        assert_eq!(patches.len(), 2);
        let p0 = &patches[0];
        assert_eq!(p0.drone, "drone_0");
        assert_eq!(p0.spec.height_cells, 1);
        assert_eq!(p0.data.len(), p0.spec.width_cells as usize);
        assert!((p0.bbox_enu_m[0] - 0.0).abs() < 1e-9 && (p0.bbox_enu_m[2] - 1.1).abs() < 1e-9);
        assert_eq!(*p0.data.last().unwrap(), 40, "hit at the end");
        assert!(m.take_patches().is_empty(), "nothing new");
        let c = m.merged().spec().cell_at(Vector2::new(2.05, 5.05)).unwrap();
        assert_eq!(m.merged().get(c), Some(40));
        assert_eq!(m.layer("drone_0").unwrap().get(c), Some(-1));
    }

    #[test]
    fn a_known_map_is_a_layer_of_its_own() {
        let mut config = MapConfig::open_field().unwrap();
        let mut known = (*config.initial).clone();
        known.set(Cell { x: 10, y: 10 }, 100).unwrap();
        config.initial = Arc::new(known);
        let m = FleetMap::new(&config).unwrap();
        assert_eq!(m.layer_names(), [KNOWN_LAYER]);
        assert_eq!(m.merged().get(Cell { x: 10, y: 10 }), Some(100));
    }

    #[test]
    fn a_drone_grid_copied_by_region_gives_the_same_merged_map_as_its_scans() {
        use crate::mapping::server::MapServer;
        let config = MapConfig::open_field().unwrap();
        let scans = [scan_from(0.05, 0.05, 1.0), scan_from(3.05, 2.05, 2.5)];
        let mut by_scans = FleetMap::new(&config).unwrap();
        let mut by_copy = FleetMap::new(&config).unwrap();
        let mut own = MapServer::new(&config);
        for scan in &scans {
            by_scans.insert("drone_0", scan).unwrap();
            own.insert(Duration::from_secs(1), std::slice::from_ref(scan));
            let region = own.last_changed().unwrap();
            by_copy
                .copy_from_drone("drone_0", own.grid(), region)
                .unwrap();
        }
        assert_eq!(by_copy.merged(), by_scans.merged());
        assert_eq!(by_copy.take_patches(), by_scans.take_patches());
        let elsewhere = crate::mapping::config::MapSection {
            size_m: Some([10.0, 10.0]),
            ..Default::default()
        };
        let other = MapServer::new(&elsewhere.config(None).unwrap().unwrap());
        assert!(!by_copy.same_spec(other.grid().spec()));
        assert!(by_copy
            .copy_from_drone("drone_0", other.grid(), other.grid().spec().full_box())
            .is_err());
    }
}
