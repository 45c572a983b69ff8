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
use super::grid::{Cell, CellBox, GridPatch, GridSpec, OccupancyGrid};
use super::layers::LayeredMap;
use super::registration::{OccupiedSince, Reference};
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
    /// This host's drones' layer regions not yet sent on the fleet bus (`None`: no bus).
    bus_pending: Option<BTreeMap<String, CellBox>>,
    /// Since when each merged cell is occupied, for registering scans against the map.
    since: OccupiedSince,
    /// Changed regions whose stamps [`FleetMap::stamp`] has not yet brought up to date.
    unstamped: BTreeMap<String, CellBox>,
    occupied_threshold: i8,
    /// The merged grid's region changed since the last [`FleetMap::take_logged`] (the flight
    /// log's copy).
    unlogged: Option<CellBox>,
}

/// A region of one drone's layer, as the fleet bus carries it.
#[derive(Debug, Clone, PartialEq)]
pub struct LayerRegion {
    pub drone: String,
    /// The grid the region belongs to (the merged map's).
    pub grid: GridSpec,
    pub region: CellBox,
    /// Row-major from `region.min`.
    pub cells: Vec<i8>,
}

impl FleetMap {
    pub fn new(config: &MapConfig) -> Result<Self, MapError> {
        let spec = *config.initial.spec();
        let mut layers = LayeredMap::new(spec, config.fuse, config.params)?;
        if config.initial.data().iter().any(|&v| v != super::UNKNOWN) {
            layers.merge_local(KNOWN_LAYER, &config.initial)?;
        }
        // The known map's obstacles were there before the run.
        let since =
            OccupiedSince::new(&layers.global, config.occupied_threshold, f64::NEG_INFINITY);
        Ok(FleetMap {
            layers,
            pending: BTreeMap::new(),
            unsynced: BTreeMap::new(),
            update_period: config.update_period,
            bus_pending: None,
            since,
            unstamped: BTreeMap::new(),
            occupied_threshold: config.occupied_threshold,
            unlogged: None,
        })
    }

    /// Shortest time between two batches of patches sent to clients.
    pub fn update_period(&self) -> Duration {
        self.update_period
    }

