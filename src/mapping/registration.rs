//! Scan-to-map registration: how well a drone's recent range hits fit the obstacles a map
//! already holds, the evidence that the position estimate they were placed with has drifted.
//!
//! In: hit points (ENU m, where the beams ended, placed at the pose the vehicle reported), an
//! offset to try, and the map as a [`Reference`]: its grid, the occupied threshold and since
//! when each occupied cell has been so ([`OccupiedSince`]). Out: a score of the fit: the hits,
//! moved by the offset, that fall in obstacle cells occupied for a while (settled), less those
//! that fall where the map holds the space free. The estimator's map correction tries offsets
//! around its own and keeps the best fit.
//!
//! Only settled cells count: a drifting drone's newest hits land where its estimate is now, so
//! counting the cells they made would pin the estimate to its own drift; the obstacles mapped
//! before, by it or by the other drones, are what tell the drift. Several seconds of hits on
//! several faces are fitted at once: one hit on a round pole, a cell of which a passing beam
//! cleared, says little, while the hits of a few seconds on several obstacles fit the map at one
//! offset only (the fit's span says how far apart the obstacles it rests on are). Hits in
//! free space count against an offset: without them, a pole's face seen now from the west fits
//! as well as its east face mapped by another drone, half a metre away.

use nalgebra::Vector2;

use super::grid::{CellBox, OccupancyGrid, UNKNOWN};

/// When each cell of a grid became occupied (s, core time); `None` where it is not occupied.
#[derive(Debug, Clone, PartialEq)]
pub struct OccupiedSince {
    stamps_s: Vec<Option<f64>>,
}

impl OccupiedSince {
    /// The cells of `grid` occupied now (at or above `threshold`) stamped with `now_s`.
    pub fn new(grid: &OccupancyGrid, threshold: i8, now_s: f64) -> Self {
        let stamps_s = grid
            .data()
            .iter()
            .map(|&v| (v >= threshold).then_some(now_s))
            .collect();
        Self { stamps_s }
    }

    /// Brings the stamps of `region` up to date with `grid`: a cell newly occupied is stamped
    /// `now_s`, a cell no longer occupied loses its stamp.
    pub fn restamp(&mut self, grid: &OccupancyGrid, threshold: i8, region: CellBox, now_s: f64) {
        let spec = grid.spec();
        let Some(region) = region.intersect(spec.full_box()) else {
            return;
        };
        let w = spec.width_cells as usize;
        for y in region.min.y..=region.max.y {
            let row = y as usize * w;
            for x in region.min.x..=region.max.x {
                let i = row + x as usize;
                let occupied = grid.data().get(i).is_some_and(|&v| v >= threshold);
                if let Some(stamp) = self.stamps_s.get_mut(i) {
                    match (occupied, *stamp) {
                        (true, None) => *stamp = Some(now_s),
                        (false, Some(_)) => *stamp = None,
                        _ => {}
                    }
                }
            }
        }
    }

    /// When the cell of flat index `i` became occupied.
    pub fn get(&self, i: usize) -> Option<f64> {
        self.stamps_s.get(i).copied().flatten()
    }
}

/// The map hits are fitted against.
#[derive(Debug, Clone, Copy)]
pub struct Reference<'a> {
    pub grid: &'a OccupancyGrid,
    pub since: &'a OccupiedSince,
    pub occupied_threshold: i8,
}

/// How well hits fit the map at one offset.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FitScore {
    /// One for each hit on a settled obstacle, less one for each in free space.
    pub score: i64,
    /// The diagonal of the box around the hits on settled obstacles (m): how far apart the
    /// obstacles are that the fit rests on.
    pub span_m: f64,
}

