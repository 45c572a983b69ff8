//! `map` records of the flight log: the cells of an occupancy grid that changed, and reading
//! them back.
//!
//! In: a grid (a drone's own map, or the fleet's merged map) and the box of its cells that
//! changed, or a band of rows of it. Out: one record per band, each at most [`MAX_BAND_CELLS`]
//! cells (so a record stays far below the readers' 1 MiB line limit; the host makes smaller
//! bands, a few a tick):
//! `{"t", "drone", "type": "map", "map": "own" | "merged", "grid": GridSpec, "region":
//! [x, y, width, height] (cells), "cells": base64 of the zlib-compressed cells, row-major from
//! the region's south-west cell, -1 unknown, else 0..=100}`, and `"more": true` on every band
//! of one update but its last. `drone` is the drone whose map it is, null for the merged map.
//! The first update of a map carries every known cell of it; later ones the cells changed since.
//! [`decode`] reads a record back, refusing (with what and why) one that does not fit its grid.

use crate::mapping::grid::{CellBox, GridSpec, OccupancyGrid};
use base64::Engine;
use flate2::read::ZlibDecoder;
use flate2::write::ZlibEncoder;
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::time::Duration;

/// Most cells in one record (256 Ki: a 512 x 512 region).
pub const MAX_BAND_CELLS: u32 = 1 << 18;

/// Which map a record belongs to.
#[derive(Debug, Clone, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum MapKey {
    /// A drone's own map, the one it plans on.
    Own(String),
    /// The fleet's merged map.
    Merged,
}

/// One `map` record, read back.
#[derive(Debug, Clone, PartialEq)]
pub struct MapUpdate {
    pub key: MapKey,
    /// The whole grid's geometry.
    pub grid: GridSpec,
    pub region: CellBox,
    /// Row-major from `region.min`.
    pub cells: Vec<i8>,
    /// More bands of the same update follow.
    pub more: bool,
}

/// Why a `map` record could not be read.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum MapRecordError {
    #[error("map record: field `{0}` is missing or malformed")]
    Field(&'static str),
    #[error("map record: `grid` is not a valid grid: {0}")]
    Grid(String),
    #[error(
        "map record: region {0:?} is empty, leaves the grid or exceeds {MAX_BAND_CELLS} cells"
    )]
    Region([u64; 4]),
    #[error("map record: `cells` holds {got} cells, the region {expected}")]
    Cells { expected: usize, got: usize },
    #[error("map record: a cell value {0} outside -1..=100")]
    Value(i8),
}

/// The `map` records of the cells of `grid` in `region` (clipped to the grid), at `t`;
/// `drone` is `None` for the merged map.
pub fn records(
    t: Duration,
    drone: Option<&str>,
    grid: &OccupancyGrid,
    region: CellBox,
) -> Vec<Value> {
    let Some(region) = region.intersect(grid.spec().full_box()) else {
        return Vec::new();
    };
    let rows_per_band = (MAX_BAND_CELLS / region.width_cells().max(1)).max(1);
    let mut out = Vec::new();
    let mut y = region.min.y;
    loop {
        let last = y.saturating_add(rows_per_band - 1).min(region.max.y);
        let mut band = region;
        band.min.y = y;
        band.max.y = last;
        out.extend(record(t, drone, grid, band, last < region.max.y));
        match last.checked_add(1) {
            Some(next) if next <= region.max.y => y = next,
            _ => break,
        }
    }
    out
}

/// One `map` record: the cells of `grid` in `band` (clipped to the grid), with `"more": true`
/// when `more` bands of the update follow; `None` when the band misses the grid or holds more
/// than [`MAX_BAND_CELLS`] cells (a record readers would refuse).
pub fn record(
    t: Duration,
    drone: Option<&str>,
    grid: &OccupancyGrid,
    band: CellBox,
    more: bool,
) -> Option<Value> {
    let patch = grid.patch(band)?;
    let region = patch.region;
    if u64::from(region.width_cells()) * u64::from(region.height_cells())
        > u64::from(MAX_BAND_CELLS)
    {
        return None;
    }
    let mut record = json!({
        "t": t.as_secs_f64(), "drone": drone, "type": "map",
        "map": if drone.is_some() { "own" } else { "merged" },
        "grid": grid.spec(),
        "region": [region.min.x, region.min.y, region.width_cells(), region.height_cells()],
        "cells": compress(&patch.data),
    });
    if more {
        record["more"] = Value::Bool(true);
    }
    Some(record)
}

