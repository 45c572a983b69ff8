//! Benchmark (BENCHMARKS.md, "MCAP flight logs"): CPU per record of the two log formats, on
//! the writer thread (`flightlog::writer`; the control thread's part, a record made into a JSON
//! line, is the same for both) and the bytes each format writes per record, for one minute of
//! three drones' pose records at 10 Hz with their events. With `FLIGHT_LOG` set to a JSON-lines
//! flight log (one with `map` records: an exploration), the same for that log, and the cost of
//! its `map` records: on the writer thread (the log written as MCAP with and without them) and
//! on the control thread (each record made again from its grid, `map_record::records`).
//!
//!     cargo bench --bench flight_log
//!     FLIGHT_LOG=explore.jsonl cargo bench --bench flight_log

use kestrel::flightlog::map_record;
use kestrel::flightlog::mcap_log::McapLog;
use kestrel::mapping::grid::{GridPatch, OccupancyGrid};
use serde_json::json;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::time::{Duration, Instant};

/// Counts what is written and throws it away (the file's cost is the disk's, not the CPU's).
#[derive(Default)]
struct Counting {
    written: u64,
    position: u64,
}

impl Write for Counting {
    fn write(&mut self, buf: &[u8]) -> io::Result<usize> {
        self.position += buf.len() as u64;
        self.written = self.written.max(self.position);
        Ok(buf.len())
    }

    fn flush(&mut self) -> io::Result<()> {
        Ok(())
    }
}

impl Seek for Counting {
    fn seek(&mut self, pos: SeekFrom) -> io::Result<u64> {
        self.position = match pos {
            SeekFrom::Start(p) => p,
            SeekFrom::End(d) => self.written.saturating_add_signed(d),
            SeekFrom::Current(d) => self.position.saturating_add_signed(d),
        };
        Ok(self.position)
    }
}

/// A minute of flight as `FlightLog` writes it: the header, three drones' poses at 10 Hz (with
/// their setpoints) and a behavior event per drone every 5 s.
fn minute() -> Vec<u8> {
    let mut out = Vec::new();
    let header = json!({ "t": 0.0, "drone": null, "type": "header", "version": "0.1.0",
        "command": "sim", "start_time": "2026-01-01T00:00:00Z",
        "drones": ["drone_0", "drone_1", "drone_2"], "seed": 0 });
    out.extend_from_slice(format!("{header}\n").as_bytes());
    for k in 0..600u32 {
        let t = f64::from(k) * 0.1;
        for d in 0..3u32 {
            let drone = format!("drone_{d}");
            let (x, y) = ((t * 0.3).cos() * 5.0 + f64::from(d), (t * 0.3).sin() * 5.0);
            let pose = json!({ "t": t, "drone": drone, "type": "pose",
                "x": x, "y": y, "z": 3.0123456789, "yaw": t * 0.1,
                "vx": -1.5 * (t * 0.3).sin(), "vy": 1.5 * (t * 0.3).cos(), "vz": 0.0012,
                "armed": true, "flight": "flying", "behavior": "follow_path",
                "mode": "OFFBOARD", "link": "connected", "battery_v": 15.9,
                "battery_fraction": 0.87,
                "setpoint": { "kind": "velocity", "vx": -1.49, "vy": 1.51, "vz": 0.0,
                              "yaw_rate": 0.1 } });
            out.extend_from_slice(format!("{pose}\n").as_bytes());
            if k % 50 == 0 {
                let event = json!({ "t": t, "drone": drone, "type": "behavior",
                    "event": "started", "id": k, "behavior": "go_to",
                    "goal": { "x": x, "y": y, "z": 3.0 }, "mission": null });
                out.extend_from_slice(format!("{event}\n").as_bytes());
            }
        }
    }
    out
}

/// The writer thread's CPU time for `text` in 16 KiB chunks, as `ChannelWriter` hands it over
/// (s), and the bytes written.
fn write_lines(text: &[u8]) -> (f64, u64) {
    let started = Instant::now();
    let mut out = BufWriter::new(Counting::default());
    for chunk in text.chunks(16 * 1024) {
        out.write_all(chunk).unwrap_or_else(|e| panic!("{e}"));
    }
    out.flush().unwrap_or_else(|e| panic!("{e}"));
    (started.elapsed().as_secs_f64(), out.get_ref().written)
}

