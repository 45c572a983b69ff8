//! 2D occupancy grid built from range scans (the `scan2occ_grid` plugin).
//!
//! In: a [`GridSpec`] and [`RangeScan`]s with [`InsertParams`]. Out: an [`OccupancyGrid`] of
//! `i8` cells (`-1` unknown, `0..=100` occupancy), a [`CellBox`] holding every cell an insertion
//! changed, and [`GridPatch`]es of changed regions.
//!
//! Update rule, per scan: every cell a beam passes through before its end is a miss; the end cell
//! is a hit when the range is below `min(range_max, max_range)`, otherwise (max-range or no return)
//! it is a miss too and the ray is only cleared. Each cell is updated at most once per scan and a
//! hit wins over a miss, so a 360-beam scan does not subtract 40 times from the cells next to the
//! sensor. A hit adds `hit_confidence`, a miss subtracts `miss_confidence`, an unknown cell counts
//! as 0 before the update, results are clipped to `0..=100`. Cells never touched stay unknown.
//! Unlike Aerostack2 (which locks cells above 80 at 100 for ever), locking is optional
//! (`lock_above`), so a moved obstacle can be cleared.
//!
//! A beam without a return ends before the first cell the map holds as occupied
//! (`no_return_stops_at`) and leaves it as it is: a ranger's dropped reading looks exactly like
//! an open view, so it may neither erase an obstacle nor see behind one. Only a beam with a hit
//! beyond such a cell clears it (a moved obstacle).

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::raycast::{trace_segment, TraceEnd};
use super::scan::{Beam, RangeScan};
use super::MapError;

/// Value of a cell never observed.
pub const UNKNOWN: i8 = -1;
/// Largest number of cells a grid may hold (about 268 million, 256 MiB of `i8`).
pub const MAX_CELLS: u64 = 1 << 28;

/// Geometry of a grid.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GridSpec {
    /// Edge of a square cell, metres (> 0).
    pub resolution_m: f64,
    pub width_cells: u32,
    pub height_cells: u32,
    /// World position of cell (0,0)'s lower-left corner (ENU, metres).
    pub origin_enu_m: Vector2<f64>,
}

/// A cell coordinate: `x` along east, `y` along north.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, PartialOrd, Ord, Serialize, Deserialize)]
pub struct Cell {
    pub x: u32,
    pub y: u32,
}

/// Cells at or above this occupancy are obstacles (Aerostack2 treats `> 30` as occupied).
pub const DEFAULT_OCCUPIED_THRESHOLD: i8 = 31;

/// An inclusive rectangle of cells.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct CellBox {
    pub min: Cell,
    pub max: Cell,
}

impl CellBox {
    pub fn of_cell(c: Cell) -> Self {
        CellBox { min: c, max: c }
    }

    /// Grows the box to contain `c`.
    pub fn include(&mut self, c: Cell) {
        self.min.x = self.min.x.min(c.x);
        self.min.y = self.min.y.min(c.y);
        self.max.x = self.max.x.max(c.x);
        self.max.y = self.max.y.max(c.y);
    }

    /// Smallest box containing both.
    pub fn union(self, other: CellBox) -> CellBox {
        let mut b = self;
        b.include(other.min);
        b.include(other.max);
        b
    }

    /// The cells in both boxes, `None` when they do not overlap.
    pub fn intersect(self, other: CellBox) -> Option<CellBox> {
        let b = CellBox {
            min: Cell {
                x: self.min.x.max(other.min.x),
                y: self.min.y.max(other.min.y),
            },
            max: Cell {
                x: self.max.x.min(other.max.x),
                y: self.max.y.min(other.max.y),
            },
        };
        (b.min.x <= b.max.x && b.min.y <= b.max.y).then_some(b)
    }

    pub fn width_cells(&self) -> u32 {
        self.max.x - self.min.x + 1
    }

    pub fn height_cells(&self) -> u32 {
        self.max.y - self.min.y + 1
    }
}

/// A rectangular copy of grid cells, row-major from `region.min` (for "changed region" updates).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct GridPatch {
    pub region: CellBox,
    pub data: Vec<i8>,
}