    /// Inserts one of `drone`'s scans into its layer and the merged grid.
    pub fn insert(&mut self, drone: &str, scan: &RangeScan) -> Result<(), MapError> {
        let (layer, global) = self.layers.insert_both(drone, scan)?;
        if let Some(changed) = global {
            self.changed(drone, changed);
        }
        if let (Some(bus), Some(changed)) = (self.bus_pending.as_mut(), layer) {
            add(bus, drone, changed);
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
        if let Some(bus) = self.bus_pending.as_mut() {
            if let Some(r) = region.intersect(self.layers.global.spec().full_box()) {
                add(bus, drone, r);
            }
        }
        Ok(())
    }

    /// From now on, keeps the regions this host's drones change for the fleet bus.
    pub fn enable_bus(&mut self) {
        self.bus_pending.get_or_insert_with(BTreeMap::new);
    }

    /// The regions of this host's drones' layers changed since the last call.
    pub fn take_bus_regions(&mut self) -> Vec<LayerRegion> {
        let pending = self
            .bus_pending
            .as_mut()
            .map(std::mem::take)
            .unwrap_or_default();
        pending
            .into_iter()
            .filter_map(|(drone, region)| self.layer_region(&drone, region))
            .collect()
    }

    /// The known part of a drone's layer (its bounding box), to send whole.
    pub fn keyframe(&self, drone: &str) -> Option<LayerRegion> {
        let layer = self.layers.layers.get(drone)?;
        let spec = layer.spec();
        let w = spec.width_cells as usize;
        let mut known: Option<CellBox> = None;
        for (i, _) in layer
            .data()
            .iter()
            .enumerate()
            .filter(|(_, &v)| v != super::UNKNOWN)
        {
            let c = Cell {
                x: (i % w) as u32,
                y: (i / w) as u32,
            };
            match known.as_mut() {
                Some(b) => b.include(c),
                None => known = Some(CellBox::of_cell(c)),
            }
        }
        self.layer_region(drone, known?)
    }

    fn layer_region(&self, drone: &str, region: CellBox) -> Option<LayerRegion> {
        let layer = self.layers.layers.get(drone)?;
        let patch = layer.patch(region)?;
        Some(LayerRegion {
            drone: drone.to_string(),
            grid: *layer.spec(),
            region: patch.region,
            cells: patch.data,
        })
    }

    /// Writes a region of another Kestrel's drone's layer, heard on the fleet bus. The region
    /// must be on this map's grid (every node of a fleet maps on the same `[map]` grid).
    pub fn apply_remote(&mut self, region: &LayerRegion) -> Result<(), MapError> {
        if region.grid != *self.layers.global.spec() {
            return Err(MapError::InvalidSpec(format!(
                "the peer maps on a {} x {} grid of {} m at ({}, {}); this Kestrel's is {} x {} of {} m at ({}, {}): give every node the same [map] section",
                region.grid.width_cells,
                region.grid.height_cells,
                region.grid.resolution_m,
                region.grid.origin_enu_m.x,
                region.grid.origin_enu_m.y,
                self.layers.global.spec().width_cells,
                self.layers.global.spec().height_cells,
                self.layers.global.spec().resolution_m,
                self.layers.global.spec().origin_enu_m.x,
                self.layers.global.spec().origin_enu_m.y,
            )));
        }
        if let Some(changed) =
            self.layers
                .set_region(&region.drone, region.region, &region.cells)?
        {
            self.changed(&region.drone, changed);
        }
        Ok(())
    }

    /// Layers kept (each drone's, the known map's).
    pub fn layer_count(&self) -> usize {
        self.layers.layers.len()
    }

    fn changed(&mut self, drone: &str, region: CellBox) {
        for regions in [&mut self.pending, &mut self.unsynced, &mut self.unstamped] {
            let slot = regions.entry(drone.to_string()).or_insert(region);
            *slot = slot.union(region);
        }
        self.unlogged = Some(self.unlogged.map_or(region, |r| r.union(region)));
    }

    /// The region of the merged grid changed since the last call, whoever changed it (for the
    /// flight log); independent of the other takers.
    pub fn take_logged(&mut self) -> Option<CellBox> {
        self.unlogged.take()
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

    /// Stamps the cells changed since the last call that became occupied with `now` (and
    /// unstamps those no longer so): see [`Self::reference`].
    pub fn stamp(&mut self, now: Duration) {
        for region in std::mem::take(&mut self.unstamped).into_values() {
            self.since.restamp(
                &self.layers.global,
                self.occupied_threshold,
                region,
                now.as_secs_f64(),
            );
        }
    }

    /// The merged grid with since when each cell is occupied, to register scans against.
    pub fn reference(&self) -> Reference<'_> {
        Reference {
            grid: &self.layers.global,
            since: &self.since,
            occupied_threshold: self.occupied_threshold,
        }
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

fn add(pending: &mut BTreeMap<String, CellBox>, drone: &str, changed: CellBox) {
    let slot = pending.entry(drone.to_string()).or_insert(changed);
    *slot = slot.union(changed);
}

#[cfg(test)]
mod tests {
    use super::*;
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
    fn obstacles_are_registered_against_once_they_have_settled() {
        let config = MapConfig::open_field().unwrap();
        let mut m = FleetMap::new(&config).unwrap();
        // drone_0 maps an obstacle at x 1.05 at 2 s; drone_1's hit falls 0.2 m short of it.
        m.insert("drone_0", &scan_from(0.05, 0.05, 1.0)).unwrap();
        m.stamp(Duration::from_secs(2));
        let hit = [Vector2::new(0.85, 0.05)];
        let east = Vector2::new(0.2, 0.0);
        assert_eq!(
            m.reference().fit_score(&hit, east, 6.9, 5.0).score,
            0.0,
            "not settled"
        );
        assert_eq!(m.reference().fit_score(&hit, east, 62.0, 5.0).score, 1.0);
        assert_eq!(
            m.reference()
                .fit_score(&hit, Vector2::zeros(), 62.0, 5.0)
                .score,
            -0.5,
            "seen free"
        );
        // Stamped once: a later stamp keeps when it became occupied.
        m.insert("drone_0", &scan_from(0.05, 0.05, 1.0)).unwrap();
        m.stamp(Duration::from_secs(9));
        assert_eq!(m.reference().fit_score(&hit, east, 62.0, 5.0).score, 1.0);
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

    /// The flight log's region covers every drone's changes and is taken apart from the patches.
    #[test]
    fn the_logged_region_is_the_union_of_all_changes() {
        let config = MapConfig::open_field().unwrap();
        let mut m = FleetMap::new(&config).unwrap();
        m.insert("drone_0", &scan_from(0.05, 0.05, 1.0)).unwrap();
        m.insert("drone_1", &scan_from(0.05, 5.05, 2.0)).unwrap();
        assert_eq!(m.take_patches().len(), 2);
        let region = m.take_logged().unwrap();
        let cell = |x, y| m.merged().spec().cell_at(Vector2::new(x, y)).unwrap();
        assert_eq!(region.min, cell(0.05, 0.05), "drone_0's first cell");
        assert_eq!(region.max, cell(2.05, 5.05), "drone_1's hit");
        assert_eq!(m.take_logged(), None, "nothing new");
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

    #[test]
    fn layers_sent_over_the_bus_give_the_peer_the_same_merged_map() {
        let config = MapConfig::open_field().unwrap();
        let mut here = FleetMap::new(&config).unwrap();
        let mut there = FleetMap::new(&config).unwrap();
        here.enable_bus();
        there.enable_bus();
        here.insert("drone_0", &scan_from(0.05, 0.05, 1.0)).unwrap();
        there
            .insert("drone_1", &scan_from(0.05, 5.05, 2.0))
            .unwrap();
        for r in here.take_bus_regions() {
            there.apply_remote(&r).unwrap();
        }
        for r in there.take_bus_regions() {
            assert_eq!(r.drone, "drone_1", "only its own drones' regions go out");
            here.apply_remote(&r).unwrap();
        }
        assert_eq!(here.merged(), there.merged());
        assert!(here.take_bus_regions().is_empty() && there.take_bus_regions().is_empty());
        // A keyframe repairs a peer that missed regions: it carries everything known.
        let mut late = FleetMap::new(&config).unwrap();
        here.insert("drone_0", &scan_from(3.05, 3.05, 2.5)).unwrap();
        late.apply_remote(&here.keyframe("drone_0").unwrap())
            .unwrap();
        late.apply_remote(&there.keyframe("drone_1").unwrap())
            .unwrap();
        assert_eq!(late.merged(), here.merged());
        // A region on another grid is refused with both grids named.
        let mut other = here.keyframe("drone_0").unwrap();
        other.grid.resolution_m = 0.2;
        let err = late.apply_remote(&other).unwrap_err().to_string();
        assert!(err.contains("same [map] section"), "{err}");
    }
}
