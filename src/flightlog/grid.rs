//! The `foxglove.Grid` of a flight log with a world: the area known at its end, as the
//! exploration evaluator sees it.
//!
//! In: the log's pose records and the header's true world. Out: one `foxglove.Grid` message (a
//! `known` UINT8 field, 100 known and 0 unknown; 0.1 m cells over the world's bounds, rows from
//! the south-west corner, in `world`), the merged known map of `exploration::offline::evaluate` (four
//! 4 m beams cast at the true obstacles from every airborne pose): the same map as the report's
//! `explored` figure. The log records neither the drones' own occupancy grids nor the map
//! updates, so this is the only grid, written once when the log closes.

use crate::exploration::offline::evaluate::{self, EvalParams, PoseSample};
use crate::sim::world::World;
use base64::Engine;
use serde_json::{json, Value};

/// The pose of `record` as the evaluator takes it, if it is a pose record.
pub fn sample(record: &Value) -> Option<PoseSample> {
    let num = |k: &str| record.get(k).and_then(Value::as_f64);
    (record.get("type")?.as_str()? == "pose").then_some(())?;
    Some(PoseSample {
        t_s: num("t")?,
        drone: record.get("drone")?.as_str()?.to_string(),
        x_m: num("x")?,
        y_m: num("y")?,
        z_m: num("z")?,
        yaw_rad: num("yaw").unwrap_or(0.0),
        crashed: record.get("flight").and_then(Value::as_str) == Some("crashed"),
    })
}

/// The known map of `samples` in `world` as a `foxglove.Grid` stamped `stamp`; `None` when the
/// evaluator refuses them (no airborne pose, a world too large).
pub fn known(world: &World, samples: &[PoseSample], stamp: &Value) -> Option<Value> {
    let (_, map) = evaluate::evaluate_with_map(world, samples, &EvalParams::default()).ok()?;
    let cells: Vec<u8> = map.known.iter().map(|&k| if k { 100 } else { 0 }).collect();
    Some(json!({
        "timestamp": stamp,
        "frame_id": super::foxglove::WORLD_FRAME,
        "pose": {
            "position": { "x": map.min_x_m, "y": map.min_y_m, "z": 0.0 },
            "orientation": { "x": 0.0, "y": 0.0, "z": 0.0, "w": 1.0 },
        },
        "column_count": map.nx,
        "cell_size": { "x": map.cell_m, "y": map.cell_m },
        "row_stride": map.nx,
        "cell_stride": 1,
        "fields": [{ "name": "known", "offset": 0, "type": 1 }],
        "data": base64::engine::general_purpose::STANDARD.encode(cells),
    }))
}