impl GridSpec {
    /// Checks resolution, size and origin.
    pub fn validate(&self) -> Result<(), MapError> {
        if !(self.resolution_m.is_finite() && self.resolution_m > 0.0) {
            return Err(MapError::InvalidSpec(format!(
                "resolution_m must be > 0, got {}",
                self.resolution_m
            )));
        }
        let cells = u64::from(self.width_cells) * u64::from(self.height_cells);
        if cells == 0 || cells > MAX_CELLS {
            return Err(MapError::InvalidSpec(format!(
                "grid must have 1..={MAX_CELLS} cells, got {}x{}",
                self.width_cells, self.height_cells
            )));
        }
        if !(self.origin_enu_m.x.is_finite() && self.origin_enu_m.y.is_finite()) {
            return Err(MapError::InvalidSpec("origin not finite".into()));
        }
        Ok(())
    }

    pub fn cell_count(&self) -> usize {
        self.width_cells as usize * self.height_cells as usize
    }

    /// The cell containing a world point, `None` outside the grid.
    pub fn cell_at(&self, p: Vector2<f64>) -> Option<Cell> {
        // Truncation equals floor on the accepted range (>= 0), without a libm call.
        let gx = (p.x - self.origin_enu_m.x) / self.resolution_m;
        let gy = (p.y - self.origin_enu_m.y) / self.resolution_m;
        let inside = gx >= 0.0
            && gy >= 0.0
            && gx < f64::from(self.width_cells)
            && gy < f64::from(self.height_cells);
        inside.then_some(Cell {
            x: gx as u32,
            y: gy as u32,
        })
    }

    /// World position of a cell's centre.
    pub fn cell_center_enu_m(&self, c: Cell) -> Vector2<f64> {
        self.origin_enu_m
            + Vector2::new(f64::from(c.x) + 0.5, f64::from(c.y) + 0.5) * self.resolution_m
    }

    /// Flat index (`y * width + x`), `None` outside the grid.
    pub fn index_of(&self, c: Cell) -> Option<usize> {
        (c.x < self.width_cells && c.y < self.height_cells)
            .then(|| c.y as usize * self.width_cells as usize + c.x as usize)
    }

    /// Cell of a flat index, `None` past the end.
    pub fn cell_of_index(&self, i: usize) -> Option<Cell> {
        (i < self.cell_count()).then(|| Cell {
            x: (i % self.width_cells as usize) as u32,
            y: (i / self.width_cells as usize) as u32,
        })
    }

    /// Whole-grid box.
    pub fn full_box(&self) -> CellBox {
        CellBox {
            min: Cell { x: 0, y: 0 },
            max: Cell {
                x: self.width_cells.saturating_sub(1),
                y: self.height_cells.saturating_sub(1),
            },
        }
    }
}

/// How scans change the grid. Defaults are Aerostack2's (`hit 40`, `miss 10`) without locking.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct InsertParams {
    /// Added to a cell at a beam's end (0..=100).
    pub hit_confidence: u8,
    /// Subtracted from a cell a beam passes through (0..=100).
    pub miss_confidence: u8,
    /// Readings are clipped to this range (metres); `None` = the scan's own `range_max_m`.
    pub max_range_m: Option<f64>,
    /// Cells above this value are kept at 100 for ever (Aerostack2 uses 80); `None` = never.
    pub lock_above: Option<u8>,
    /// A beam without a return stops before a cell at or above this value (the occupied
    /// threshold), leaving it as it is; `None` = it clears its whole ray.
    pub no_return_stops_at: Option<u8>,
}

impl Default for InsertParams {
    fn default() -> Self {
        InsertParams {
            hit_confidence: 40,
            miss_confidence: 10,
            max_range_m: None,
            lock_above: None,
            no_return_stops_at: Some(DEFAULT_OCCUPIED_THRESHOLD as u8),
        }
    }
}

/// Per-scan bookkeeping reused between insertions: a stamp per cell,
/// `generation << 9 | hit << 8 | value before the scan (as u8)`.
#[derive(Debug, Clone, Default)]
struct RayScratch {
    mark: Vec<u32>,
    generation: u32,
}

