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

/// A hit on an obstacle mapped this long ago or longer counts fully (s); younger ones count in
/// proportion: where a drone's own recent map and an older one disagree (its estimate drifted in
/// between), the older one wins, and a drone drawing new ground alone does not lock on the
/// map it has just drawn.
pub const FULL_WEIGHT_AGE_S: f64 = 30.0;
/// What a hit in space the map holds free counts (against).
const FREE_HIT: f64 = -0.5;

/// How well hits fit the map at one offset.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FitScore {
    /// For each hit on a settled obstacle, its weight by age (at most one), less a half for
    /// each in free space.
    pub score: f64,
    /// The diagonal of the box around the hits on settled obstacles (m): how far apart the
    /// obstacles are that the fit rests on.
    pub span_m: f64,
    /// How long ago the settled obstacles hit became so (s, the mean of their weighted ages).
    pub age_s: f64,
    /// How many hits fall on settled obstacles, whatever their age.
    pub on_obstacles: usize,
}

impl Reference<'_> {
    /// How well `hits`, moved by `offset_m`, fit the map at `now_s`: for each in a cell
    /// occupied for `settle_s` or longer, its age over [`FULL_WEIGHT_AGE_S`] (at most one), less
    /// a half for each in a cell the map holds free (a hit where a beam went through before). A
    /// hit in unseen space, or on an obstacle mapped only lately, counts nothing.
    pub fn fit_score(
        &self,
        hits: &[Vector2<f64>],
        offset_m: Vector2<f64>,
        now_s: f64,
        settle_s: f64,
    ) -> FitScore {
        let spec = self.grid.spec();
        let mut score = 0.0;
        let (mut weights, mut weighted_age_s, mut on_obstacles) = (0.0, 0.0, 0);
        let mut corners: Option<(Vector2<f64>, Vector2<f64>)> = None;
        for &h in hits {
            let p = h + offset_m;
            let Some(i) = spec.cell_at(p).and_then(|c| spec.index_of(c)) else {
                continue;
            };
            let age_s = self.since.get(i).map_or(0.0, |since| now_s - since);
            match self.grid.data().get(i) {
                Some(&v) if v >= self.occupied_threshold && age_s >= settle_s => {
                    let weight = (age_s / FULL_WEIGHT_AGE_S).min(1.0);
                    score += weight;
                    weights += weight;
                    weighted_age_s += weight * age_s;
                    on_obstacles += 1;
                    corners = Some(corners.map_or((p, p), |(lo, hi)| (lo.inf(&p), hi.sup(&p))));
                }
                Some(&v) if v >= self.occupied_threshold => {}
                Some(&v) if v != UNKNOWN => score += FREE_HIT,
                _ => {}
            }
        }
        FitScore {
            score,
            span_m: corners.map_or(0.0, |(lo, hi)| (hi - lo).norm()),
            age_s: if weights > 0.0 {
                weighted_age_s / weights
            } else {
                0.0
            },
            on_obstacles,
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
            r.fit_score(&hits, Vector2::zeros(), 100.0, 5.0).score,
            -5.0,
            "all in free space"
        );
        let on = r.fit_score(&hits, Vector2::new(0.2, 0.0), 100.0, 5.0);
        assert_eq!(on.score, 10.0);
        assert!(
            (on.span_m - 0.9).abs() < 1e-9,
            "hits 1.55 to 2.45 m: {on:?}"
        );
        assert_eq!(
            r.fit_score(&hits, Vector2::new(0.2, 0.32), 100.0, 5.0)
                .score,
            7.0 - 1.5
        );
        assert_eq!(
            r.fit_score(&hits, Vector2::new(0.2, 0.0), 4.0, 5.0).score,
            0.0,
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
            r.fit_score(&hits, Vector2::new(0.2, 0.32), 100.0, 5.0)
                .score,
            7.0,
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
        assert_eq!(
            r.fit_score(&hit, Vector2::zeros(), 11.9, 5.0).score,
            0.0,
            "too new"
        );
        assert_eq!(
            r.fit_score(&hit, Vector2::zeros(), 13.0, 5.0).score,
            0.2,
            "6 s of 30"
        );
        assert_eq!(r.fit_score(&hit, Vector2::zeros(), 60.0, 5.0).score, 1.0);
        g.set(cell, 10).unwrap();
        since.restamp(&g, 31, CellBox::of_cell(cell), 10.0);
        assert_eq!(since.get(i), None, "freed: no stamp");
    }
}
