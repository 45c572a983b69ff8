//! Where one drone can fly from where it is: path distances over the navigable cells of a
//! [`Space`], and the path to any reached cell.
//!
//! In: a [`Space`] and the drone's position. Out: a [`Reach`]: for every cell the length of the
//! shortest 8-connected path through navigable cells (m; `None` when unreachable) and that
//! path, shortened to the corners a straight line cannot cut. One search serves the allocator
//! (path distance to every frontier at once) and the flight (the path to the chosen one).
//!
//! The drone's own neighbourhood (the safety distance around it) counts as navigable where it
//! is no closer to an obstacle or to unknown space than the drone already is, so a drone that
//! hovers where it has not mapped yet (just after takeoff) can leave it, and one that has come
//! close to an obstacle leaves it without grazing it. Discs to keep out of (around a drone
//! another Kestrel flew that fell silent: the safety stage stops any drone at their edge) are
//! not passable either, except, for a drone already inside one, outward. Costs are 10 per
//! straight step and 14 per diagonal, searched with a bucket queue (O(cells)).

use nalgebra::Vector2;

use super::space::Space;

const STRAIGHT: u32 = 10;
const DIAGONAL: u32 = 14;
const UNREACHED: u32 = u32::MAX;

/// A disc no path may enter (ENU m).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct KeepOut {
    pub centre_enu_m: Vector2<f64>,
    pub radius_m: f64,
}

/// Path distances from one start.
#[derive(Debug, Clone)]
pub struct Reach {
    width: usize,
    start: usize,
    /// The discs kept out of, with the start's distance from each centre (m).
    keep_out: Vec<(KeepOut, f64)>,
    cost: Vec<u32>,
    parent: Vec<u32>,
    resolution_m: f64,
}

impl Reach {
    /// Searches from `from_enu_m`; `None` when it lies outside the grid.
    pub fn new(space: &Space, from_enu_m: Vector2<f64>) -> Option<Self> {
        Self::keeping_out(space, from_enu_m, &[])
    }