/// The box of the known cells of `grid` (`None`: none known).
pub fn known_box(grid: &OccupancyGrid) -> Option<CellBox> {
    let spec = grid.spec();
    let mut known: Option<CellBox> = None;
    for (i, _) in grid.data().iter().enumerate().filter(|(_, &v)| v >= 0) {
        if let Some(c) = spec.cell_of_index(i) {
            match known.as_mut() {
                Some(b) => b.include(c),
                None => known = Some(CellBox::of_cell(c)),
            }
        }
    }
    known
}

fn compress(cells: &[i8]) -> String {
    let bytes: Vec<u8> = cells.iter().map(|&v| v as u8).collect();
    let mut z = ZlibEncoder::new(Vec::new(), flate2::Compression::fast());
    // Writing into a Vec cannot fail.
    let zipped = z
        .write_all(&bytes)
        .and_then(|()| z.finish())
        .unwrap_or_default();
    base64::engine::general_purpose::STANDARD.encode(zipped)
}

/// Reads a `map` record (see the module doc).
pub fn decode(record: &Value) -> Result<MapUpdate, MapRecordError> {
    let key = match record.get("map").and_then(Value::as_str) {
        Some("merged") => MapKey::Merged,
        Some("own") => MapKey::Own(
            record
                .get("drone")
                .and_then(Value::as_str)
                .ok_or(MapRecordError::Field("drone"))?
                .to_string(),
        ),
        _ => return Err(MapRecordError::Field("map")),
    };
    let grid: GridSpec = record
        .get("grid")
        .cloned()
        .and_then(|g| serde_json::from_value(g).ok())
        .ok_or(MapRecordError::Field("grid"))?;
    grid.validate()
        .map_err(|e| MapRecordError::Grid(e.to_string()))?;
    let region = region_of(record, &grid)?;
    let expected = (region.width_cells() * region.height_cells()) as usize;
    let text = record
        .get("cells")
        .and_then(Value::as_str)
        .ok_or(MapRecordError::Field("cells"))?;
    let zipped = base64::engine::general_purpose::STANDARD
        .decode(text)
        .map_err(|_| MapRecordError::Field("cells"))?;
    let mut bytes = Vec::with_capacity(expected);
    // One byte more than the region holds tells a record with too many cells.
    ZlibDecoder::new(zipped.as_slice())
        .take(expected as u64 + 1)
        .read_to_end(&mut bytes)
        .map_err(|_| MapRecordError::Field("cells"))?;
    if bytes.len() != expected {
        return Err(MapRecordError::Cells {
            expected,
            got: bytes.len(),
        });
    }
    let cells: Vec<i8> = bytes.into_iter().map(|b| b as i8).collect();
    if let Some(&v) = cells.iter().find(|&&v| !(-1..=100).contains(&v)) {
        return Err(MapRecordError::Value(v));
    }
    Ok(MapUpdate {
        key,
        grid,
        region,
        cells,
        more: record.get("more").and_then(Value::as_bool).unwrap_or(false),
    })
}