impl Reference<'_> {
    /// How well `hits`, moved by `offset_m`, fit the map: one for each in a cell occupied since
    /// `settled_before_s` or earlier, less one for each in a cell the map holds free (a hit
    /// where a beam went through before). A hit in unseen space, or on an obstacle mapped only
    /// lately, counts nothing.
    pub fn fit_score(
        &self,
        hits: &[Vector2<f64>],
        offset_m: Vector2<f64>,
        settled_before_s: f64,
    ) -> FitScore {
        let spec = self.grid.spec();
        let mut score = 0;
        let mut corners: Option<(Vector2<f64>, Vector2<f64>)> = None;
        for &h in hits {
            let p = h + offset_m;
            let Some(i) = spec.cell_at(p).and_then(|c| spec.index_of(c)) else {
                continue;
            };
            let settled = |i: usize| self.since.get(i).is_some_and(|s| s <= settled_before_s);
            match self.grid.data().get(i) {
                Some(&v) if v >= self.occupied_threshold && settled(i) => {
                    score += 1;
                    corners = Some(corners.map_or((p, p), |(lo, hi)| (lo.inf(&p), hi.sup(&p))));
                }
                Some(&v) if v >= self.occupied_threshold => {}
                Some(&v) if v != UNKNOWN => score -= 1,
                _ => {}
            }
        }
        FitScore {
            score,
            span_m: corners.map_or(0.0, |(lo, hi)| (hi - lo).norm()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::{Cell, GridSpec};

    /// A 4 m x 4 m grid at 0.1 m, known free, with the cells of `occupied` (world points) at 100.
    fn grid(occupied: &[(f64, f64)]) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 40,
            height_cells: 40,
            origin_enu_m: Vector2::zeros(),
        };
        let mut g = OccupancyGrid::from_data(spec, vec![0; 1600]).unwrap();
        for &(x, y) in occupied {
            let c = spec.cell_at(Vector2::new(x, y)).unwrap();
            g.set(c, 100).unwrap();
        }
        g
    }

    fn reference<'a>(g: &'a OccupancyGrid, since: &'a OccupiedSince) -> Reference<'a> {
        Reference {
            grid: g,
            since,
            occupied_threshold: 31,
        }
    }

    #[test]
    fn hits_score_on_settled_obstacles_and_against_free_space() {
        // The face of an obstacle along x 2.0-2.1, y 1.5-2.5; hits 0.2 m short of it.
        let face: Vec<(f64, f64)> = (15..25)
            .map(|k| (2.05, f64::from(k) / 10.0 + 0.05))
            .collect();
        let g = grid(&face);
        let since = OccupiedSince::new(&g, 31, 0.0);
        let r = reference(&g, &since);
        let hits: Vec<_> = (15..25)
            .map(|k| Vector2::new(1.85, f64::from(k) / 10.0 + 0.05))
            .collect();
        assert_eq!(
            r.fit_score(&hits, Vector2::zeros(), 10.0).score,
            -10,
            "all in free space"
        );
        let on = r.fit_score(&hits, Vector2::new(0.2, 0.0), 10.0);
        assert_eq!(on.score, 10);
        assert!(
            (on.span_m - 0.9).abs() < 1e-9,
            "hits 1.55 to 2.45 m: {on:?}"
        );
        assert_eq!(
            r.fit_score(&hits, Vector2::new(0.2, 0.32), 10.0).score,
            7 - 3
        );
        assert_eq!(
            r.fit_score(&hits, Vector2::new(0.2, 0.0), -1.0).score,
            0,
            "not settled"
        );
        let mut unseen = g.clone();
        for (x, y) in (0..40).flat_map(|x| (0..40).map(move |y| (x, y))) {
            if unseen.get(Cell { x, y }) == Some(0) {
                unseen.set(Cell { x, y }, UNKNOWN).unwrap();
            }
        }
        let r = reference(&unseen, &since);
        assert_eq!(
            r.fit_score(&hits, Vector2::new(0.2, 0.32), 10.0).score,
            7,
            "unseen: nothing"
        );
    }

    #[test]
    fn a_cell_is_stamped_when_it_becomes_occupied_and_unstamped_when_freed() {
        let mut g = grid(&[]);
        let mut since = OccupiedSince::new(&g, 31, 0.0);
        let cell = Cell { x: 20, y: 20 };
        let i = 20 * 40 + 20;
        g.set(cell, 40).unwrap();
        since.restamp(&g, 31, CellBox::of_cell(cell), 7.0);
        assert_eq!(since.get(i), Some(7.0));
        g.set(cell, 80).unwrap();
        since.restamp(&g, 31, CellBox::of_cell(cell), 9.0);
        assert_eq!(since.get(i), Some(7.0), "occupied since 7 s");
        let hit = [Vector2::new(2.05, 2.05)];
        let r = reference(&g, &since);
        assert_eq!(r.fit_score(&hit, Vector2::zeros(), 6.9).score, 0, "too new");
        assert_eq!(r.fit_score(&hit, Vector2::zeros(), 7.0).score, 1);
        g.set(cell, 10).unwrap();
        since.restamp(&g, 31, CellBox::of_cell(cell), 10.0);
        assert_eq!(since.get(i), None, "freed: no stamp");
    }
}
