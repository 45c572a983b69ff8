//! The map server of one drone (the `scan2occ_grid` plugin): its occupancy grid, fed with the
//! drone's range scans every tick.
//!
//! In: a [`MapConfig`], then per tick the scans the platform reported and the time.
//! Out: the grid, a revision that changes with every changed cell, the box of cells changed by
//! the last insertion, and a [`PlanningMap`] derived at most once per revision, only when a
//! planner asks for it (scans arrive at 10-20 Hz, plans are rare).

use std::sync::{Arc, Mutex, PoisonError};
use std::time::Duration;

use super::config::MapConfig;
use super::grid::{CellBox, InsertParams, OccupancyGrid};
use super::scan::RangeScan;
use super::MapError;
use crate::planning::PlanningMap;

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
    /// The planning map of `revision`, built on demand.
    planning: Mutex<Option<(u64, Arc<PlanningMap>)>>,
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
            planning: Mutex::new(None),
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
        changed
    }

    pub fn grid(&self) -> &OccupancyGrid {
        &self.grid
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

    /// The grid prepared for planning (distance field, Voronoi diagram, graph), rebuilt only
    /// when the grid changed since the last call.
    pub fn planning_map(&self) -> Arc<PlanningMap> {
        let mut cache = self.planning.lock().unwrap_or_else(PoisonError::into_inner);
        if let Some((revision, map)) = cache.as_ref() {
            if *revision == self.revision {
                return map.clone();
            }
        }
        let mut map = PlanningMap::new(self.grid.clone(), self.occupied_threshold)
            .with_stamp(self.updated_at.as_secs_f64());
        if let Some(g) = &self.graph {
            map = map.with_graph((**g).clone());
        }
        let map = Arc::new(map);
        *cache = Some((self.revision, map.clone()));
        map
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
    fn scans_mark_hits_and_bump_the_revision_and_the_planning_map() {
        let mut m = MapServer::new(&MapConfig::open_field().unwrap());
        let before = m.planning_map();
        assert!(Arc::ptr_eq(&before, &m.planning_map()), "cached");
        let changed = m.insert(Duration::from_secs(1), &[scan_east(2.0)]).unwrap();
        assert_eq!(m.revision(), 1);
        assert!(changed.width_cells() >= 20);
        assert_eq!(m.is_occupied_at(Vector2::new(2.05, 0.05)), Some(true));
        assert_eq!(m.is_occupied_at(Vector2::new(1.05, 0.05)), Some(false));
        let after = m.planning_map();
        assert!(!Arc::ptr_eq(&before, &after), "rebuilt after a change");
        assert_eq!(after.stamp_s(), Some(1.0));
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
