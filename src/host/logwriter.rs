//! Flight-log output that never blocks the control loop: bytes go through a bounded channel
//! to a writer thread that owns the file.
//!
//! In: what `FlightLog` writes. Out: the file, flushed whenever the writer is idle. When the
//! disk cannot keep up, records are dropped (and counted) rather than stalling the loop.

use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::mpsc::{sync_channel, RecvTimeoutError, SyncSender, TrySendError};
use std::sync::Arc;
use std::time::Duration;

/// Chunks queued before records are dropped.
const QUEUE: usize = 4096;

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
}

impl LogFile {
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}

/// Starts the writer thread of `file` (opened by `flightlog::files`), found at `path`.
pub fn open(file: std::fs::File, path: &Path) -> std::io::Result<(ChannelWriter, LogFile)> {
    let (tx, rx) = sync_channel::<Vec<u8>>(QUEUE);
    let dropped = Arc::new(AtomicU64::new(0));
    std::thread::Builder::new()
        .name("kestrel-log".into())
        .spawn(move || {
            let mut out = std::io::BufWriter::new(file);
            loop {
                match rx.recv_timeout(Duration::from_millis(100)) {
                    Ok(chunk) => {
                        if let Err(e) = out.write_all(&chunk) {
                            tracing::error!("flight log: {e}");
                            return;
                        }
                    }
                    Err(RecvTimeoutError::Timeout) => {
                        if let Err(e) = out.flush() {
                            tracing::error!("flight log: {e}");
                            return;
                        }
                    }
                    Err(RecvTimeoutError::Disconnected) => {
                        let _ = out.flush();
                        return;
                    }
                }
            }
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
        },
    ))
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