const MARK_HIT: u32 = 1 << 8;
const MARK_SHIFT: u32 = 9;

/// World directions of a scan's beams, in order. Evenly spaced beams (a lidar) are rotated
/// from one to the next (two multiplications instead of a `sin_cos` call each; the drift over
/// thousands of beams stays below 1e-12 rad); other scans use `sin_cos` per beam.
struct BeamDirections {
    current: Vector2<f64>,
    step: Option<(f64, f64)>,
}

impl BeamDirections {
    fn new(scan: &RangeScan) -> Self {
        let angles = || scan.beams.iter().map(|b| b.angle_rad);
        let first = angles().next().unwrap_or(0.0);
        let second = angles().nth(1).unwrap_or(first);
        let delta = second - first;
        let even = scan.beams.len() >= 3
            && angles()
                .zip(angles().skip(1))
                .all(|(a, b)| ((b - a) - delta).abs() <= 1e-12 * (1.0 + delta.abs()));
        let (sin, cos) = (scan.yaw_rad + first).sin_cos();
        BeamDirections {
            current: Vector2::new(cos, sin),
            step: even.then(|| (delta.cos(), delta.sin())),
        }
    }

    /// Direction of `beam`, which must be the next beam of the scan.
    fn next(&mut self, scan: &RangeScan, beam: &Beam) -> Vector2<f64> {
        match self.step {
            Some((c, s)) => {
                let d = self.current;
                self.current = Vector2::new(d.x * c - d.y * s, d.x * s + d.y * c);
                d
            }
            None => scan.beam_direction_enu(beam),
        }
    }
}

/// Occupancy grid: `-1` unknown, `0..=100` occupancy probability in percent.
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(try_from = "GridJson")]
pub struct OccupancyGrid {
    spec: GridSpec,
    data: Vec<i8>,
    #[serde(skip)]
    scratch: RayScratch,
}

/// The JSON form `{spec, data}` before validation.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct GridJson {
    spec: GridSpec,
    data: Vec<i8>,
}

impl TryFrom<GridJson> for OccupancyGrid {
    type Error = MapError;
    fn try_from(raw: GridJson) -> Result<Self, MapError> {
        OccupancyGrid::from_data(raw.spec, raw.data)
    }
}

impl PartialEq for OccupancyGrid {
    fn eq(&self, other: &Self) -> bool {
        self.spec == other.spec && self.data == other.data
    }
}

impl OccupancyGrid {
    /// An all-unknown grid.
    pub fn new(spec: GridSpec) -> Result<Self, MapError> {
        spec.validate()?;
        Ok(OccupancyGrid {
            spec,
            data: vec![UNKNOWN; spec.cell_count()],
            scratch: RayScratch::default(),
        })
    }

    /// A grid from row-major cells (`y * width + x`, row 0 at the south edge).
    pub fn from_data(spec: GridSpec, data: Vec<i8>) -> Result<Self, MapError> {
        spec.validate()?;
        if data.len() != spec.cell_count() {
            return Err(MapError::DataLength {
                expected: spec.cell_count(),
                got: data.len(),
            });
        }
        if let Some(&v) = data.iter().find(|&&v| !(-1..=100).contains(&v)) {
            return Err(MapError::InvalidValue(v));
        }
        Ok(OccupancyGrid {
            spec,
            data,
            scratch: RayScratch::default(),
        })
    }

    pub fn spec(&self) -> &GridSpec {
        &self.spec
    }

    /// Row-major cells.
    pub fn data(&self) -> &[i8] {
        &self.data
    }

    pub fn get(&self, c: Cell) -> Option<i8> {
        self.spec
            .index_of(c)
            .and_then(|i| self.data.get(i).copied())
    }

    /// Value at a world point, `None` outside the grid.
    pub fn get_at(&self, p: Vector2<f64>) -> Option<i8> {
        self.spec.cell_at(p).and_then(|c| self.get(c))
    }

