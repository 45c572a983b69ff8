//! What the fleet bus carries, and its checks: every message from a peer is hostile until it
//! decodes within bounds.
//!
//! In: bytes from the bus, or a node's drone states and map regions. Out: [`StateMsg`] (JSON: a
//! node's drones, their state, behavior, mission and exploration claim) and [`MapMsg`] (binary:
//! `KMP1`, a little-endian `u16` header length, a JSON header, then the region's cells
//! zlib-compressed), or a [`WireError`] that says what was wrong. Sizes are bounded before any
//! allocation: a message, its header, its drone list, its cell count, the inflated data.

use crate::mapping::grid::{CellBox, GridSpec};
use crate::types::LinkHealth;
use serde::{Deserialize, Serialize};
use std::io::{Read, Write};

use super::config::valid_name;

/// The wire format's version; a peer on another version is refused with a clear error.
pub const WIRE_VERSION: u32 = 1;
/// Largest state message accepted (bytes).
pub const MAX_STATE_BYTES: usize = 64 * 1024;
/// Most drones one node may announce.
pub const MAX_DRONES_PER_NODE: usize = 32;
/// Largest map message accepted (bytes, compressed).
pub const MAX_MAP_BYTES: usize = 8 * 1024 * 1024;
/// Largest map header accepted (bytes).
const MAX_MAP_HEADER_BYTES: usize = 1024;
const MAP_MAGIC: &[u8; 4] = b"KMP1";
/// Positions beyond this from the origin are refused (m).
const MAX_POSITION_M: f64 = 1.0e6;
/// Speeds beyond this are refused (m/s).
const MAX_SPEED_MPS: f64 = 100.0;
/// Longest behavior or mission word.
const MAX_WORD_LEN: usize = 64;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WireError {
    #[error("{0} bytes, at most {1}")]
    TooLarge(usize, usize),
    #[error("not a fleet-bus message: {0}")]
    Malformed(String),
    #[error("wire version {0}, this Kestrel speaks {WIRE_VERSION}")]
    Version(u32),
    #[error("{field}: {message}")]
    Field { field: String, message: String },
}

fn field(field: impl Into<String>, message: impl Into<String>) -> WireError {
    WireError::Field {
        field: field.into(),
        message: message.into(),
    }
}

/// One drone as its node announces it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DroneState {
    pub id: String,
    /// Where it is, how it moves and where it heads: `null`, all three, until its autopilot has
    /// given a position (nothing is made up; receivers leave such a drone out of separation).
    pub position_enu_m: Option<[f64; 3]>,
    pub velocity_enu_mps: Option<[f64; 3]>,
    pub yaw_rad: Option<f64>,
    /// Airborne and armed.
    pub flying: bool,
    /// Its node's link to its autopilot.
    pub link: LinkHealth,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub battery_pct: Option<f64>,
    /// The motion behavior running, if any.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub behavior: Option<String>,
    /// Where that behavior takes it (ENU m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub goal_enu_m: Option<[f64; 3]>,
    /// Its mission executor's state (`idle`, `running`, `paused`, ...).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mission: Option<String>,
    /// The frontier goal it holds in an exploration (ENU m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub claim_enu_m: Option<[f64; 2]>,
}

/// A node's drones, sent `[fleet] state_rate_hz` times a second.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateMsg {
    pub v: u32,
    pub node: String,
    /// Counts up per message from one node (a restarted node starts again at 0).
    pub seq: u64,
    /// The sender's wall clock when sent (µs since the UNIX epoch): latency measurements only,
    /// never trusted for ordering.
    pub sent_unix_us: u64,
    pub drones: Vec<DroneState>,
}

impl StateMsg {
    pub fn encode(&self) -> Vec<u8> {
        serde_json::to_vec(self).unwrap_or_default()
    }

    pub fn decode(bytes: &[u8]) -> Result<Self, WireError> {
        if bytes.len() > MAX_STATE_BYTES {
            return Err(WireError::TooLarge(bytes.len(), MAX_STATE_BYTES));
        }
        let msg: StateMsg =
            serde_json::from_slice(bytes).map_err(|e| WireError::Malformed(e.to_string()))?;
        msg.check()?;
        Ok(msg)
    }

