//! Mapping: range data in, maps out.
//!
//! * [`scan`]: every range sensor (multi-ranger, OBSTACLE_DISTANCE sectors, planar lidar, depth
//!   image rows, point clouds, a binary wire message) is adapted to one [`RangeScan`].
//! * [`grid`]: a 2D [`OccupancyGrid`] updated by ray casting a [`RangeScan`] (the
//!   `scan2occ_grid` plugin); returns the changed cell box so callers can publish only what moved.
//! * [`raycast`]: the cell walk along a segment, shared by scan insertion and line-of-sight checks.
//! * [`export`]: the grid as PNG and in the ROS `map_server` format (PGM + YAML), both ways.
//! * [`layers`]: a [`LayeredMap`], one layer per drone fused into one global grid.
//! * [`config`], [`server`], [`merged`]: the `[map]` config section, each drone's map server
//!   (scans in every tick, grid and planning map out) and the fleet's merged map with the
//!   changed regions for clients.
//! * [`registration`]: how well range hits, moved by an offset, fit the obstacles a map has held
//!   for a while: the evidence the estimator's map correction learns a drifting estimate from.
//! * [`history`]: a drone's scans as reported, kept to draw its map again when the offset of its
//!   drifting estimate is found, later, to have been another.
//! * [`graph`]: a [`TopoGraph`] (nodes + weighted edges), built from an indoor-farm description
//!   or loaded from JSON.
//!
//! Everything here is plain synchronous data and math: no clock, no channels, and no I/O except
//! [`config`] reading the known map and graph files at startup.

pub mod config;
pub mod export;
pub mod graph;
pub mod grid;
pub mod history;
pub mod layers;
pub mod merged;
pub mod raycast;
pub mod registration;
pub mod scan;
pub mod server;

pub use graph::{FarmSpec, GraphEdge, GraphNode, TopoGraph};
pub use grid::{Cell, CellBox, GridPatch, GridSpec, InsertParams, OccupancyGrid, UNKNOWN};
pub use layers::{FuseRule, LayeredMap};
pub use scan::{Beam, RangeScan};

impl From<crate::types::scan::ScanError> for MapError {
    fn from(e: crate::types::scan::ScanError) -> Self {
        MapError::InvalidScan(e.0)
    }
}

/// Errors from building, updating, importing or exporting maps.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MapError {
    #[error("invalid grid spec: {0}")]
    InvalidSpec(String),
    #[error("grid data has {got} cells but the spec needs {expected}")]
    DataLength { expected: usize, got: usize },
    #[error("invalid occupancy value {0} (must be -1 or 0..=100)")]
    InvalidValue(i8),
    #[error("cell ({x}, {y}) is outside the map")]
    OutsideMap { x: u32, y: u32 },
    #[error("invalid scan: {0}")]
    InvalidScan(String),
    #[error("image encoding failed: {0}")]
    Image(String),
    #[error("invalid ROS map: {0}")]
    RosMap(String),
    #[error("invalid graph: {0}")]
    Graph(String),
    #[error("invalid farm description: {0}")]
    Farm(String),
}