    /// Sets one cell (`-1` or `0..=100`).
    pub fn set(&mut self, c: Cell, value: i8) -> Result<(), MapError> {
        if !(-1..=100).contains(&value) {
            return Err(MapError::InvalidValue(value));
        }
        let slot = self
            .spec
            .index_of(c)
            .and_then(|i| self.data.get_mut(i))
            .ok_or(MapError::OutsideMap { x: c.x, y: c.y })?;
        *slot = value;
        Ok(())
    }

    /// Copy of a region (clipped to the grid), `None` if the region misses the grid.
    pub fn patch(&self, region: CellBox) -> Option<GridPatch> {
        let full = self.spec.full_box();
        if region.min.x > full.max.x || region.min.y > full.max.y {
            return None;
        }
        let region = CellBox {
            min: region.min,
            max: Cell {
                x: region.max.x.min(full.max.x),
                y: region.max.y.min(full.max.y),
            },
        };
        if region.max.x < region.min.x || region.max.y < region.min.y {
            return None;
        }
        let w = self.spec.width_cells as usize;
        let mut data = Vec::with_capacity((region.width_cells() * region.height_cells()) as usize);
        for y in region.min.y..=region.max.y {
            let row = y as usize * w;
            let cells = self
                .data
                .get(row + region.min.x as usize..=row + region.max.x as usize)?;
            data.extend_from_slice(cells);
        }
        Some(GridPatch { region, data })
    }

    /// Writes a patch taken from a grid on the same spec back in (a copy kept in step with
    /// another grid). Refused whole, with nothing written, when the patch leaves the grid or its
    /// data does not fill its region.
    pub fn write_patch(&mut self, patch: &GridPatch) -> Result<(), MapError> {
        let r = patch.region;
        let full = self.spec.full_box();
        if r.intersect(full) != Some(r) {
            return Err(MapError::OutsideMap {
                x: r.max.x,
                y: r.max.y,
            });
        }
        let row_len = r.width_cells() as usize;
        if patch.data.len() != row_len * r.height_cells() as usize {
            return Err(MapError::InvalidSpec(format!(
                "a patch of {}x{} cells carries {} values",
                r.width_cells(),
                r.height_cells(),
                patch.data.len()
            )));
        }
        let w = self.spec.width_cells as usize;
        for (y, src) in (r.min.y..=r.max.y).zip(patch.data.chunks(row_len)) {
            let start = y as usize * w + r.min.x as usize;
            if let Some(dst) = self.data.get_mut(start..start + row_len) {
                dst.copy_from_slice(src);
            }
        }
        Ok(())
    }

