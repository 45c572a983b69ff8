//! What the host answers about maps: a copy of a drone's grid or of the merged grid, with the
//! facts a client needs to read it.
//!
//! In: a drone's [`MapServer`] or the fleet's [`FleetMap`]. Out: a [`MapView`], serialised by
//! the API off the control loop.

use crate::mapping::merged::FleetMap;
use crate::mapping::server::MapServer;
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
}
