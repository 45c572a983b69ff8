//! The flight log as MCAP: the JSON-lines records turned into Foxglove's channels as they come.
//!
//! In: the bytes `FlightLog` writes (one JSON record a line), through [`Write`], or one record
//! at a time ([`McapLog::record`], for `kestrel log convert`). Out: an MCAP file with
//! - `/kestrel/records`: every record unchanged (schema `kestrel.FlightLogRecord`), so nothing
//!   of the JSON-lines log is lost and the readers of both formats see the same records;
//! - the Foxglove channels `foxglove::derive` makes of them (`/tf`, `/<drone>/pose`,
//!   `/events`, `/<drone>/plan`), JSON-encoded with JSON schemas;
//! - `/world`: the obstacles of the header's world (a simulated run's), once after the header,
//!   when the world file loads (its path as the header gives it, tried from each of
//!   [`McapLog::world_dirs`]'s directories);
//! - `/map/known`: with that world, the area known at the end (`grid`, one `foxglove.Grid`
//!   written when the log is finished; a killed process leaves none);
//! - `/<drone>/map` and `/map`: each drone's own map and the merged map, a `foxglove.Grid`
//!   after each of their `map` records (`grids`: whole, at the map rate within a byte budget);
//! - `/frontiers` and `/<drone>/frontier`: `foxglove.SceneUpdate`s of each `frontiers` record
//!   (`scene::FrontierScenes`).
//!
//! Message times are the run's wall-clock start (the header's `start_time`) plus the record's
//! `t`. The file is chunked without compression (the mcap crate is built without zstd and lz4);
//! [`Write::flush`] closes the chunk being written and flushes the file, so a process killed
//! later leaves a file readable up to that flush. [`McapLog::finish`] (or dropping it) writes
//! the summary and footer.

use super::files;
use super::foxglove::{self, Schema};
use super::grids::Grids;
use super::{grid, map_record, scene};
use crate::exploration::offline::evaluate::PoseSample;
use crate::sim::world::World;
use mcap::records::MessageHeader;
use mcap::{WriteOptions, Writer};
use serde_json::Value;
use std::collections::{BTreeMap, HashMap};
use std::io::{self, Seek, Write};
use std::path::{Path, PathBuf};

/// Topic of the unchanged flight-log records.
pub const RECORDS_TOPIC: &str = "/kestrel/records";
/// Schema name of the records channel.
pub const RECORDS_SCHEMA: &str = "kestrel.FlightLogRecord";
/// Chunk size (bytes) at which a chunk is closed even without a flush.
const CHUNK_BYTES: u64 = 256 * 1024;