    /// Ray-casts a scan into the grid (see the module docs for the rule). Returns a box that
    /// contains every cell whose value changed, `None` if nothing changed. (A cell first missed
    /// then hit by the same scan may end where it started and still be inside the box.)
    pub fn insert_scan(
        &mut self,
        scan: &RangeScan,
        params: &InsertParams,
    ) -> Result<Option<CellBox>, MapError> {
        scan.validate()?;
        let limit_m = match params.max_range_m {
            Some(m) if m.is_finite() && m > 0.0 => m.min(scan.range_max_m),
            Some(m) => {
                return Err(MapError::InvalidScan(format!(
                    "max_range_m must be > 0, got {m}"
                )))
            }
            None => scan.range_max_m,
        };
        let gen = self.next_generation();
        let hit = i16::from(params.hit_confidence.min(100));
        let miss = -i16::from(params.miss_confidence.min(100));
        let lock = params.lock_above.map(i16::from);
        let stop_at = params.no_return_stops_at.map(|s| s.min(100) as i8);
        let update = |old: i8, delta: i16| -> i8 {
            let old = i16::from(old);
            if lock.is_some_and(|l| old > l) {
                100
            } else {
                (old.max(0) + delta).clamp(0, 100) as i8
            }
        };
        // The update of every possible cell value, indexed by the value as `u8`.
        let table = |delta: i16| -> [i8; 256] {
            let mut t = [0i8; 256];
            for (byte, slot) in t.iter_mut().enumerate() {
                *slot = update(byte as u8 as i8, delta);
            }
            t
        };
        let (after_hit, after_miss) = (table(hit), table(miss));
        let w = self.spec.width_cells as usize;
        let mut changed: Option<CellBox> = None;
        // Cell coordinates are only computed for cells that change (rare once the map settles).
        let note = |changed: &mut Option<CellBox>, i: usize| {
            let c = Cell {
                x: (i % w) as u32,
                y: (i / w) as u32,
            };
            match changed.as_mut() {
                Some(b) => b.include(c),
                None => *changed = Some(CellBox::of_cell(c)),
            }
        };
        let origin = scan.origin_enu_m.xy();
        let OccupancyGrid {
            spec,
            data,
            scratch,
        } = self;
        let mark = &mut scratch.mark;
        let mut directions = BeamDirections::new(scan);
        for beam in &scan.beams {
            let direction = directions.next(scan, beam);
            let (range_m, is_hit) = match beam.range_m {
                Some(r) if r.is_nan() || r < scan.range_min_m => continue,
                Some(r) if r < limit_m => (r, true),
                _ => (limit_m, false),
            };
            let end = origin + direction * range_m;
            let stop_at = if is_hit { None } else { stop_at };
            // Every cell on the ray, the end included, is a miss unless already updated by
            // this scan; a beam without a return stops at an occupied cell.
            let traced = trace_segment(spec, origin, end, |i| {
                if let (Some(m), Some(v)) = (mark.get_mut(i), data.get_mut(i)) {
                    let fresh = *m >> MARK_SHIFT != gen;
                    if let Some(s) = stop_at {
                        let before_scan = if fresh { *v } else { (*m & 0xFF) as u8 as i8 };
                        if before_scan.max(*v) >= s {
                            return false;
                        }
                    }
                    if fresh {
                        let old = *v;
                        *m = (gen << MARK_SHIFT) | u32::from(old as u8);
                        let new = after_miss[usize::from(old as u8)];
                        if new != old {
                            *v = new;
                            note(&mut changed, i);
                        }
                    }
                }
                true
            });
            if !(is_hit && traced == TraceEnd::EndInside) {
                continue;
            }
            // The end cell: a hit replaces whatever this scan did to it so far.
            let end_index = spec.cell_at(end).and_then(|c| spec.index_of(c));
            let Some(e) = end_index else { continue };
            if let (Some(m), Some(v)) = (mark.get_mut(e), data.get_mut(e)) {
                if *m & MARK_HIT == 0 {
                    *m |= MARK_HIT;
                    let before_scan = (*m & 0xFF) as u8 as i8;
                    let new = after_hit[usize::from(before_scan as u8)];
                    if new != *v {
                        *v = new;
                        note(&mut changed, e);
                    }
                }
            }
        }
        Ok(changed)
    }

