//! What the host answers about maps: a copy of a drone's grid or of the merged grid, with the
//! facts a client needs to read it.
//!
//! In: a drone's [`MapServer`] or the fleet's [`FleetMap`]. Out: a [`MapView`], serialised by
//! the API off the control loop, and its cells counted by kind; the API names the grid's
//! [`GridSpec`] through here rather than through `mapping`.

use crate::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD;
use crate::mapping::merged::FleetMap;
use crate::mapping::server::MapServer;
pub use crate::mapping::GridSpec;
use crate::mapping::OccupancyGrid;

/// A copy of one map.
#[derive(Debug, Clone, PartialEq)]
pub struct MapView {
    /// The drone whose own map this is; `None` = the merged map.
    pub drone: Option<String>,
    pub grid: OccupancyGrid,
    /// Layers fused into the merged map (drones, `known`); empty for a drone's map.
    pub layers: Vec<String>,
    /// A drone map's revision (changes with every changed cell).
    pub revision: Option<u64>,
    /// When a drone map last changed (s since the host started).
    pub updated_at_s: Option<f64>,
    /// Cells at or above this value are obstacles for planning.
    pub occupied_threshold: Option<i8>,
}

impl MapView {
    pub fn of_drone(drone: &str, map: &MapServer) -> Self {
        MapView {
            drone: Some(drone.to_string()),
            grid: map.grid().clone(),
            layers: Vec::new(),
            revision: Some(map.revision()),
            updated_at_s: Some(map.updated_at().as_secs_f64()),
            occupied_threshold: Some(map.occupied_threshold()),
        }
    }

    pub fn merged(map: &FleetMap) -> Self {
        MapView {
            drone: None,
            grid: map.merged().clone(),
            layers: map.layer_names(),
            revision: None,
            updated_at_s: None,
            occupied_threshold: None,
        }
    }

    /// How many cells are unknown, free and occupied (at or above the view's threshold, else
    /// the planners' default).
    pub fn cell_counts(&self) -> CellCounts {
        let threshold = self
            .occupied_threshold
            .unwrap_or(DEFAULT_OCCUPIED_THRESHOLD);
        let mut counts = CellCounts::default();
        for &v in self.grid.data() {
            match v {
                v if v < 0 => counts.unknown += 1,
                v if v >= threshold => counts.occupied += 1,
                _ => counts.free += 1,
            }
        }
        counts
    }
}

/// The cells of a map by kind.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct CellCounts {
    pub unknown: usize,
    pub free: usize,
    pub occupied: usize,
}