    fn check(&self) -> Result<(), WireError> {
        if self.v != WIRE_VERSION {
            return Err(WireError::Version(self.v));
        }
        if !valid_name(&self.node) {
            return Err(field("/node", "not a valid node name"));
        }
        if self.drones.len() > MAX_DRONES_PER_NODE {
            return Err(field(
                "/drones",
                format!(
                    "{} drones, at most {MAX_DRONES_PER_NODE}",
                    self.drones.len()
                ),
            ));
        }
        for (i, d) in self.drones.iter().enumerate() {
            d.check()
                .map_err(|(f, m)| field(format!("/drones/{i}/{f}"), m))?;
        }
        Ok(())
    }
}

fn finite_within(v: &[f64], bound: f64) -> bool {
    v.iter().all(|x| x.is_finite() && x.abs() <= bound)
}

impl DroneState {
    /// A drone at rest at `position_enu_m`, its link ok, with nothing else to say (no battery,
    /// behavior, goal, mission or claim): the base other states are built on.
    pub fn at_rest(id: &str, position_enu_m: [f64; 3], flying: bool) -> Self {
        DroneState {
            id: id.into(),
            position_enu_m: Some(position_enu_m),
            velocity_enu_mps: Some([0.0; 3]),
            yaw_rad: Some(0.0),
            flying,
            link: LinkHealth::Ok,
            battery_pct: None,
            behavior: None,
            goal_enu_m: None,
            mission: None,
            claim_enu_m: None,
        }
    }

    fn check(&self) -> Result<(), (&'static str, String)> {
        if !valid_name(&self.id) {
            return Err(("id", "not a valid drone id".into()));
        }
        let known = [
            self.position_enu_m.is_some(),
            self.velocity_enu_mps.is_some(),
            self.yaw_rad.is_some(),
        ];
        if known.iter().any(|k| *k != known[0]) {
            return Err((
                "position_enu_m",
                "position_enu_m, velocity_enu_mps and yaw_rad are all null or all set".into(),
            ));
        }
        if !self
            .position_enu_m
            .is_none_or(|p| finite_within(&p, MAX_POSITION_M))
        {
            return Err((
                "position_enu_m",
                format!("must be finite, within {MAX_POSITION_M} m"),
            ));
        }
        if !self
            .velocity_enu_mps
            .is_none_or(|v| finite_within(&v, MAX_SPEED_MPS))
        {
            return Err((
                "velocity_enu_mps",
                format!("must be finite, within {MAX_SPEED_MPS} m/s"),
            ));
        }
        if !self
            .yaw_rad
            .is_none_or(|y| finite_within(&[y], 4.0 * std::f64::consts::PI))
        {
            return Err(("yaw_rad", "must be finite, within 4 pi rad".into()));
        }
        if let Some(b) = self.battery_pct {
            if !(0.0..=100.0).contains(&b) {
                return Err(("battery_pct", "must be within 0 to 100 %".into()));
            }
        }
        if let Some(g) = &self.goal_enu_m {
            if !finite_within(g, MAX_POSITION_M) {
                return Err((
                    "goal_enu_m",
                    format!("must be finite, within {MAX_POSITION_M} m"),
                ));
            }
        }
        if let Some(c) = &self.claim_enu_m {
            if !finite_within(c, MAX_POSITION_M) {
                return Err((
                    "claim_enu_m",
                    format!("must be finite, within {MAX_POSITION_M} m"),
                ));
            }
        }
        for (name, word) in [("behavior", &self.behavior), ("mission", &self.mission)] {
            if word.as_ref().is_some_and(|w| w.len() > MAX_WORD_LEN) {
                return Err((name, format!("longer than {MAX_WORD_LEN} bytes")));
            }
        }
        Ok(())
    }
}

/// The header of a map message.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MapHeader {
    pub v: u32,
    pub node: String,
    pub drone: String,
    pub seq: u64,
    /// The whole known part of the drone's map (sent periodically), not only what changed.
    pub keyframe: bool,
    /// The grid the region belongs to: every node of a fleet maps on the same `[map]` grid.
    pub grid: GridSpec,
    /// The cells carried, inclusive, in `grid`'s cells.
    pub region: CellBox,
}

/// A region of one drone's map layer.
#[derive(Debug, Clone, PartialEq)]
pub struct MapMsg {
    pub header: MapHeader,
    /// Row-major from `region.min`: -1 unknown, else occupancy 0..=100.
    pub cells: Vec<i8>,
}

