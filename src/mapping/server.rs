//! The map server of one drone (the `scan2occ_grid` plugin): its occupancy grid, fed with the
//! drone's range scans every tick.
//!
//! In: a [`MapConfig`], then per tick the scans the platform reported and the time.
//! Out: the grid, a revision that changes with every changed cell, the box of cells changed by
//! the last insertion, and a [`MapSnapshot`] (a shared copy, made at most once per revision and
//! only when a planner asks: scans arrive at 10-20 Hz, plans are rare) that planning derives its
//! own planning map from, off the control tick.

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use super::config::MapConfig;
use super::graph::TopoGraph;
use super::grid::{CellBox, InsertParams, OccupancyGrid};
use super::scan::RangeScan;
use super::MapError;

/// A drone's grid as it was at one revision, shared with the planner's worker thread.
#[derive(Debug, Clone)]
pub struct MapSnapshot {
    pub grid: OccupancyGrid,
    pub revision: u64,
    pub occupied_threshold: i8,
    /// When a cell last changed (s, core time).
    pub updated_at_s: f64,
    pub graph: Option<Arc<TopoGraph>>,
}

/// One drone's map.
#[derive(Debug)]
pub struct MapServer {
    grid: OccupancyGrid,
    params: InsertParams,
    occupied_threshold: i8,
    graph: Option<Arc<super::graph::TopoGraph>>,
    revision: u64,
    updated_at: Duration,
    rejected_scans: u64,
    last_rejection: Option<MapError>,
    /// Cells changed by the last insertion.
    last_changed: Option<CellBox>,
    /// The snapshot of `revision`, made on demand.
    snapshot: Mutex<Option<Arc<MapSnapshot>>>,
}

impl MapServer {
    pub fn new(config: &MapConfig) -> Self {
        MapServer {
            grid: (*config.initial).clone(),
            params: config.params,
            occupied_threshold: config.occupied_threshold,
            graph: config.graph.clone(),
            revision: 0,
            updated_at: Duration::ZERO,
            rejected_scans: 0,
            last_rejection: None,
            last_changed: None,
            snapshot: Mutex::new(None),
        }
    }

    /// Ray-casts every scan into the grid. Returns the box of changed cells (`None`: nothing
    /// changed). Invalid scans are counted and the latest reason kept, see [`Self::rejected`].
    pub fn insert(&mut self, now: Duration, scans: &[RangeScan]) -> Option<CellBox> {
        let mut changed: Option<CellBox> = None;
        for scan in scans {
            match self.grid.insert_scan(scan, &self.params) {
                Ok(Some(b)) => changed = Some(changed.map_or(b, |c| c.union(b))),
                Ok(None) => {}
                Err(e) => {
                    self.rejected_scans += 1;
                    self.last_rejection = Some(e);
                }
            }
        }
        if changed.is_some() {
            self.revision += 1;
            self.updated_at = now;
        }
        self.last_changed = changed;
        changed
    }

    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
    }

    /// The insertion parameters the grid is drawn with.
    pub fn params(&self) -> &InsertParams {
        &self.params
    }

    /// Takes `grid`, the same scans drawn again ([`super::history`]), in place of the grid:
    /// the cells that differ count as the last insertion's change. Returns them (`None`: none).
    pub fn redrawn(&mut self, now: Duration, grid: OccupancyGrid) -> Option<CellBox> {
        let changed = super::history::changed_box(&self.grid, &grid);
        self.grid = grid;
        if changed.is_some() {
            self.revision += 1;
            self.updated_at = now;
        }
        self.last_changed = match (self.last_changed, changed) {
            (Some(a), Some(b)) => Some(a.union(b)),
            (a, b) => a.or(b),
        };
        changed
    }

    /// The cells the last [`Self::insert`] changed (`None`: nothing changed).
    pub fn last_changed(&self) -> Option<CellBox> {
        self.last_changed
    }

    /// Changes whenever a cell changed.
    pub fn revision(&self) -> u64 {
        self.revision
    }

    /// When a cell last changed (core time).
    pub fn updated_at(&self) -> Duration {
        self.updated_at
    }

    pub fn occupied_threshold(&self) -> i8 {
        self.occupied_threshold
    }

    /// Scans refused as invalid so far, and the latest reason.
    pub fn rejected(&self) -> (u64, Option<&MapError>) {
        (self.rejected_scans, self.last_rejection.as_ref())
    }

    /// Whether the cell holding `p` is an obstacle (`None` outside the grid).
    pub fn is_occupied_at(&self, p: nalgebra::Vector2<f64>) -> Option<bool> {
        self.grid.get_at(p).map(|v| v >= self.occupied_threshold)
    }

    /// A shared copy of the grid at this revision, made only when the grid changed since the
    /// last call.
    pub fn snapshot(&self) -> Arc<MapSnapshot> {
        let mut cache = self.snapshot.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some(snap) = cache.as_ref() {
            if snap.revision == self.revision {
                return snap.clone();
            }
        }
        let snap = Arc::new(MapSnapshot {
            grid: self.grid.clone(),
            revision: self.revision,
            occupied_threshold: self.occupied_threshold,
            updated_at_s: self.updated_at.as_secs_f64(),
            graph: self.graph.clone(),
        });
        *cache = Some(snap.clone());
        snap
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::scan::Beam;
    use nalgebra::{Vector2, Vector3};

    fn scan_east(range_m: f64) -> RangeScan {
        RangeScan {
            origin_enu_m: Vector3::new(0.05, 0.05, 1.0),
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
    fn scans_mark_hits_and_bump_the_revision_and_the_snapshot() {
        let mut m = MapServer::new(&MapConfig::open_field().unwrap());
        let before = m.snapshot();
        assert!(Arc::ptr_eq(&before, &m.snapshot()), "cached");
        let changed = m.insert(Duration::from_secs(1), &[scan_east(2.0)]).unwrap();
        assert_eq!(m.revision(), 1);
        assert!(changed.width_cells() >= 20);
        assert_eq!(m.is_occupied_at(Vector2::new(2.05, 0.05)), Some(true));
        assert_eq!(m.is_occupied_at(Vector2::new(1.05, 0.05)), Some(false));
        let after = m.snapshot();
        assert!(!Arc::ptr_eq(&before, &after), "made again after a change");
        assert_eq!((after.revision, after.updated_at_s), (1, 1.0));
    }

    #[test]
    fn invalid_scans_are_counted_not_inserted() {
        let mut m = MapServer::new(&MapConfig::open_field().unwrap());
        let mut bad = scan_east(1.0);
        bad.range_max_m = -1.0;
        assert_eq!(m.insert(Duration::ZERO, &[bad]), None);
        assert_eq!(m.rejected().0, 1);
        assert_eq!(m.revision(), 0);
    }
}
