//! A drone's scans as it reported them, kept so its map can be drawn again when the offset from
//! its drifting estimate to the map's frame turns out, later, to have been another.
//!
//! In: each tick's scans in the vehicle's reported frame with the offset they were drawn at, and
//! then and again a track of offsets at past times (`estimator::map_correction`'s smoothed one).
//! Out: how far the track moves any kept scan from where it was drawn, and the grid drawn again
//! with every kept scan at the track's offset of its time.
//!
//! A drone that maps new ground while its estimate drifts draws that ground where the estimate
//! is; when it comes back to ground it mapped long ago and the map correction learns how far it
//! had drifted, the ground drawn since is off by up to that much. Obstacles there sit where the
//! drone was not, free cells cover poles. Drawn again, the map is one piece: a pole seen twice
//! lands in one place.
//!
//! Bounded: at most `max_scans` are kept; the oldest are folded into a base grid at the offset
//! they were last drawn at, and stay as they are from then on.

use std::collections::VecDeque;

use nalgebra::{Vector2, Vector3};

use super::grid::{CellBox, InsertParams, OccupancyGrid};
use super::scan::RangeScan;

/// One kept scan.
#[derive(Debug, Clone)]
struct Drawn {
    at_s: f64,
    /// In the vehicle's reported frame.
    scan: RangeScan,
    /// The offset it is drawn at in the map (ENU m, horizontal).
    offset_m: Vector2<f64>,
}

/// The scans a drone's map is drawn from, and the grid of those no longer kept.
#[derive(Debug, Clone)]
pub struct ScanHistory {
    base: OccupancyGrid,
    scans: VecDeque<Drawn>,
    max_scans: usize,
}

/// The offset of `track` (time s, offset; times rising) at `t_s`: between two steps, on the line
/// between them; after the last, the last; `None` before the first (the track says nothing).
pub fn offset_at(track: &[(f64, Vector2<f64>)], t_s: f64) -> Option<Vector2<f64>> {
    let first = track.first()?;
    if t_s < first.0 {
        return None;
    }
    let after = track.partition_point(|(t, _)| *t <= t_s);
    let Some(&(t1, o1)) = track.get(after) else {
        return track.last().map(|(_, o)| *o);
    };
    let (t0, o0) = track[after - 1];
    let span = t1 - t0;
    if span <= 0.0 {
        return Some(o1);
    }
    Some(o0 + (o1 - o0) * ((t_s - t0) / span))
}

/// `scan` moved by a horizontal offset.
fn shifted(scan: &RangeScan, offset_m: Vector2<f64>) -> RangeScan {
    RangeScan {
        origin_enu_m: scan.origin_enu_m + Vector3::new(offset_m.x, offset_m.y, 0.0),
        ..scan.clone()
    }
}

impl ScanHistory {
    /// No scans yet; `initial` is the map before any (the known map).
    pub fn new(initial: OccupancyGrid, max_scans: usize) -> Self {
        Self {
            base: initial,
            scans: VecDeque::new(),
            max_scans: max_scans.max(1),
        }
    }

    /// How many scans are kept.
    pub fn len(&self) -> usize {
        self.scans.len()
    }

    pub fn is_empty(&self) -> bool {
        self.scans.is_empty()
    }

    /// Keeps the scans of `at_s` (reported frame), drawn at `offset_m`. The oldest past
    /// `max_scans` go into the base grid.
    pub fn push(
        &mut self,
        at_s: f64,
        scans: &[RangeScan],
        offset_m: Vector2<f64>,
        params: &InsertParams,
    ) {
        for scan in scans {
            self.scans.push_back(Drawn {
                at_s,
                scan: scan.clone(),
                offset_m,
            });
        }
        while self.scans.len() > self.max_scans {
            if let Some(old) = self.scans.pop_front() {
                // Scans were validated when the map took them first; a refused one changes nothing.
                let _ = self
                    .base
                    .insert_scan(&shifted(&old.scan, old.offset_m), params);
            }
        }
    }

    /// The farthest `track` moves a kept scan from the offset it is drawn at (m).
    pub fn deviation_m(&self, track: &[(f64, Vector2<f64>)]) -> f64 {
        self.scans
            .iter()
            .filter_map(|d| offset_at(track, d.at_s).map(|o| (o - d.offset_m).norm()))
            .fold(0.0, f64::max)
    }

    /// The grid drawn again: the base, then every kept scan in order at `track`'s offset of its
    /// time (a scan before the track keeps its own). The scans are drawn so from now on.
    pub fn redraw(
        &mut self,
        track: &[(f64, Vector2<f64>)],
        params: &InsertParams,
    ) -> OccupancyGrid {
        let mut grid = self.base.clone();
        for d in &mut self.scans {
            if let Some(o) = offset_at(track, d.at_s) {
                d.offset_m = o;
            }
            let _ = grid.insert_scan(&shifted(&d.scan, d.offset_m), params);
        }
        grid
    }
}

