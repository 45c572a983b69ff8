//! The maps of an MCAP flight log as Foxglove draws them: a copy of each grid kept from the
//! `map` records, and a `foxglove.Grid` of it after each update.
//!
//! In: `map` records read back ([`MapUpdate`]) with their time. Out: `foxglove.Grid` messages
//! on `/<drone>/map` (a drone's own map) and `/map` (the merged map): the whole grid as far as
//! it is known (the box of every region updated so far; Foxglove shows the latest message of a
//! topic, so each message is the map, not a change), one INT8 `occupancy` field (-1 unknown,
//! else 0..=100, as a ROS `OccupancyGrid`), rows from the south-west corner, in `world`.
//!
//! One message per update (the records come at the map rate, and only for maps that changed),
//! but no more bytes a second on a topic than [`GRID_BYTES_PER_S`]: a grid too large for that
//! at the map rate is written less often, always whole and current, and the last state of
//! every map is written when the log closes ([`Grids::finish`]).

use super::foxglove::WORLD_FRAME;
use super::map_record::{MapKey, MapUpdate};
use crate::mapping::grid::{CellBox, GridPatch, OccupancyGrid};
use base64::Engine;
use serde_json::{json, Value};
use std::collections::BTreeMap;

/// Most bytes a second of `foxglove.Grid` messages on one topic (measured in BENCHMARKS.md,
/// "MCAP flight logs").
pub const GRID_BYTES_PER_S: f64 = 32_000.0;
/// Most maps kept (a log of more drones' maps keeps the first ones).
const MAX_MAPS: usize = 64;
/// Most cells of all maps kept together (hostile logs given to `kestrel log convert`).
const MAX_CELLS_KEPT: usize = 1 << 27;

/// One grid message: where it goes and its JSON body.
#[derive(Debug, Clone, PartialEq)]
pub struct GridMessage {
    pub topic: String,
    pub message: Value,
}

struct Kept {
    grid: OccupancyGrid,
    /// Every region updated so far.
    known: Option<CellBox>,
    /// Log time (ns) before which no message is written.
    next_ns: u64,
    /// Updated since its last message.
    unwritten: bool,
}

/// The copies of every map of one log.
#[derive(Default)]
pub struct Grids {
    maps: BTreeMap<MapKey, Kept>,
}

/// The topic of a map.
pub fn topic(key: &MapKey) -> String {
    match key {
        MapKey::Own(drone) => format!("/{drone}/map"),
        MapKey::Merged => "/map".into(),
    }
}

impl Grids {
    /// Applies `update` (logged at `now_ns`, ns since 1970); the grid's message when one is due.
    pub fn update(&mut self, update: MapUpdate, now_ns: u64) -> Option<GridMessage> {
        let stale = self
            .maps
            .get(&update.key)
            .is_some_and(|k| *k.grid.spec() != update.grid);
        if stale {
            self.maps.remove(&update.key);
        }
        if !self.maps.contains_key(&update.key) {
            let kept: usize = self.maps.values().map(|k| k.grid.data().len()).sum();
            if self.maps.len() >= MAX_MAPS || kept + update.grid.cell_count() > MAX_CELLS_KEPT {
                return None;
            }
            let grid = OccupancyGrid::new(update.grid).ok()?;
            let kept = Kept {
                grid,
                known: None,
                next_ns: 0,
                unwritten: false,
            };
            self.maps.insert(update.key.clone(), kept);
        }
        let kept = self.maps.get_mut(&update.key)?;
        let patch = GridPatch {
            region: update.region,
            data: update.cells,
        };
        kept.grid.write_patch(&patch).ok()?;
        kept.known = Some(kept.known.map_or(update.region, |k| k.union(update.region)));
        kept.unwritten = true;
        if update.more || now_ns < kept.next_ns {
            return None;
        }
        message(&update.key, kept, now_ns)
    }

    /// The maps updated since their last message, each as it is now (when the log closes).
    pub fn finish(&mut self, now_ns: u64) -> Vec<GridMessage> {
        self.maps
            .iter_mut()
            .filter(|(_, k)| k.unwritten)
            .filter_map(|(key, kept)| message(key, kept, now_ns))
            .collect()
    }
}

fn message(key: &MapKey, kept: &mut Kept, now_ns: u64) -> Option<GridMessage> {
    let body = grid_message(&kept.grid, kept.known?, now_ns)?;
    let bytes = body["data"].as_str().map_or(0, str::len) as f64;
    kept.next_ns = now_ns.saturating_add((bytes / GRID_BYTES_PER_S * 1e9) as u64);
    kept.unwritten = false;
    Some(GridMessage {
        topic: topic(key),
        message: body,
    })
}

