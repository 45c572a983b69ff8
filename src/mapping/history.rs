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
//!
//! Drawing an hour of scans again takes about 0.1 s, too long for one control tick: a redraw is
//! started ([`ScanHistory::start_redraw`]) and drawn a bounded number of scans per tick
//! ([`ScanHistory::step_redraw`]); scans kept meanwhile are drawn into it too, and the grid is
//! handed over once it has caught up with the present.

use std::collections::VecDeque;

use nalgebra::{Vector2, Vector3};

use super::grid::{CellBox, InsertParams, OccupancyGrid};
use super::scan::RangeScan;

/// One kept scan.
#[derive(Debug, Clone)]
struct Drawn {
    /// Counts the scans kept, from 0: the order they are drawn in.
    seq: u64,
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
    /// The `seq` the next kept scan gets.
    next_seq: u64,
    redraw: Option<Redraw>,
}

/// A redraw under way: the grid drawn so far and where it is in the kept scans.
#[derive(Debug, Clone)]
struct Redraw {
    grid: OccupancyGrid,
    track: Vec<(f64, Vector2<f64>)>,
    /// The `seq` of the next scan to draw.
    next_seq: u64,
    /// Scans from this `seq` on were kept after the track was made: they keep their own offset.
    first_newer_seq: u64,
}

impl Redraw {
    /// Draws `d`, moved to the track's offset of its time when the track covers it.
    fn draw(&mut self, d: &mut Drawn, params: &InsertParams) {
        if d.seq < self.first_newer_seq {
            if let Some(o) = offset_at(&self.track, d.at_s) {
                d.offset_m = o;
            }
        }
        // Scans were validated when the map took them first; a refused one changes nothing.
        let _ = self.grid.insert_scan(&shifted(&d.scan, d.offset_m), params);
        self.next_seq = d.seq + 1;
    }
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
            next_seq: 0,
            redraw: None,
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
                seq: self.next_seq,
                at_s,
                scan: scan.clone(),
                offset_m,
            });
            self.next_seq += 1;
        }
        while self.scans.len() > self.max_scans {
            if let Some(mut old) = self.scans.pop_front() {
                // A redraw under way that has not reached it draws it first, so it moves with the
                // track there as well as in the base.
                if let Some(r) = self.redraw.as_mut().filter(|r| old.seq >= r.next_seq) {
                    r.draw(&mut old, params);
                }
                // Scans were validated when the map took them first; a refused one changes nothing.
                let _ = self
                    .base
                    .insert_scan(&shifted(&old.scan, old.offset_m), params);
            }
        }
    }

    /// Whether a redraw is under way.
    pub fn redrawing(&self) -> bool {
        self.redraw.is_some()
    }

    /// Starts drawing the grid again with every kept scan at `track`'s offset of its time (a scan
    /// before the track keeps its own); a redraw under way is dropped.
    pub fn start_redraw(&mut self, track: Vec<(f64, Vector2<f64>)>) {
        self.redraw = Some(Redraw {
            grid: self.base.clone(),
            track,
            next_seq: self.scans.front().map_or(self.next_seq, |d| d.seq),
            first_newer_seq: self.next_seq,
        });
    }

    /// Draws up to `max_scans` more of the redraw under way. Returns the grid once every kept
    /// scan is drawn (the scans are drawn so from then on); `None` while it is not done or none
    /// is under way.
    pub fn step_redraw(
        &mut self,
        max_scans: usize,
        params: &InsertParams,
    ) -> Option<OccupancyGrid> {
        let r = self.redraw.as_mut()?;
        let front_seq = self.scans.front().map_or(self.next_seq, |d| d.seq);
        let start = usize::try_from(r.next_seq.saturating_sub(front_seq)).unwrap_or(usize::MAX);
        for d in self.scans.iter_mut().skip(start).take(max_scans) {
            r.draw(d, params);
        }
        if r.next_seq < self.next_seq {
            return None;
        }
        self.redraw.take().map(|r| r.grid)
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
        self.start_redraw(track.to_vec());
        // Unbounded, the step draws every kept scan and hands the grid over.
        self.step_redraw(usize::MAX, params)
            .unwrap_or_else(|| self.base.clone())
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

    #[test]
    fn a_redraw_in_slices_catches_up_with_scans_kept_meanwhile_and_ends_as_one_in_a_step() {
        let params = InsertParams::default();
        let track = [(0.0, Vector2::zeros()), (10.0, Vector2::new(0.5, 0.0))];
        let walls = |k: u32| east(-0.5, f64::from(k) * 0.2 - 4.0);
        let mut sliced = ScanHistory::new(grid(), 100);
        let mut whole = ScanHistory::new(grid(), 100);
        for k in 0..30 {
            for h in [&mut sliced, &mut whole] {
                h.push(f64::from(k) / 3.0, &[walls(k)], Vector2::zeros(), &params);
            }
        }
        sliced.start_redraw(track.to_vec());
        assert!(sliced.redrawing());
        let mut steps = 0;
        let grid = loop {
            steps += 1;
            // Two more scans kept each tick, drawn at the offset of now (0.5 m east).
            let k = 29 + steps;
            sliced.push(
                f64::from(k) / 3.0,
                &[walls(k)],
                Vector2::new(0.5, 0.0),
                &params,
            );
            if let Some(g) = sliced.step_redraw(7, &params) {
                break g;
            }
            assert!(steps < 20, "never caught up");
        };
        assert!(!sliced.redrawing());
        // 30 scans, then one more per step, 7 drawn a step: 35 drawn by the fifth.
        assert_eq!(steps, 5);
        // The same scans at once: the first 30 moved with the track, the rest as kept.
        for k in 30..(30 + steps) {
            whole.push(
                f64::from(k) / 3.0,
                &[walls(k)],
                Vector2::new(0.5, 0.0),
                &params,
            );
        }
        let at_once = whole.redraw(&track, &params);
        assert_eq!(grid.data(), at_once.data());
        assert_eq!(
            sliced.step_redraw(7, &params).map(|_| ()),
            None,
            "none under way"
        );
    }

    #[test]
    fn a_scan_folded_into_the_base_before_a_redraw_reached_it_is_moved_too() {
        let params = InsertParams::default();
        let mut history = ScanHistory::new(grid(), 3);
        for k in 0..3 {
            history.push(
                f64::from(k),
                &[east(0.0, f64::from(k))],
                Vector2::zeros(),
                &params,
            );
        }
        // Every scan 1 m north; nothing drawn yet when a fourth scan pushes the first out.
        history.start_redraw(vec![(0.0, Vector2::new(0.0, 1.0))]);
        history.push(3.0, &[east(0.0, 3.0)], Vector2::new(0.0, 1.0), &params);
        let g = history.step_redraw(10, &params).unwrap();
        assert!(occupied(&g, 2.05, 1.0), "the folded one, moved");
        assert!(!occupied(&g, 2.05, 0.0), "not where it was");
        assert!(occupied(&g, 2.05, 4.0), "the newest, at its own offset");
        // The base has it moved as well: a later redraw keeps it there.
        let again = history.redraw(&[(0.0, Vector2::new(0.0, 1.0))], &params);
        assert!(occupied(&again, 2.05, 1.0) && !occupied(&again, 2.05, 0.0));
    }
}