fn region_of(record: &Value, grid: &GridSpec) -> Result<CellBox, MapRecordError> {
    let a = record
        .get("region")
        .and_then(Value::as_array)
        .filter(|a| a.len() == 4)
        .ok_or(MapRecordError::Field("region"))?;
    let mut r = [0u64; 4];
    for (slot, v) in r.iter_mut().zip(a) {
        *slot = v.as_u64().ok_or(MapRecordError::Field("region"))?;
    }
    let [x, y, w, h] = r;
    let fits = w > 0
        && h > 0
        && w * h <= u64::from(MAX_BAND_CELLS)
        && x + w <= u64::from(grid.width_cells)
        && y + h <= u64::from(grid.height_cells);
    if !fits {
        return Err(MapRecordError::Region(r));
    }
    let cell = |x: u64, y: u64| crate::mapping::grid::Cell {
        x: x as u32,
        y: y as u32,
    };
    Ok(CellBox {
        min: cell(x, y),
        max: cell(x + w - 1, y + h - 1),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::Cell;
    use nalgebra::Vector2;

    fn grid(width: u32, height: u32) -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: width,
            height_cells: height,
            origin_enu_m: Vector2::new(-2.0, 3.0),
        };
        let data = (0..width * height).map(|i| (i % 102) as i8 - 1).collect();
        OccupancyGrid::from_data(spec, data).unwrap()
    }

    fn cells(x0: u32, y0: u32, x1: u32, y1: u32) -> CellBox {
        CellBox {
            min: Cell { x: x0, y: y0 },
            max: Cell { x: x1, y: y1 },
        }
    }

    #[test]
    fn a_region_comes_back_cell_for_cell() {
        let g = grid(30, 20);
        let region = cells(3, 4, 12, 18);
        let out = records(Duration::from_millis(2500), Some("drone_1"), &g, region);
        assert_eq!(out.len(), 1);
        assert_eq!(out[0]["t"], 2.5);
        assert_eq!(out[0]["region"], json!([3, 4, 10, 15]));
        let back = decode(&out[0]).unwrap();
        assert_eq!(back.key, MapKey::Own("drone_1".into()));
        assert_eq!(back.grid, *g.spec());
        assert_eq!(back.region, region);
        assert_eq!(back.cells, g.patch(region).unwrap().data);
        assert!(!back.more);
        let merged = records(Duration::ZERO, None, &g, region);
        assert_eq!(decode(&merged[0]).unwrap().key, MapKey::Merged);
        assert_eq!(merged[0]["drone"], Value::Null);
    }

    /// A region wider than a record holds is cut in bands of rows; all but the last say more
    /// follow, and together they hold the region.
    #[test]
    fn a_large_region_is_cut_in_bands() {
        let g = grid(1024, 700);
        let out = records(Duration::ZERO, None, &g, g.spec().full_box());
        assert_eq!(out.len(), 3, "256 rows of 1024 cells a record");
        let mut copy = OccupancyGrid::new(*g.spec()).unwrap();
        for (i, r) in out.iter().enumerate() {
            let u = decode(r).unwrap();
            assert_eq!(u.more, i < 2);
            assert!(u.cells.len() <= MAX_BAND_CELLS as usize);
            let patch = crate::mapping::grid::GridPatch {
                region: u.region,
                data: u.cells,
            };
            copy.write_patch(&patch).unwrap();
        }
        assert_eq!(copy, g);
        assert!(out.iter().all(|r| r.to_string().len() < 1 << 20));
    }

    #[test]
    fn the_known_box_holds_every_known_cell() {
        let spec = *grid(10, 10).spec();
        let mut g = OccupancyGrid::new(spec).unwrap();
        assert_eq!(known_box(&g), None);
        g.set(Cell { x: 7, y: 2 }, 0).unwrap();
        g.set(Cell { x: 3, y: 5 }, 100).unwrap();
        assert_eq!(known_box(&g), Some(cells(3, 2, 7, 5)));
    }

    /// What does not fit its grid is refused, saying which field.
    #[test]
    fn bad_records_are_refused_naming_the_field() {
        let g = grid(30, 20);
        let good = records(Duration::ZERO, Some("d"), &g, cells(0, 0, 9, 9)).remove(0);
        let with = |k: &str, v: Value| {
            let mut r = good.clone();
            r[k] = v;
            decode(&r).unwrap_err()
        };
        assert_eq!(with("map", json!("other")), MapRecordError::Field("map"));
        assert_eq!(
            with("region", json!([25, 0, 10, 10])),
            MapRecordError::Region([25, 0, 10, 10])
        );
        assert_eq!(
            with("region", json!([0, 0, 5, 5])),
            MapRecordError::Cells {
                expected: 25,
                got: 26
            }
        );
        assert_eq!(
            with("cells", json!("not base64!")),
            MapRecordError::Field("cells")
        );
        assert!(matches!(
            with(
                "grid",
                json!({"resolution_m": 0.0, "width_cells": 1, "height_cells": 1,
                "origin_enu_m": [0.0, 0.0]})
            ),
            MapRecordError::Grid(_)
        ));
        let mut wrong = good.clone();
        wrong["cells"] = json!(compress(&[120; 100]));
        assert_eq!(decode(&wrong).unwrap_err(), MapRecordError::Value(120));
    }
}