/// The box of cells where `a` and `b` (on one spec) differ; `None` where none does.
pub fn changed_box(a: &OccupancyGrid, b: &OccupancyGrid) -> Option<CellBox> {
    if a.spec() != b.spec() {
        return Some(b.spec().full_box());
    }
    let spec = b.spec();
    let mut changed: Option<CellBox> = None;
    for (i, (x, y)) in a.data().iter().zip(b.data()).enumerate() {
        if x != y {
            if let Some(c) = spec.cell_of_index(i) {
                match changed.as_mut() {
                    Some(bx) => bx.include(c),
                    None => changed = Some(CellBox::of_cell(c)),
                }
            }
        }
    }
    changed
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::GridSpec;
    use crate::mapping::scan::Beam;

    fn grid() -> OccupancyGrid {
        OccupancyGrid::new(GridSpec {
            resolution_m: 0.1,
            width_cells: 100,
            height_cells: 100,
            origin_enu_m: Vector2::new(-5.0, -5.0),
        })
        .unwrap()
    }

    /// One beam east from `(x, y)` ending on a hit 2 m away.
    fn east(x: f64, y: f64) -> RangeScan {
        RangeScan {
            origin_enu_m: Vector3::new(x, y, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(2.0),
            }],
        }
    }

    fn occupied(g: &OccupancyGrid, x: f64, y: f64) -> bool {
        g.get_at(Vector2::new(x, y)).is_some_and(|v| v >= 31)
    }

    #[test]
    fn offsets_between_steps_lie_on_the_line_and_none_before_the_track() {
        let track = [
            (1.0, Vector2::new(0.0, 0.0)),
            (3.0, Vector2::new(1.0, -1.0)),
        ];
        assert_eq!(offset_at(&track, 0.5), None);
        assert_eq!(offset_at(&track, 2.0), Some(Vector2::new(0.5, -0.5)));
        assert_eq!(offset_at(&track, 9.0), Some(Vector2::new(1.0, -1.0)));
        assert_eq!(offset_at(&[], 2.0), None);
    }

    #[test]
    fn a_wall_seen_twice_at_two_offsets_lands_in_one_place_once_redrawn() {
        let params = InsertParams::default();
        let mut history = ScanHistory::new(grid(), 100);
        let mut live = grid();
        // The same wall 2 m east, seen at t = 1 s with no offset, and at t = 10 s by an estimate
        // that had drifted 0.5 m west unseen (drawn with the offset of then, 0).
        for (t, scan) in [(1.0, east(0.0, 0.0)), (10.0, east(-0.5, 0.0))] {
            let _ = live.insert_scan(&scan, &params);
            history.push(t, &[scan], Vector2::zeros(), &params);
        }
        assert!(
            occupied(&live, 1.5, 0.0) && occupied(&live, 2.05, 0.0),
            "two walls"
        );
        // A fit at 10 s finds the offset: +0.5 m east then, none at 1 s.
        let track = [(1.0, Vector2::zeros()), (10.0, Vector2::new(0.5, 0.0))];
        assert!((history.deviation_m(&track) - 0.5).abs() < 1e-9);
        let redrawn = history.redraw(&track, &params);
        assert!(occupied(&redrawn, 2.05, 0.0), "the wall where it is");
        assert!(
            !occupied(&redrawn, 1.55, 0.0),
            "no wall where the drifted view had it"
        );
        assert!(history.deviation_m(&track) < 1e-9, "drawn at the track now");
        let b = changed_box(&live, &redrawn).unwrap();
        assert!(b.min.x <= 65 && b.max.x >= 65, "{b:?}");
        assert_eq!(changed_box(&redrawn, &redrawn), None);
    }

    #[test]
    fn the_oldest_scans_past_the_bound_stay_as_drawn() {
        let params = InsertParams::default();
        let mut history = ScanHistory::new(grid(), 2);
        for t in 0..5 {
            history.push(
                f64::from(t),
                &[east(0.0, f64::from(t) * 0.5)],
                Vector2::zeros(),
                &params,
            );
        }
        assert_eq!(history.len(), 2);
        // Every scan moved 1 m north: the three folded into the base do not move.
        let track = [(0.0, Vector2::new(0.0, 1.0))];
        let g = history.redraw(&track, &params);
        assert!(
            occupied(&g, 2.05, 0.0) && occupied(&g, 2.05, 1.0),
            "folded, as drawn"
        );
        assert!(
            occupied(&g, 2.05, 2.5) && occupied(&g, 2.05, 3.0),
            "kept, moved"
        );
    }
}