fn write_mcap(text: &[u8]) -> (f64, u64) {
    let started = Instant::now();
    let mut out = Counting::default();
    {
        let mut log = McapLog::new(BufWriter::new(&mut out)).unwrap_or_else(|e| panic!("{e}"));
        // One flush a second of flight, as the writer thread does in real time.
        for second in text
            .split_inclusive(|&b| b == b'\n')
            .collect::<Vec<_>>()
            .chunks(31)
        {
            for line in second {
                log.write_all(line).unwrap_or_else(|e| panic!("{e}"));
            }
            log.flush().unwrap_or_else(|e| panic!("{e}"));
        }
        log.finish().unwrap_or_else(|e| panic!("{e}"));
    }
    (started.elapsed().as_secs_f64(), out.written)
}

/// The control thread's time to make each `map` record of `text` again from its grid (s), and
/// how many there were.
fn encode_maps(text: &str) -> (f64, usize) {
    let mut spent = Duration::ZERO;
    let mut n = 0;
    for line in text.lines().filter(|l| l.contains(r#""type":"map""#)) {
        let record: serde_json::Value =
            serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}"));
        let update = map_record::decode(&record).unwrap_or_else(|e| panic!("{e}"));
        let mut grid = OccupancyGrid::new(update.grid).unwrap_or_else(|e| panic!("{e}"));
        let patch = GridPatch {
            region: update.region,
            data: update.cells,
        };
        grid.write_patch(&patch).unwrap_or_else(|e| panic!("{e}"));
        let started = Instant::now();
        let again = map_record::records(Duration::ZERO, Some("d"), &grid, update.region);
        spent += started.elapsed();
        assert!(!again.is_empty());
        n += 1;
    }
    (spent.as_secs_f64(), n)
}

/// The log at `path`: the writer thread's CPU per record with and without its `map` records,
/// and the control thread's per `map` record.
fn real_log(path: &str) {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{path}: {e}"));
    let is_map = |l: &&str| l.contains(r#""type":"map""#);
    let without: String = text
        .lines()
        .filter(|l| !is_map(l))
        .map(|l| format!("{l}\n"))
        .collect();
    let records = text.lines().count() as f64;
    for run in 1..=3 {
        let (lines_s, lines_bytes) = write_lines(text.as_bytes());
        let (all_s, all_bytes) = write_mcap(text.as_bytes());
        let (rest_s, rest_bytes) = write_mcap(without.as_bytes());
        let (encode_s, maps) = encode_maps(&text);
        let maps_f = maps as f64;
        println!(
            "{path} run {run}: {records} records, {maps} map records; JSON lines {:.0} ns/record, \
             {lines_bytes} bytes; MCAP {:.0} µs/record, {all_bytes} bytes ({:.2}x), of which \
             the map records {:.0} µs each on the writer thread ({} bytes); made on the control \
             thread in {:.0} µs each",
            lines_s / records * 1e9,
            all_s / records * 1e6,
            all_bytes as f64 / lines_bytes as f64,
            (all_s - rest_s) / maps_f * 1e6,
            all_bytes - rest_bytes,
            encode_s / maps_f * 1e6,
        );
    }
}

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("flight_log: run it with `cargo bench --bench flight_log`");
        return;
    }
    if let Ok(path) = std::env::var("FLIGHT_LOG") {
        real_log(&path);
    }
    let text = minute();
    let records = text.iter().filter(|&&b| b == b'\n').count() as f64;
    for run in 1..=3 {
        let (lines_s, lines_bytes) = write_lines(&text);
        let (mcap_s, mcap_bytes) = write_mcap(&text);
        println!(
            "run {run}: {records} records; JSON lines {:.0} ns/record, {lines_bytes} bytes; \
             MCAP {:.0} ns/record, {mcap_bytes} bytes ({:.2}x)",
            lines_s / records * 1e9,
            mcap_s / records * 1e9,
            mcap_bytes as f64 / lines_bytes as f64,
        );
    }
}
