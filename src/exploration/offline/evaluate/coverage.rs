//! What each drone has seen: the four body-fixed beams of every airborne sample cast at the
//! true obstacles and marked on the evaluation grid.
//!
//! In: the grid, the indexed obstacles, the drones' tracks, the sensor parameters. Out:
//! [`Known`]: each drone's known cells, how many drones know each cell, and how the union grew
//! over log time.

use super::motion::Tracks;
use super::raster::{CellSet, Raster};
use super::EvalParams;
use crate::sim::spatial::ShapeIndex;
use crate::types::{Vec2, Vec3};
use std::f64::consts::FRAC_PI_2;

/// The cells known by each drone, and the union's growth.
#[derive(Debug, Clone)]
pub struct Known {
    per_drone: Vec<CellSet>,
    cells: usize,
    /// (log time, cells known by any drone) after every sample that added a cell.
    growth: Vec<(f64, usize)>,
    /// Cells in the order they joined the union: `order[..n]` were known when `growth` says n.
    order: Vec<u32>,
    /// Log times of the first and last samples.
    start_s: f64,
    end_s: f64,
}

/// Most points an area curve gets, whatever the log's length.
const MAX_CURVE_POINTS: usize = 100_000;

/// Casts every airborne sample's beams, in time order.
pub fn cast(raster: &Raster, index: &ShapeIndex, tracks: &Tracks, params: &EvalParams) -> Known {
    let cells = raster.cells();
    let mut per_drone: Vec<CellSet> = tracks
        .drones()
        .iter()
        .map(|_| CellSet::new(cells))
        .collect();
    let mut union = CellSet::new(cells);
    let mut union_count = 0usize;
    let mut growth = Vec::new();
    let mut order = Vec::new();
    let (mut start_s, mut end_s) = (f64::INFINITY, f64::NEG_INFINITY);
    for (drone, s) in tracks.in_time_order() {
        start_s = start_s.min(s.t_s);
        end_s = end_s.max(s.t_s);
        if s.z_m <= params.airborne_z_m {
            continue;
        }
        let Some(known) = per_drone.get_mut(drone) else {
            continue;
        };
        let origin = Vec3::new(s.x_m, s.y_m, s.z_m);
        let near = index.near(s.x_m, s.y_m, params.beam_range_m);
        let before = union_count;
        for k in 0..4 {
            let yaw = s.yaw_rad + f64::from(k) * FRAC_PI_2;
            let dir = Vec2::new(yaw.cos(), yaw.sin());
            let hit_m = index.ray_m(&near, &origin, &dir);
            let reach_m = match hit_m {
                Some(d) if d < params.min_range_m => continue,
                Some(d) => d.min(params.beam_range_m),
                None => params.beam_range_m,
            };
            let end = (s.x_m + reach_m * dir.x, s.y_m + reach_m * dir.y);
            raster.traverse((s.x_m, s.y_m), end, |i| {
                known.insert(i);
                if union.insert(i) {
                    union_count += 1;
                    // The raster has at most 100 million cells (`Raster::over`).
                    order.push(u32::try_from(i).unwrap_or(u32::MAX));
                }
                true
            });
        }
        if union_count > before {
            growth.push((s.t_s, union_count));
        }
    }
    Known {
        per_drone,
        cells,
        growth,
        order,
        start_s,
        end_s,
    }
}

impl Known {
    pub fn per_drone(&self) -> &[CellSet] {
        &self.per_drone
    }

    /// (log time, cells known) after every sample that added a cell.
    pub fn growth(&self) -> &[(f64, usize)] {
        &self.growth
    }

    /// Cells in the order they became known to any drone.
    pub fn order(&self) -> &[u32] {
        &self.order
    }

    pub fn union(&self) -> CellSet {
        let mut u = CellSet::new(self.cells);
        for s in &self.per_drone {
            u.union_with(s);
        }
        u
    }

    /// For every cell, how many drones know it.
    pub fn counts_per_cell(&self) -> Vec<u8> {
        let mut counts = vec![0u8; self.cells];
        for set in &self.per_drone {
            for (i, c) in counts.iter_mut().enumerate() {
                if set.contains(i) {
                    *c = c.saturating_add(1);
                }
            }
        }
        counts
    }

    /// Cells known at every multiple of `step_s` of log time from the first sample to the
    /// last, and at the last sample.
    pub fn curve(&self, step_s: f64) -> Vec<(f64, usize)> {
        if !(self.start_s.is_finite() && self.end_s.is_finite()) {
            return Vec::new();
        }
        let first = (self.start_s / step_s).ceil();
        let mut out: Vec<(f64, usize)> = (0..MAX_CURVE_POINTS)
            .map(|k| (first + k as f64) * step_s)
            .take_while(|t| *t < self.end_s)
            .map(|t| (t, self.known_at(t)))
            .collect();
        out.push((self.end_s, self.known_at(self.end_s)));
        out
    }

    /// Cells known by any drone after every sample at or before `t_s`.
    fn known_at(&self, t_s: f64) -> usize {
        let n = self.growth.partition_point(|(t, _)| *t <= t_s);
        n.checked_sub(1)
            .and_then(|i| self.growth.get(i))
            .map_or(0, |(_, c)| *c)
    }

    /// First log time at which at least `cells` cells were known.
    pub fn first_time_reaching(&self, cells: usize) -> Option<f64> {
        self.growth
            .iter()
            .find(|(_, c)| *c >= cells)
            .map(|(t, _)| *t)
    }
}