impl MapMsg {
    /// The message as bytes: magic, header length, header, compressed cells.
    pub fn encode(&self) -> Vec<u8> {
        let header = serde_json::to_vec(&self.header).unwrap_or_default();
        let Ok(header_len) = u16::try_from(header.len()) else {
            return Vec::new();
        };
        let mut out = Vec::with_capacity(header.len() + self.cells.len() / 8 + 16);
        out.extend_from_slice(MAP_MAGIC);
        out.extend_from_slice(&header_len.to_le_bytes());
        out.extend_from_slice(&header);
        let mut z = flate2::write::ZlibEncoder::new(out, flate2::Compression::fast());
        let raw: Vec<u8> = self.cells.iter().map(|&c| c.to_le_bytes()[0]).collect();
        if z.write_all(&raw).is_err() {
            return Vec::new();
        }
        z.finish().unwrap_or_default()
    }

    /// Decodes and checks a message; `max_cells` bounds the region (the receiver's grid size).
    pub fn decode(bytes: &[u8], max_cells: usize) -> Result<Self, WireError> {
        if bytes.len() > MAX_MAP_BYTES {
            return Err(WireError::TooLarge(bytes.len(), MAX_MAP_BYTES));
        }
        let rest = bytes
            .strip_prefix(MAP_MAGIC)
            .ok_or_else(|| WireError::Malformed("no KMP1 magic".into()))?;
        let (len, rest) = rest
            .split_first_chunk::<2>()
            .ok_or_else(|| WireError::Malformed("cut before the header length".into()))?;
        let len = usize::from(u16::from_le_bytes(*len));
        if len > MAX_MAP_HEADER_BYTES {
            return Err(field(
                "header",
                format!("{len} bytes, at most {MAX_MAP_HEADER_BYTES}"),
            ));
        }
        let (header, compressed) = rest
            .split_at_checked(len)
            .ok_or_else(|| WireError::Malformed("cut inside the header".into()))?;
        let header: MapHeader =
            serde_json::from_slice(header).map_err(|e| WireError::Malformed(e.to_string()))?;
        header.check()?;
        let w = header.region.width_cells() as usize;
        let h = header.region.height_cells() as usize;
        let cells = w.saturating_mul(h);
        if cells > max_cells {
            return Err(field(
                "/region",
                format!("{cells} cells, at most {max_cells}"),
            ));
        }
        let mut raw = Vec::with_capacity(cells);
        flate2::read::ZlibDecoder::new(compressed)
            .take(cells as u64 + 1)
            .read_to_end(&mut raw)
            .map_err(|e| WireError::Malformed(format!("cells do not inflate: {e}")))?;
        if raw.len() != cells {
            return Err(field(
                "cells",
                format!("{} cells for a {w} x {h} region", raw.len()),
            ));
        }
        let cells: Vec<i8> = raw.into_iter().map(|b| i8::from_le_bytes([b])).collect();
        if let Some(bad) = cells.iter().position(|&c| !(-1..=100).contains(&c)) {
            return Err(field(
                "cells",
                format!(
                    "cell {bad} is {}, not -1 or 0..=100",
                    cells.get(bad).copied().unwrap_or(0)
                ),
            ));
        }
        Ok(MapMsg { header, cells })
    }
}