    fn next_generation(&mut self) -> u32 {
        let s = &mut self.scratch;
        if s.mark.len() != self.data.len() {
            s.mark = vec![0; self.data.len()];
            s.generation = 0;
        }
        s.generation += 1;
        // Generations use the top 23 bits; on wrap, clear the stamps so old ones cannot match.
        if s.generation >= 1 << (32 - MARK_SHIFT) {
            s.mark.iter_mut().for_each(|m| *m = 0);
            s.generation = 1;
        }
        s.generation
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;

    pub(crate) fn spec(w: u32, h: u32, res: f64) -> GridSpec {
        GridSpec {
            resolution_m: res,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        }
    }

    fn scan_at(x: f64, y: f64, beams: Vec<Beam>) -> RangeScan {
        RangeScan {
            origin_enu_m: Vector3::new(x, y, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams,
        }
    }

    fn row(g: &OccupancyGrid, y: u32) -> Vec<i8> {
        (0..g.spec().width_cells)
            .map(|x| g.get(Cell { x, y }).unwrap_or(i8::MIN))
            .collect()
    }

    #[test]
    fn world_cell_conversion_uses_lower_left_origin() {
        let s = GridSpec {
            resolution_m: 0.5,
            width_cells: 4,
            height_cells: 2,
            origin_enu_m: Vector2::new(-1.0, 2.0),
        };
        assert_eq!(
            s.cell_at(Vector2::new(-0.9, 2.1)),
            Some(Cell { x: 0, y: 0 })
        );
        assert_eq!(
            s.cell_at(Vector2::new(0.99, 2.99)),
            Some(Cell { x: 3, y: 1 })
        );
        assert_eq!(s.cell_at(Vector2::new(1.0, 2.5)), None);
        assert_eq!(s.cell_at(Vector2::new(f64::NAN, 2.5)), None);
        assert_eq!(
            s.cell_center_enu_m(Cell { x: 1, y: 1 }),
            Vector2::new(-0.25, 2.75)
        );
        assert_eq!(s.index_of(Cell { x: 3, y: 1 }), Some(7));
        assert_eq!(s.index_of(Cell { x: 4, y: 0 }), None);
    }

    #[test]
    fn single_beam_marks_misses_then_hit() {
        let mut g = OccupancyGrid::new(spec(8, 2, 1.0)).unwrap();
        let s = scan_at(
            0.5,
            0.5,
            vec![Beam {
                angle_rad: 0.0,
                range_m: Some(3.0),
            }],
        );
        let changed = g.insert_scan(&s, &InsertParams::default()).unwrap();
        assert_eq!(row(&g, 0), vec![0, 0, 0, 40, -1, -1, -1, -1]);
        assert_eq!(row(&g, 1), vec![-1; 8]);
        assert_eq!(
            changed,
            Some(CellBox {
                min: Cell { x: 0, y: 0 },
                max: Cell { x: 3, y: 0 }
            })
        );
    }

    #[test]
    fn diagonal_beam_matches_hand_computed_grid() {
        let mut g = OccupancyGrid::new(spec(6, 4, 1.0)).unwrap();
        // From (0.5,0.5) to (4.5,2.5): cells (0,0) (1,0) (1,1) (2,1) (3,1) (3,2) then hit (4,2).
        let mut s = scan_at(
            0.5,
            0.5,
            vec![Beam {
                angle_rad: 0.5f64.atan(),
                range_m: Some(20f64.sqrt()),
            }],
        );
        s.range_max_m = 10.0;
        g.insert_scan(&s, &InsertParams::default()).unwrap();
        assert_eq!(row(&g, 0), vec![0, 0, -1, -1, -1, -1]);
        assert_eq!(row(&g, 1), vec![-1, 0, 0, 0, -1, -1]);
        assert_eq!(row(&g, 2), vec![-1, -1, -1, 0, 40, -1]);
        assert_eq!(row(&g, 3), vec![-1; 6]);
    }

    #[test]
    fn max_range_and_no_return_clear_without_hit() {
        let mut g = OccupancyGrid::new(spec(8, 3, 1.0)).unwrap();
        let mut s = scan_at(
            0.5,
            1.5,
            vec![
                Beam {
                    angle_rad: 0.0,
                    range_m: Some(4.0),
                },
                Beam {
                    angle_rad: 0.0,
                    range_m: Some(9.0),
                },
            ],
        );
        g.insert_scan(&s, &InsertParams::default()).unwrap();
        // Cleared to range_max 4.0 m: cells 0..=4 free, no hit anywhere.
        assert_eq!(row(&g, 1), vec![0, 0, 0, 0, 0, -1, -1, -1]);
        s.beams = vec![Beam {
            angle_rad: 0.0,
            range_m: None,
        }];
        let changed = g.insert_scan(&s, &InsertParams::default()).unwrap();
        assert_eq!(changed, None);
        // A tighter max_range clips the reading: 3.0 m is beyond 2.5 m, so the ray is cleared to
        // x = 3.0 (cell 3) and nothing is hit.
        let mut g2 = OccupancyGrid::new(spec(8, 3, 1.0)).unwrap();
        s.beams = vec![Beam {
            angle_rad: 0.0,
            range_m: Some(3.0),
        }];
        let p = InsertParams {
            max_range_m: Some(2.5),
            ..InsertParams::default()
        };
        g2.insert_scan(&s, &p).unwrap();
        assert_eq!(row(&g2, 1), vec![0, 0, 0, 0, -1, -1, -1, -1]);
    }

    #[test]
    fn confidence_accumulates_and_clips() {
        let mut g = OccupancyGrid::new(spec(5, 1, 1.0)).unwrap();
        let hit = scan_at(
            0.5,
            0.5,
            vec![Beam {
                angle_rad: 0.0,
                range_m: Some(2.0),
            }],
        );
        let p = InsertParams::default();
        let mut at2 = Vec::new();
        for _ in 0..4 {
            g.insert_scan(&hit, &p).unwrap();
            at2.push(g.get(Cell { x: 2, y: 0 }).unwrap_or(i8::MIN));
        }
        assert_eq!(at2, vec![40, 80, 100, 100]);
        // A longer beam now passes through (2,0): each scan subtracts 10.
        let pass = scan_at(
            0.5,
            0.5,
            vec![Beam {
                angle_rad: 0.0,
                range_m: Some(3.9),
            }],
        );
        g.insert_scan(&pass, &p).unwrap();
        g.insert_scan(&pass, &p).unwrap();
        // Cell 3 was only ever missed (unknown -> 0), cell 4 is hit twice by the longer beam.
        assert_eq!(row(&g, 0), vec![0, 0, 80, 0, 80]);
        // With Aerostack2's lock at 80, cells above 80 stay at 100.
        let mut locked = OccupancyGrid::new(spec(5, 1, 1.0)).unwrap();
        let lp = InsertParams {
            lock_above: Some(80),
            ..p
        };
        for _ in 0..3 {
            locked.insert_scan(&hit, &lp).unwrap();
        }
        locked.insert_scan(&pass, &lp).unwrap();
        assert_eq!(locked.get(Cell { x: 2, y: 0 }), Some(100));
    }

    fn east(range_m: Option<f64>) -> RangeScan {
        scan_at(
            0.5,
            0.5,
            vec![Beam {
                angle_rad: 0.0,
                range_m,
            }],
        )
    }

    #[test]
    fn an_obstacle_seen_once_survives_beams_without_a_return() {
        let p = InsertParams::default();
        let mut g = OccupancyGrid::new(spec(8, 1, 1.0)).unwrap();
        g.insert_scan(&east(Some(3.0)), &p).unwrap();
        for _ in 0..20 {
            g.insert_scan(&east(None), &p).unwrap();
        }
        // Still occupied, and nothing behind it is taken as seen.
        assert_eq!(row(&g, 0), vec![0, 0, 0, 40, -1, -1, -1, -1]);
        // Clearing whole rays, one dropped reading erases it and "sees" behind it.
        let clear_all = InsertParams {
            no_return_stops_at: None,
            ..p
        };
        let mut g = OccupancyGrid::new(spec(8, 1, 1.0)).unwrap();
        g.insert_scan(&east(Some(3.0)), &clear_all).unwrap();
        g.insert_scan(&east(None), &clear_all).unwrap();
        assert_eq!(row(&g, 0), vec![0, 0, 0, 30, 0, -1, -1, -1]);
    }

    #[test]
    fn a_moved_obstacle_is_cleared_by_returns_from_beyond_it() {
        let p = InsertParams::default();
        let mut g = OccupancyGrid::new(spec(8, 1, 1.0)).unwrap();
        for _ in 0..3 {
            g.insert_scan(&east(Some(2.0)), &p).unwrap();
        }
        assert_eq!(g.get(Cell { x: 2, y: 0 }), Some(100));
        // The obstacle is gone: the beam now returns from 3.5 m, through its cell.
        let gone: Vec<i8> = (0..8)
            .map(|_| {
                g.insert_scan(&east(Some(3.5)), &p).unwrap();
                g.get(Cell { x: 2, y: 0 }).unwrap()
            })
            .collect();
        assert_eq!(gone, vec![90, 80, 70, 60, 50, 40, 30, 20]);
        // Free again, it is cleared by a beam without a return, which stops at the far obstacle.
        g.insert_scan(&east(None), &p).unwrap();
        assert_eq!(row(&g, 0), vec![0, 0, 10, 0, 100, -1, -1, -1]);
    }

    #[test]
    fn overlapping_beams_update_a_cell_once_and_hit_wins() {
        let mut g = OccupancyGrid::new(spec(6, 1, 1.0)).unwrap();
        let s = scan_at(
            0.5,
            0.5,
            vec![
                Beam {
                    angle_rad: 0.0,
                    range_m: Some(4.0 - 0.5),
                },
                Beam {
                    angle_rad: 0.0,
                    range_m: Some(2.0),
                },
                Beam {
                    angle_rad: 0.0,
                    range_m: Some(3.0),
                },
            ],
        );
        g.insert_scan(&s, &InsertParams::default()).unwrap();
        // Cells 2 and 3 are hits of one beam and misses of another: hit wins (+40 once);
        // cells 0 and 1 are missed by all three beams but lose 10 only once.
        assert_eq!(row(&g, 0), vec![0, 0, 40, 40, 40, -1]);
    }

    #[test]
    fn rotated_beam_directions_match_sin_cos() {
        let beams: Vec<Beam> = (0..3600)
            .map(|i| Beam {
                angle_rad: -3.0 + f64::from(i) * 0.001_7,
                range_m: None,
            })
            .collect();
        let mut s = scan_at(0.0, 0.0, beams);
        s.yaw_rad = 0.7;
        let mut dirs = BeamDirections::new(&s);
        assert!(dirs.step.is_some());
        for b in &s.beams {
            let d = dirs.next(&s, b);
            assert!(
                (d - s.beam_direction_enu(b)).norm() < 1e-11,
                "{}",
                b.angle_rad
            );
        }
        // Uneven spacing falls back to sin_cos per beam.
        s.beams.truncate(3);
        s.beams[2].angle_rad += 0.5;
        assert!(BeamDirections::new(&s).step.is_none());
    }

    #[test]
    fn invalid_scans_are_typed_errors() {
        let mut g = OccupancyGrid::new(spec(4, 4, 1.0)).unwrap();
        let mut s = scan_at(0.5, 0.5, vec![]);
        s.range_max_m = f64::NAN;
        assert!(matches!(
            g.insert_scan(&s, &InsertParams::default()),
            Err(MapError::InvalidScan(_))
        ));
    }

    #[test]
    fn scan_from_outside_the_grid_only_touches_inside_cells() {
        let mut g = OccupancyGrid::new(spec(4, 1, 1.0)).unwrap();
        let s = RangeScan {
            origin_enu_m: Vector3::new(-2.0, 0.5, 0.0),
            yaw_rad: 0.0,
            range_min_m: 0.0,
            range_max_m: 10.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(4.5),
            }],
        };
        g.insert_scan(&s, &InsertParams::default()).unwrap();
        assert_eq!(row(&g, 0), vec![0, 0, 40, -1]);
    }