    /// As [`Reach::new`], never entering the discs `keep_out` (nor going deeper into one the
    /// drone is in).
    pub fn keeping_out(
        space: &Space,
        from_enu_m: Vector2<f64>,
        keep_out: &[KeepOut],
    ) -> Option<Self> {
        let spec = *space.spec();
        let (w, h) = (spec.width_cells as usize, spec.height_cells as usize);
        let start = space.index_at(from_enu_m)?;
        let start_at = space.center_of(start)?;
        let keep_out: Vec<(KeepOut, f64)> = keep_out
            .iter()
            .map(|k| (*k, (start_at - k.centre_enu_m).norm()))
            .collect();
        let outside = |i: usize| outside_keep_out(space, &keep_out, i);
        let s = space.safety_cells() as i64;
        let (sx, sy) = ((start % w) as i64, (start / w) as i64);
        // Near the start: never closer to an obstacle or the unknown than the drone already is.
        let start_margin = space.clearance_level(start);
        let near_start_ok =
            |i: usize| space.is_clear(i) && space.clearance_level(i) >= start_margin;
        // Which cells a path may enter, worked out once (each is asked up to 16 times below):
        // the navigable ones, and near the start those no closer to trouble than the start;
        // none inside a keep-out disc.
        let mut pass = space.navigable_cells().to_vec();
        for y in (sy - s).max(0)..=(sy + s).min(h as i64 - 1) {
            for x in (sx - s).max(0)..=(sx + s).min(w as i64 - 1) {
                let i = y as usize * w + x as usize;
                pass[i] = pass[i] || near_start_ok(i);
            }
        }
        for (k, _) in &keep_out {
            // The disc's cells, its centre possibly off the grid.
            let r = (k.radius_m / spec.resolution_m).ceil() as i64 + 1;
            let from_origin = (k.centre_enu_m - spec.origin_enu_m) / spec.resolution_m;
            let (cx, cy) = (from_origin.x.floor() as i64, from_origin.y.floor() as i64);
            for y in (cy - r).max(0)..=(cy + r).min(h as i64 - 1) {
                for x in (cx - r).max(0)..=(cx + r).min(w as i64 - 1) {
                    let i = y as usize * w + x as usize;
                    pass[i] = pass[i] && outside(i);
                }
            }
        }
        let passable = |i: usize| pass[i];
        let mut cost = vec![UNREACHED; w * h];
        let mut parent = vec![u32::MAX; w * h];
        let mut buckets: Vec<Vec<u32>> = vec![Vec::new(); (DIAGONAL + 1) as usize];
        cost[start] = 0;
        buckets[0].push(start as u32);
        let mut pending = 1usize;
        let mut current: u32 = 0;
        while pending > 0 {
            let slot = (current % (DIAGONAL + 1)) as usize;
            let Some(i) = buckets[slot].pop() else {
                current += 1;
                continue;
            };
            pending -= 1;
            let i = i as usize;
            if cost[i] != current {
                continue;
            }
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for (dx, dy) in NEIGHBOURS {
                let (nx, ny) = (x + dx, y + dy);
                if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                    continue;
                }
                let j = ny as usize * w + nx as usize;
                if !passable(j) {
                    continue;
                }
                // No corner cutting between two blocked cells.
                if dx != 0 && dy != 0 {
                    let a = y as usize * w + nx as usize;
                    let b = ny as usize * w + x as usize;
                    if !passable(a) || !passable(b) {
                        continue;
                    }
                }
                let step = if dx != 0 && dy != 0 {
                    DIAGONAL
                } else {
                    STRAIGHT
                };
                let c = current + step;
                if c < cost[j] {
                    cost[j] = c;
                    parent[j] = i as u32;
                    buckets[(c % (DIAGONAL + 1)) as usize].push(j as u32);
                    pending += 1;
                }
            }
        }
        Some(Reach {
            width: w,
            start,
            keep_out,
            cost,
            parent,
            resolution_m: spec.resolution_m,
        })
    }

    /// Path length (m) to cell `index`, if reached.
    pub fn distance_m(&self, index: usize) -> Option<f64> {
        let c = *self.cost.get(index)?;
        (c != UNREACHED).then(|| f64::from(c) / f64::from(STRAIGHT) * self.resolution_m)
    }

    /// The cells from the start to `index` (both included), if reached.
    fn cells_to(&self, index: usize) -> Option<Vec<usize>> {
        self.distance_m(index)?;
        let mut cells = vec![index];
        let mut at = index;
        while at != self.start {
            at = *self.parent.get(at)? as usize;
            cells.push(at);
            if cells.len() > self.cost.len() {
                return None;
            }
        }
        cells.reverse();
        Some(cells)
    }

    /// The path to `index` as cell centres (ENU m), keeping only the corners a straight segment
    /// through navigable cells cannot cut; the start cell is left out.
    pub fn path_to(&self, space: &Space, index: usize) -> Option<Vec<Vector2<f64>>> {
        let cells = self.cells_to(index)?;
        let mut corners = Vec::new();
        let mut from = 0usize;
        while from + 1 < cells.len() {
            // The farthest cell along the path still in straight sight of `from`.
            let mut next = from + 1;
            for (k, &c) in cells.iter().enumerate().skip(from + 2) {
                if self.line_clear(space, cells[from], c) {
                    next = k;
                }
            }
            corners.push(cells[next]);
            from = next;
        }
        corners
            .into_iter()
            .map(|i| space.center_of(i))
            .collect::<Option<Vec<_>>>()
    }

    /// Whether cell `index` lies inside a keep-out disc (deeper than the start is).
    pub fn kept_out(&self, space: &Space, index: usize) -> bool {
        !outside_keep_out(space, &self.keep_out, index)
    }

    /// The reached cell nearest to cell `index` within `within_m` of it, if any: where to look
    /// at a goal that lies in a keep-out disc from.
    pub fn nearest_reached(&self, space: &Space, index: usize, within_m: f64) -> Option<usize> {
        let at = space.center_of(index)?;
        let r = (within_m / self.resolution_m).ceil() as i64;
        let w = self.width as i64;
        let h = (self.cost.len() / self.width) as i64;
        let (cx, cy) = ((index as i64) % w, (index as i64) / w);
        let mut best: Option<(f64, usize)> = None;
        for y in (cy - r).max(0)..=(cy + r).min(h - 1) {
            for x in (cx - r).max(0)..=(cx + r).min(w - 1) {
                let i = (y * w + x) as usize;
                if self.cost[i] == UNREACHED {
                    continue;
                }
                let Some(c) = space.center_of(i) else {
                    continue;
                };
                let d = (c - at).norm();
                if d <= within_m && best.is_none_or(|(b, _)| d < b) {
                    best = Some((d, i));
                }
            }
        }
        best.map(|(_, i)| i)
    }

    /// Whether every cell on the segment between two cells is navigable (or the start's own
    /// neighbourhood).
    pub fn line_clear(&self, space: &Space, a: usize, b: usize) -> bool {
        let w = self.width as i64;
        let (mut x, mut y) = ((a as i64) % w, (a as i64) / w);
        let (x1, y1) = ((b as i64) % w, (b as i64) / w);
        let (dx, dy) = ((x1 - x).abs(), -(y1 - y).abs());
        let (step_x, step_y) = ((x1 - x).signum(), (y1 - y).signum());
        let mut err = dx + dy;
        loop {
            let i = (y * w + x) as usize;
            if !outside_keep_out(space, &self.keep_out, i)
                || (!space.is_navigable(i) && !self.near_start(i, space))
            {
                return false;
            }
            if x == x1 && y == y1 {
                return true;
            }
            let e2 = 2 * err;
            if e2 >= dy {
                err += dy;
                x += step_x;
            }
            if e2 <= dx {
                err += dx;
                y += step_y;
            }
        }
    }

    fn near_start(&self, i: usize, space: &Space) -> bool {
        let w = self.width as i64;
        let s = space.safety_cells() as i64;
        let (x, y) = ((i as i64) % w, (i as i64) / w);
        let (sx, sy) = ((self.start as i64) % w, (self.start as i64) / w);
        (x - sx).abs() <= s
            && (y - sy).abs() <= s
            && space.is_clear(i)
            && space.clearance_level(i) >= space.clearance_level(self.start)
    }
}

