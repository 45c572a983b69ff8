//! Benchmark (BENCHMARKS.md, "MCAP flight logs"): CPU per record of the two log formats, on
//! the writer thread (`flightlog::writer`; the control thread's part, a record made into a JSON
//! line, is the same for both) and the bytes each format writes per record, for one minute of
//! three drones' pose records at 10 Hz with their events.
//!
//!     cargo bench --bench flight_log

use kestrel::flightlog::mcap_log::McapLog;
use serde_json::json;
use std::io::{self, BufWriter, Seek, SeekFrom, Write};
use std::time::Instant;

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

fn main() {
    // `cargo test --all-targets` runs bench binaries too: only `cargo bench` measures.
    if !std::env::args().any(|a| a == "--bench") {
        println!("flight_log: run it with `cargo bench --bench flight_log`");
        return;
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