    #[test]
    fn json_round_trip_and_validation() {
        let mut g = OccupancyGrid::new(spec(3, 2, 0.5)).unwrap();
        g.set(Cell { x: 1, y: 1 }, 77).unwrap();
        let text = serde_json::to_string(&g).unwrap();
        let back: OccupancyGrid = serde_json::from_str(&text).unwrap();
        assert_eq!(back, g);
        let bad = text.replace("77", "101");
        assert!(serde_json::from_str::<OccupancyGrid>(&bad).is_err());
        assert!(g.set(Cell { x: 3, y: 0 }, 0).is_err());
        assert_eq!(
            OccupancyGrid::from_data(spec(3, 2, 0.5), vec![0; 5]),
            Err(MapError::DataLength {
                expected: 6,
                got: 5
            })
        );
    }

    #[test]
    fn patch_extracts_row_major_region() {
        let data: Vec<i8> = (0..12).collect();
        let g = OccupancyGrid::from_data(spec(4, 3, 1.0), data).unwrap();
        let p = g
            .patch(CellBox {
                min: Cell { x: 1, y: 1 },
                max: Cell { x: 9, y: 2 },
            })
            .unwrap();
        assert_eq!(p.region.max, Cell { x: 3, y: 2 });
        assert_eq!(p.data, vec![5, 6, 7, 9, 10, 11]);
    }
}
