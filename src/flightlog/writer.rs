//! Flight-log output that never blocks the control loop: bytes go through a bounded channel
//! to a writer thread that owns the file.
//!
//! In: what `FlightLog` writes (JSON lines) and the file's format. Out: the file: JSON lines
//! flushed whenever the writer is idle, or MCAP (`flightlog::mcap_log`, the records turned into
//! Foxglove's channels here, off the control thread) with a chunk closed and flushed at most
//! every [`MCAP_FLUSH`] and its summary written when the log closes. When the disk cannot keep
//! up, records are dropped (and counted) rather than stalling the loop.

use crate::flightlog::mcap_log::McapLog;
use crate::flightlog::LogFormat;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, Receiver, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::{Duration, Instant};

/// Chunks queued before records are dropped.
const QUEUE: usize = 4096;
/// Longest time between two flushes of an MCAP log (each closes a chunk): what a killed
/// process loses at most, beyond what was still queued.
pub const MCAP_FLUSH: Duration = Duration::from_secs(1);

pub struct ChannelWriter {
    tx: SyncSender<Vec<u8>>,
    buffer: Vec<u8>,
    dropped: Arc<AtomicU64>,
}

/// Where the log goes, and how many records were lost on the way.
#[derive(Clone)]
pub struct LogFile {
    pub path: PathBuf,
    pub dropped: Arc<AtomicU64>,
    closed: Arc<AtomicBool>,
}

impl LogFile {
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }

    /// Waits up to `timeout` for the writer thread to have closed the file (it does once the
    /// [`ChannelWriter`] is dropped): an MCAP log's summary is then written. Whether it has.
    pub fn wait_closed(&self, timeout: Duration) -> bool {
        let until = Instant::now() + timeout;
        while !self.closed.load(Ordering::Acquire) {
            if Instant::now() >= until {
                return false;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        true
    }
}

/// The file as the writer thread writes it.
enum Sink {
    Lines(BufWriter<std::fs::File>),
    Mcap(Box<McapLog<BufWriter<std::fs::File>>>),
}

impl Sink {
    fn finish(self) -> std::io::Result<()> {
        match self {
            Sink::Lines(mut out) => out.flush(),
            Sink::Mcap(log) => Ok(log.finish()?),
        }
    }

    fn out(&mut self) -> &mut dyn Write {
        match self {
            Sink::Lines(out) => out,
            Sink::Mcap(log) => log.as_mut(),
        }
    }
}

/// Starts the writer thread of `file` (opened by `flightlog::files`), found at `path`, writing
/// `format`.
pub fn open(
    file: std::fs::File,
    path: &Path,
    format: LogFormat,
) -> std::io::Result<(ChannelWriter, LogFile)> {
    let (tx, rx) = sync_channel::<Vec<u8>>(QUEUE);
    let dropped = Arc::new(AtomicU64::new(0));
    let closed = Arc::new(AtomicBool::new(false));
    let sink = match format {
        LogFormat::Jsonl => Sink::Lines(BufWriter::new(file)),
        LogFormat::Mcap => Sink::Mcap(Box::new(McapLog::new(BufWriter::new(file))?)),
    };
    let done = closed.clone();
    std::thread::Builder::new()
        .name("kestrel-log".into())
        .spawn(move || {
            if let Err(e) = write_until_closed(&rx, sink) {
                tracing::error!("flight log: {e}");
            }
            done.store(true, Ordering::Release);
        })?;
    Ok((
        ChannelWriter {
            tx,
            buffer: Vec::new(),
            dropped: dropped.clone(),
        },
        LogFile {
            path: path.to_path_buf(),
            dropped,
            closed,
        },
    ))
}

/// The writer thread: writes what arrives, flushes when idle (an MCAP log at most every
/// [`MCAP_FLUSH`], and at least that often while busy), finishes the file when the sender goes.
fn write_until_closed(rx: &Receiver<Vec<u8>>, mut sink: Sink) -> std::io::Result<()> {
    let mcap = matches!(sink, Sink::Mcap(_));
    let mut flushed = Instant::now();
    loop {
        let flush = match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(chunk) => {
                sink.out().write_all(&chunk)?;
                mcap && flushed.elapsed() >= MCAP_FLUSH
            }
            Err(RecvTimeoutError::Timeout) => !mcap || flushed.elapsed() >= MCAP_FLUSH,
            Err(RecvTimeoutError::Disconnected) => return sink.finish(),
        };
        if flush {
            sink.out().flush()?;
            flushed = Instant::now();
        }
    }
}

impl Write for ChannelWriter {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.buffer.extend_from_slice(buf);
        if self.buffer.len() >= 16 * 1024 {
            self.flush()?;
        }
        Ok(buf.len())
    }

    /// Hands the buffered records to the writer thread (it writes them to disk when idle).
    fn flush(&mut self) -> std::io::Result<()> {
        if self.buffer.is_empty() {
            return Ok(());
        }
        let chunk = std::mem::take(&mut self.buffer);
        match self.tx.try_send(chunk) {
            Ok(()) => Ok(()),
            Err(TrySendError::Full(_)) => {
                self.dropped.fetch_add(1, Ordering::Relaxed);
                Ok(())
            }
            Err(TrySendError::Disconnected(_)) => Err(std::io::Error::new(
                std::io::ErrorKind::BrokenPipe,
                "flight log writer stopped",
            )),
        }
    }
}