/// Whether cell `i` lies outside every disc, or inside one no deeper than the start was.
fn outside_keep_out(space: &Space, keep_out: &[(KeepOut, f64)], i: usize) -> bool {
    if keep_out.is_empty() {
        return true;
    }
    let Some(at) = space.center_of(i) else {
        return false;
    };
    keep_out.iter().all(|(k, start_m)| {
        let d = (at - k.centre_enu_m).norm();
        d >= k.radius_m || d >= *start_m
    })
}

const NEIGHBOURS: [(i64, i64); 8] = [
    (1, 0),
    (-1, 0),
    (0, 1),
    (0, -1),
    (1, 1),
    (1, -1),
    (-1, 1),
    (-1, -1),
];

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::super::space::tests::grid;
    use super::super::space::{Space, SpaceParams};
    use super::*;

    #[test]
    fn distances_go_around_a_wall_and_the_path_keeps_clear_of_it() {
        // 100 x 100 free, a wall at x = 50 from y = 0 to 70: from (2, 2) to (8, 2) the path
        // goes over the wall's end.
        let g = grid(100, 100, |x, y| if x == 50 && y < 70 { 100 } else { 0 });
        let space = Space::new(&g, &SpaceParams::default());
        let reach = Reach::new(&space, Vector2::new(2.0, 2.0)).unwrap();
        let goal = space.index_at(Vector2::new(8.0, 2.0)).unwrap();
        let d = reach.distance_m(goal).unwrap();
        assert!(
            d > 2.0 * (5.5f64.powi(2) + 3.0f64.powi(2)).sqrt() - 0.5,
            "{d}"
        );
        let path = reach.path_to(&space, goal).unwrap();
        assert!(path.len() >= 2 && path.len() < 8, "{path:?}");
        assert!((path.last().unwrap() - Vector2::new(8.05, 2.05)).norm() < 0.1);
        // Every segment stays 0.4 m clear of the wall.
        let mut prev = Vector2::new(2.05, 2.05);
        for p in &path {
            for k in 0..=100 {
                let q = prev + (p - prev) * (k as f64 / 100.0);
                if q.y < 7.0 {
                    assert!((q.x - 5.05).abs() > 0.4, "{q:?} on {path:?}");
                }
            }
            prev = *p;
        }
    }

    #[test]
    fn unknown_space_is_not_reached_but_the_drones_own_spot_is_left() {
        // All unknown but a known corridor; the drone sits in unknown at its end.
        let g = grid(100, 40, |x, y| {
            if (10..=30).contains(&y) && x >= 20 {
                0
            } else {
                crate::mapping::grid::UNKNOWN
            }
        });
        let space = Space::new(&g, &SpaceParams::default());
        let reach = Reach::new(&space, Vector2::new(2.25, 2.05)).unwrap();
        let inside = space.index_at(Vector2::new(6.0, 2.05)).unwrap();
        assert!(
            reach.distance_m(inside).is_some(),
            "the corridor is reached from the spot"
        );
        let unknown = space.index_at(Vector2::new(1.0, 0.5)).unwrap();
        assert!(reach.distance_m(unknown).is_none());
    }

    #[test]
    fn a_drone_near_an_obstacle_leaves_without_coming_closer_to_it() {
        // All known free but an obstacle cell at (5.05, 2.05); the drone 0.3 m east of it,
        // within the safety distance (so in no navigable cell).
        let g = grid(100, 40, |x, y| if (x, y) == (50, 20) { 100 } else { 0 });
        let space = Space::new(&g, &SpaceParams::default());
        let from = Vector2::new(5.35, 2.05);
        assert!(!space.is_navigable(space.index_at(from).unwrap()));
        let reach = Reach::new(&space, from).unwrap();
        let closer = space.index_at(Vector2::new(5.25, 2.05)).unwrap();
        assert!(
            reach.distance_m(closer).is_none(),
            "0.2 m from the obstacle"
        );
        let away = space.index_at(Vector2::new(5.75, 2.05)).unwrap();
        assert!(reach.distance_m(away).is_some());
        // The way to the far side goes round at the safety distance.
        let far_side = space.index_at(Vector2::new(4.45, 2.05)).unwrap();
        let path = reach.path_to(&space, far_side).unwrap();
        let obstacle = Vector2::new(5.05, 2.05);
        let mut at = from;
        for p in &path {
            for k in 0..=20 {
                let q = at + (p - at) * (f64::from(k) / 20.0);
                assert!((q - obstacle).norm() > 0.19, "{q:?} on {path:?}");
            }
            at = *p;
        }
    }

    #[test]
    fn a_path_never_cuts_toward_an_unknown_hole_where_a_pole_no_beam_hit_may_stand() {
        // Known free but a 5 x 5 unknown hole (cells 28..33 x 18..23, centre (3.05, 2.05)): a
        // pole the beams went round without hitting. The drone is 0.45 m from its corner, just
        // outside the safety distance; the goal lies beyond the hole. Near its own spot the
        // path must not come closer to the unknown than the drone already is.
        let hole = |x: u32, y: u32| (28..33).contains(&x) && (18..23).contains(&y);
        let g = grid(80, 50, |x, y| {
            if hole(x, y) {
                crate::mapping::grid::UNKNOWN
            } else {
                0
            }
        });
        let space = Space::new(&g, &SpaceParams::default());
        let from = Vector2::new(2.45, 2.65);
        let to_hole = |q: Vector2<f64>| {
            let nearest = Vector2::new(q.x.clamp(2.8, 3.3), q.y.clamp(1.8, 2.3));
            (q - nearest).norm()
        };
        let start_gap = to_hole(from);
        assert!(start_gap > 0.4 && start_gap < 0.5, "{start_gap}");
        let reach = Reach::new(&space, from).unwrap();
        let goal = space.index_at(Vector2::new(3.85, 1.25)).unwrap();
        let path = reach.path_to(&space, goal).unwrap();
        let mut at = from;
        for p in &path {
            for k in 0..=40 {
                let q = at + (p - at) * (f64::from(k) / 40.0);
                assert!(to_hole(q) > 0.35, "{q:?} on {path:?}");
            }
            at = *p;
        }
    }

    #[test]
    fn a_keep_out_disc_is_neither_entered_nor_crossed_but_left_from_inside() {
        // 10 x 4 m known free; a 1.5 m disc around (5, 2) (a silent drone's last position).
        let g = grid(100, 40, |_, _| 0);
        let space = Space::new(&g, &SpaceParams::default());
        let disc = KeepOut {
            centre_enu_m: Vector2::new(5.0, 2.0),
            radius_m: 1.5,
        };
        let reach = Reach::keeping_out(&space, Vector2::new(2.05, 2.05), &[disc]).unwrap();
        let inside = space.index_at(Vector2::new(5.6, 2.0)).unwrap();
        assert!(reach.distance_m(inside).is_none());
        // Across: round it, never through it.
        let across = space.index_at(Vector2::new(8.05, 2.05)).unwrap();
        let path = reach.path_to(&space, across).unwrap();
        let mut at = Vector2::new(2.05, 2.05);
        for p in &path {
            for k in 0..=40 {
                let q = at + (p - at) * (f64::from(k) / 40.0);
                assert!((q - disc.centre_enu_m).norm() > 1.45, "{q:?} on {path:?}");
            }
            at = *p;
        }
        // From inside it, a drone gets out, moving away from the centre.
        let from_inside = Reach::keeping_out(&space, Vector2::new(4.45, 2.05), &[disc]).unwrap();
        let out = space.index_at(Vector2::new(2.05, 2.05)).unwrap();
        assert!(from_inside.distance_m(out).is_some());
        let deeper = space.index_at(Vector2::new(5.15, 2.05)).unwrap();
        assert!(from_inside.distance_m(deeper).is_none());
    }
}