impl MapHeader {
    fn check(&self) -> Result<(), WireError> {
        if self.v != WIRE_VERSION {
            return Err(WireError::Version(self.v));
        }
        if !valid_name(&self.node) {
            return Err(field("/node", "not a valid node name"));
        }
        if !valid_name(&self.drone) {
            return Err(field("/drone", "not a valid drone id"));
        }
        self.grid
            .validate()
            .map_err(|e| field("/grid", e.to_string()))?;
        let full = self.grid.full_box();
        let r = self.region;
        if r.min.x > r.max.x || r.min.y > r.max.y || r.max.x > full.max.x || r.max.y > full.max.y {
            return Err(field("/region", "not a box inside the grid"));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::mapping::grid::Cell;
    use nalgebra::Vector2;

    fn state() -> StateMsg {
        StateMsg {
            v: WIRE_VERSION,
            node: "pi-1".into(),
            seq: 7,
            sent_unix_us: 1,
            drones: vec![DroneState {
                id: "drone_1".into(),
                position_enu_m: Some([1.0, 2.0, 1.0]),
                velocity_enu_mps: Some([0.5, 0.0, 0.0]),
                yaw_rad: Some(0.3),
                flying: true,
                link: LinkHealth::Ok,
                battery_pct: Some(80.0),
                behavior: Some("follow_path".into()),
                goal_enu_m: Some([4.0, 2.0, 1.0]),
                mission: Some("running".into()),
                claim_enu_m: Some([4.0, 2.0]),
            }],
        }
    }

    fn grid() -> GridSpec {
        GridSpec {
            resolution_m: 0.1,
            width_cells: 120,
            height_cells: 120,
            origin_enu_m: Vector2::new(-6.0, -6.0),
        }
    }

    fn map(region: CellBox, cells: Vec<i8>) -> MapMsg {
        MapMsg {
            header: MapHeader {
                v: WIRE_VERSION,
                node: "pi-1".into(),
                drone: "drone_1".into(),
                seq: 3,
                keyframe: false,
                grid: grid(),
                region,
            },
            cells,
        }
    }

    fn cells(w: u32, h: u32) -> CellBox {
        CellBox {
            min: Cell { x: 10, y: 20 },
            max: Cell {
                x: 10 + w - 1,
                y: 20 + h - 1,
            },
        }
    }

    #[test]
    fn states_round_trip_and_bad_ones_name_the_field() {
        let s = state();
        assert_eq!(StateMsg::decode(&s.encode()).unwrap(), s);
        let mut nan = state();
        nan.drones[0].position_enu_m = Some([0.0, f64::NAN, 1.0]);
        // NaN serializes as null, which is not a number.
        assert!(StateMsg::decode(&nan.encode()).is_err());
        let mut far = state();
        far.drones[0].velocity_enu_mps = Some([1e3, 0.0, 0.0]);
        let err = StateMsg::decode(&far.encode()).unwrap_err();
        assert!(
            err.to_string().contains("/drones/0/velocity_enu_mps"),
            "{err}"
        );
        let mut unplaced = state();
        let d = &mut unplaced.drones[0];
        (d.position_enu_m, d.velocity_enu_mps, d.yaw_rad) = (None, None, None);
        assert_eq!(StateMsg::decode(&unplaced.encode()).unwrap(), unplaced);
        let mut half = state();
        half.drones[0].yaw_rad = None;
        assert!(StateMsg::decode(&half.encode())
            .unwrap_err()
            .to_string()
            .contains("all null or all set"));
        let mut sneaky = state();
        sneaky.drones[0].id = "x/../y".into();
        assert!(StateMsg::decode(&sneaky.encode())
            .unwrap_err()
            .to_string()
            .contains("/drones/0/id"));
        let mut future = state();
        future.v = 2;
        assert_eq!(
            StateMsg::decode(&future.encode()),
            Err(WireError::Version(2))
        );
        let huge = vec![b' '; MAX_STATE_BYTES + 1];
        assert!(matches!(
            StateMsg::decode(&huge),
            Err(WireError::TooLarge(..))
        ));
    }

    #[test]
    fn map_regions_round_trip_compressed() {
        let mut data = vec![-1i8; 40 * 30];
        data[5] = 100;
        data[100] = 0;
        let m = map(cells(40, 30), data);
        let bytes = m.encode();
        assert!(
            bytes.len() < 300,
            "{} bytes for 1200 mostly unknown cells",
            bytes.len()
        );
        assert_eq!(MapMsg::decode(&bytes, grid().cell_count()).unwrap(), m);
    }

    #[test]
    fn map_messages_are_bounded_before_inflating() {
        // A region bigger than the receiver's grid is refused before any cell is inflated.
        let m = map(cells(40, 30), vec![0; 1200]);
        assert!(MapMsg::decode(&m.encode(), 1000)
            .unwrap_err()
            .to_string()
            .contains("/region"));
        // More cells than the region holds (a zip bomb) stops at the region's size.
        let mut lying = map(cells(2, 2), vec![0; 4]);
        lying.cells = vec![0; 1 << 20];
        let err = MapMsg::decode(&lying.encode(), grid().cell_count()).unwrap_err();
        assert!(
            err.to_string().contains("5 cells for a 2 x 2 region"),
            "{err}"
        );
        // Out-of-range values, a region outside the grid, truncation, garbage.
        let bad = map(cells(2, 1), vec![0, 101]);
        assert!(MapMsg::decode(&bad.encode(), 10_000).is_err());
        let outside = map(
            CellBox {
                min: Cell { x: 119, y: 0 },
                max: Cell { x: 120, y: 0 },
            },
            vec![0, 0],
        );
        assert!(MapMsg::decode(&outside.encode(), 10_000)
            .unwrap_err()
            .to_string()
            .contains("/region"));
        let good = map(cells(2, 2), vec![0; 4]).encode();
        for cut in [0, 3, 5, 20, good.len() - 1] {
            assert!(
                MapMsg::decode(&good[..cut], 10_000).is_err(),
                "cut at {cut}"
            );
        }
    }
}