#[derive(Debug, thiserror::Error)]
pub enum McapLogError {
    #[error("writing MCAP: {0}")]
    Mcap(#[from] mcap::McapError),
    #[error("writing MCAP: {0}")]
    Io(#[from] io::Error),
}

impl From<McapLogError> for io::Error {
    fn from(e: McapLogError) -> Self {
        match e {
            McapLogError::Io(e) => e,
            McapLogError::Mcap(e) => io::Error::other(e),
        }
    }
}

pub struct McapLog<W: Write + Seek> {
    writer: Writer<W>,
    /// Bytes of a record not yet ended by its newline.
    pending: Vec<u8>,
    channels: HashMap<String, u16>,
    schemas: HashMap<&'static str, u16>,
    /// The run's start (ns since 1970, UTC), from the header; 0 until then.
    start_ns: u64,
    /// Time of the last record with a `t`, for records without one.
    last_ns: u64,
    sequence: u32,
    /// Where a relative world path of the header is looked for, in order.
    world_dirs: Vec<PathBuf>,
    /// The header's world, once loaded, and the poses flown in it (for the known map).
    world: Option<World>,
    samples: Vec<PoseSample>,
    /// Copies of the maps of the `map` records.
    grids: Grids,
    frontiers: scene::FrontierScenes,
    /// `map` records that could not be read (the first is logged).
    bad_maps: u64,
    finished: bool,
}

impl<W: Write + Seek> McapLog<W> {
    /// Starts an MCAP file on `out` (its magic and header are written at once).
    pub fn new(out: W) -> Result<Self, McapLogError> {
        let writer = WriteOptions::new()
            .compression(None)
            .chunk_size(Some(CHUNK_BYTES))
            .library(concat!("kestrel ", env!("CARGO_PKG_VERSION")))
            .create(out)?;
        Ok(Self {
            writer,
            pending: Vec::new(),
            channels: HashMap::new(),
            schemas: HashMap::new(),
            start_ns: 0,
            last_ns: 0,
            sequence: 0,
            world_dirs: vec![PathBuf::new()],
            world: None,
            samples: Vec::new(),
            grids: Grids::default(),
            frontiers: scene::FrontierScenes::default(),
            bad_maps: 0,
            finished: false,
        })
    }

    /// Looks for the header's world (when its path is relative) in `dirs`, in order, instead
    /// of the working directory.
    pub fn world_dirs(mut self, dirs: Vec<PathBuf>) -> Self {
        self.world_dirs = dirs;
        self
    }

    /// One record: a line of the JSON-lines log without its newline. A line that is not JSON
    /// still goes to the records channel as it is (stamped with the last time).
    pub fn record(&mut self, line: &[u8]) -> Result<(), McapLogError> {
        let value: Option<Value> = serde_json::from_slice(line).ok();
        if let Some(v) = &value {
            self.stamp(v);
        }
        let records = self.channel(RECORDS_TOPIC, None)?;
        self.write(records, line)?;
        let Some(value) = value else {
            return Ok(());
        };
        for derived in foxglove::derive(&value, self.last_ns) {
            self.derived(&derived.topic, derived.schema, &derived.message)?;
        }
        match value.get("type").and_then(Value::as_str) {
            Some("header") => {
                self.world = self.world_of(&value);
                if let Some(world) = &self.world {
                    let update = scene::world(world, &self.stamp_json());
                    self.derived("/world", Schema::SceneUpdate, &update)?;
                }
            }
            Some("map") => self.map(&value)?,
            Some("frontiers") => {
                for (topic, update) in self.frontiers.update(&value, &self.stamp_json()) {
                    self.derived(&topic, Schema::SceneUpdate, &update)?;
                }
            }
            _ => {}
        }
        if self.world.is_some() {
            self.samples.extend(grid::sample(&value));
        }
        Ok(())
    }

    /// A `map` record into its map's copy, and the map's grid when one is due.
    fn map(&mut self, record: &Value) -> Result<(), McapLogError> {
        match map_record::decode(record) {
            Ok(update) => {
                if let Some(m) = self.grids.update(update, self.last_ns) {
                    self.derived(&m.topic, Schema::Grid, &m.message)?;
                }
            }
            Err(e) => {
                self.bad_maps += 1;
                if self.bad_maps == 1 {
                    tracing::warn!("flight log: {e} (kept on {RECORDS_TOPIC}, drawn nowhere)");
                }
            }
        }
        Ok(())
    }

    /// The last record's time as Foxglove's `{sec, nsec}`.
    fn stamp_json(&self) -> Value {
        serde_json::json!({
            "sec": self.last_ns / 1_000_000_000, "nsec": self.last_ns % 1_000_000_000,
        })
    }

    fn derived(
        &mut self,
        topic: &str,
        schema: Schema,
        message: &Value,
    ) -> Result<(), McapLogError> {
        let channel = self.channel(topic, Some(schema))?;
        let data = serde_json::to_vec(message).map_err(io::Error::other)?;
        self.write(channel, &data)
    }

    /// The header's world, if it names one that loads.
    fn world_of(&self, header: &Value) -> Option<World> {
        let path = Path::new(header.get("world")?.as_str()?);
        if path.is_absolute() {
            return World::load(path).ok();
        }
        self.world_dirs
            .iter()
            .find_map(|dir| World::load(&dir.join(path)).ok())
    }

    /// Writes what is left (a last record without its newline), the known map, the summary
    /// and the footer. Dropping the log does the same, without the errors.
    pub fn finish(mut self) -> Result<(), McapLogError> {
        self.close()
    }

    fn close(&mut self) -> Result<(), McapLogError> {
        if std::mem::replace(&mut self.finished, true) {
            return Ok(());
        }
        self.end_pending()?;
        for m in self.grids.finish(self.last_ns) {
            self.derived(&m.topic, Schema::Grid, &m.message)?;
        }
        if let Some(world) = self.world.take() {
            let stamp = self.stamp_json();
            if let Some(known) = grid::known(&world, &self.samples, &stamp) {
                self.derived("/map/known", Schema::Grid, &known)?;
            }
        }
        self.writer.finish()?;
        Ok(())
    }

    fn end_pending(&mut self) -> Result<(), McapLogError> {
        let rest = std::mem::take(&mut self.pending);
        if rest.iter().any(|b| !b.is_ascii_whitespace()) {
            self.record(rest.trim_ascii())?;
        }
        Ok(())
    }

    fn stamp(&mut self, record: &Value) {
        if record.get("type").and_then(Value::as_str) == Some("header") {
            if let Some(s) = record
                .get("start_time")
                .and_then(Value::as_str)
                .and_then(files::parse_rfc3339)
            {
                self.start_ns = s.saturating_mul(1_000_000_000);
            }
        }
        if let Some(t) = record.get("t").and_then(Value::as_f64) {
            if t.is_finite() && t >= 0.0 {
                self.last_ns = self.start_ns.saturating_add((t * 1e9) as u64);
            }
        }
    }

    /// The channel of `topic` (added on first use); `None` is the records channel's schema.
    fn channel(&mut self, topic: &str, schema: Option<Schema>) -> Result<u16, McapLogError> {
        if let Some(&id) = self.channels.get(topic) {
            return Ok(id);
        }
        let (name, data) = match schema {
            Some(s) => (s.name(), s.json_schema()),
            None => (RECORDS_SCHEMA, records_schema()),
        };
        let schema_id = match self.schemas.get(name) {
            Some(&id) => id,
            None => {
                let bytes = serde_json::to_vec(&data).map_err(io::Error::other)?;
                let id = self.writer.add_schema(name, "jsonschema", &bytes)?;
                self.schemas.insert(name, id);
                id
            }
        };
        let id = self
            .writer
            .add_channel(schema_id, topic, "json", &BTreeMap::new())?;
        self.channels.insert(topic.to_string(), id);
        Ok(id)
    }

    fn write(&mut self, channel_id: u16, data: &[u8]) -> Result<(), McapLogError> {
        self.sequence = self.sequence.wrapping_add(1);
        let header = MessageHeader {
            channel_id,
            sequence: self.sequence,
            log_time: self.last_ns,
            publish_time: self.last_ns,
        };
        self.writer.write_to_known_channel(&header, data)?;
        Ok(())
    }
}

/// The records channel's schema: any flight-log record (the module doc of `flightlog`).
fn records_schema() -> Value {
    serde_json::json!({
        "title": RECORDS_SCHEMA,
        "description": "One Kestrel flight-log record, as in the JSON-lines log",
        "type": "object",
        "required": ["t", "drone", "type"],
        "properties": {
            "t": { "type": "number", "description": "s since the start of the run" },
            "drone": { "type": ["string", "null"] },
            "type": { "type": "string" },
        },
    })
}

impl<W: Write + Seek> Drop for McapLog<W> {
    fn drop(&mut self) {
        if let Err(e) = self.close() {
            tracing::error!("flight log: {e}");
        }
    }
}

impl<W: Write + Seek> Write for McapLog<W> {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.pending.extend_from_slice(buf);
        let mut start = 0;
        while let Some(end) = self.pending[start..].iter().position(|&b| b == b'\n') {
            let line = self.pending[start..start + end].to_vec();
            start += end + 1;
            if !line.trim_ascii().is_empty() {
                self.record(&line)?;
            }
        }
        self.pending.drain(..start);
        Ok(buf.len())
    }

    /// Closes the chunk being written and flushes the file: readable up to here.
    fn flush(&mut self) -> io::Result<()> {
        self.writer.flush().map_err(io::Error::other)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::flightlog::reader;
    use std::io::Cursor;

    const LINES: &str = concat!(
        r#"{"t":0.0,"drone":null,"type":"header","start_time":"2026-01-02T03:04:05Z"}"#,
        "\n",
        r#"{"t":0.5,"drone":"drone_0","type":"pose","x":1.0,"y":2.0,"z":3.0,"yaw":0.0}"#,
        "\n",
        r#"{"t":0.6,"drone":"drone_0","type":"safety","reason":"geofence"}"#,
        "\n",
    );

    /// The file written from [`LINES`]: finished, or only flushed (as a killed process leaves it).
    fn written(finish: bool) -> Vec<u8> {
        let dir = tempfile::tempdir().expect("tempdir");
        let path = dir.path().join("flight.mcap");
        let file = std::fs::File::create(&path).expect("create");
        let mut log = McapLog::new(io::BufWriter::new(file)).expect("new");
        log.write_all(LINES.as_bytes()).expect("write");
        if finish {
            log.finish().expect("finish");
        } else {
            log.flush().expect("flush");
        }
        std::fs::read(&path).expect("read")
    }

    #[test]
    fn the_records_come_back_unchanged_with_their_times() {
        let mut log = McapLog::new(Cursor::new(Vec::new())).expect("new");
        log.write_all(LINES.as_bytes()).expect("write");
        log.end_pending().expect("end");
        assert_eq!(log.start_ns, 1_767_323_045_000_000_000);
        assert_eq!(log.last_ns, log.start_ns + 600_000_000);
        let bytes = written(true);
        let back = reader::records_from_mcap(&bytes);
        assert_eq!(back.lines, LINES.as_bytes());
        assert!(!back.cut_short);
    }

    #[test]
    fn a_file_without_its_summary_is_read_up_to_its_last_flush() {
        let bytes = written(false);
        let back = reader::records_from_mcap(&bytes);
        assert_eq!(back.lines, LINES.as_bytes());
        assert!(back.cut_short);
        // Cut in the message indexes after the chunk: the chunk is whole.
        let cut = reader::records_from_mcap(&bytes[..bytes.len() - 10]);
        assert_eq!(cut.lines, LINES.as_bytes());
        // Cut in the chunk (uncompressed): the whole records before the cut.
        let cut = reader::records_from_mcap(&bytes[..bytes.len() / 2]);
        assert!(cut.cut_short);
        assert!(LINES.as_bytes().starts_with(&cut.lines));
        assert!(
            cut.lines.ends_with(b"\n"),
            "{}",
            String::from_utf8_lossy(&cut.lines)
        );
    }
}