/// The cells of `grid` in `region` as a `foxglove.Grid` stamped `stamp_ns`.
pub fn grid_message(grid: &OccupancyGrid, region: CellBox, stamp_ns: u64) -> Option<Value> {
    let patch = grid.patch(region)?;
    let spec = grid.spec();
    let r = spec.resolution_m;
    let bytes: Vec<u8> = patch.data.iter().map(|&v| v as u8).collect();
    Some(json!({
        "timestamp": { "sec": stamp_ns / 1_000_000_000, "nsec": stamp_ns % 1_000_000_000 },
        "frame_id": WORLD_FRAME,
        "pose": {
            "position": {
                "x": spec.origin_enu_m.x + f64::from(patch.region.min.x) * r,
                "y": spec.origin_enu_m.y + f64::from(patch.region.min.y) * r,
                "z": 0.0,
            },
            "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 },
        },
        "column_count": patch.region.width_cells(),
        "cell_size": { "x": r, "y": r },
        "row_stride": patch.region.width_cells(),
        "cell_stride": 1,
        // Foxglove's NumericType INT8.
        "fields": [{ "name": "occupancy", "offset": 0, "type": 2 }],
        "data": base64::engine::general_purpose::STANDARD.encode(bytes),
    }))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::map_record;
    use crate::mapping::grid::{Cell, GridSpec};
    use nalgebra::Vector2;
    use std::time::Duration;

    fn spec(width: u32, height: u32) -> GridSpec {
        GridSpec {
            resolution_m: 0.5,
            width_cells: width,
            height_cells: height,
            origin_enu_m: Vector2::new(-10.0, -5.0),
        }
    }

    fn cells(x0: u32, y0: u32, x1: u32, y1: u32) -> CellBox {
        CellBox {
            min: Cell { x: x0, y: y0 },
            max: Cell { x: x1, y: y1 },
        }
    }

    /// The updates of `grid` in `region` as the log's records carry them.
    fn updates(grid: &OccupancyGrid, region: CellBox) -> Vec<MapUpdate> {
        map_record::records(Duration::ZERO, Some("drone_0"), grid, region)
            .iter()
            .map(|r| map_record::decode(r).unwrap())
            .collect()
    }

    fn data(message: &Value) -> Vec<i8> {
        let text = message["data"].as_str().unwrap();
        let bytes = base64::engine::general_purpose::STANDARD
            .decode(text)
            .unwrap();
        bytes.into_iter().map(|b| b as i8).collect()
    }

    /// Each message is the whole map as far as it is known, placed where its cells are.
    #[test]
    fn a_grid_is_every_region_known_so_far() {
        let mut source = OccupancyGrid::new(spec(40, 30)).unwrap();
        source.set(Cell { x: 2, y: 3 }, 100).unwrap();
        source.set(Cell { x: 5, y: 4 }, 0).unwrap();
        let mut grids = Grids::default();
        let first = updates(&source, cells(2, 3, 5, 4)).remove(0);
        let m = grids.update(first, 1_500_000_000).unwrap();
        assert_eq!(m.topic, "/drone_0/map");
        assert_eq!(
            m.message["timestamp"],
            json!({"sec": 1, "nsec": 500_000_000})
        );
        assert_eq!(
            m.message["pose"]["position"],
            json!({"x": -9.0, "y": -3.5, "z": 0.0})
        );
        assert_eq!(m.message["column_count"], 4);
        assert_eq!(
            data(&m.message),
            source.patch(cells(2, 3, 5, 4)).unwrap().data
        );
        source.set(Cell { x: 30, y: 20 }, 70).unwrap();
        let later = updates(&source, cells(30, 20, 30, 20)).remove(0);
        let m = grids.update(later, 60_000_000_000).unwrap();
        assert_eq!(m.message["column_count"], 29);
        let d = data(&m.message);
        assert_eq!(d.len(), 29 * 18);
        assert_eq!((d[0], d[3 + 29], d[d.len() - 1]), (100, 0, 70));
        assert!(grids.finish(61_000_000_000).is_empty(), "nothing unwritten");
    }

    /// A large grid is written at most as often as the byte budget allows, and as it is at the
    /// end when the log closes.
    #[test]
    fn a_large_grid_keeps_to_its_byte_budget() {
        let source = OccupancyGrid::from_data(spec(400, 300), vec![0; 120_000]).unwrap();
        let mut grids = Grids::default();
        let whole = source.spec().full_box();
        let mut written = 0;
        for tick in 0..20u64 {
            let t_ns = tick * 500_000_000;
            for u in updates(&source, whole) {
                written += usize::from(grids.update(u, t_ns).is_some());
            }
        }
        // 160 000 bytes of base64 a message: one each 5 s of the 10 s.
        assert_eq!(written, 2);
        let end = grids.finish(10_000_000_000);
        assert_eq!(end.len(), 1);
        assert_eq!(data(&end[0].message), source.data());
    }

    /// An update of a map on another grid starts the map again.
    #[test]
    fn a_map_on_a_new_grid_starts_over() {
        let mut a = OccupancyGrid::new(spec(10, 10)).unwrap();
        a.set(Cell { x: 1, y: 1 }, 100).unwrap();
        let mut grids = Grids::default();
        grids.update(updates(&a, cells(1, 1, 1, 1)).remove(0), 0);
        let mut b = OccupancyGrid::new(spec(20, 10)).unwrap();
        b.set(Cell { x: 9, y: 9 }, 0).unwrap();
        let m = grids
            .update(updates(&b, cells(9, 9, 9, 9)).remove(0), 0)
            .unwrap();
        assert_eq!(m.message["column_count"], 1);
        assert_eq!(data(&m.message), [0]);
    }
}
