//! Saving off the control loop: the `kestrel-store` thread and the [`Sink`] that feeds it.
//!
//! In: [`Change`]s from the control loop ([`Sink::push`]: a lock and a map insert per change,
//! never I/O, never a wait on the disk; a newer change of a file replaces an older one not yet
//! written, so the queue is bounded by the number of files). Out: the files, written durably in
//! batches (see `files`); the number of the last durable push, which the API waits for before it
//! acknowledges a change ([`Sink::saved`]); the [`StoreHealth`] for `GET /api/health`. A failed
//! batch is logged, reported in the health, kept and retried (1 s, doubling to 30 s).

use super::layout::{self, Change, LoadReport, Problem};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::{Arc, Condvar, Mutex, MutexGuard, PoisonError};
use std::time::Duration;
use tokio::sync::watch;

const RETRY_FIRST: Duration = Duration::from_secs(1);
const RETRY_MAX: Duration = Duration::from_secs(30);

#[derive(Default)]
struct Queue {
    pending: BTreeMap<PathBuf, Change>,
    /// Pushes so far (a push's number: the value after it).
    queued: u64,
}

struct Inner {
    root: PathBuf,
    queue: Mutex<Queue>,
    wake: Condvar,
    report: LoadReport,
}

#[derive(Debug, Clone, Default)]
struct Progress {
    /// Every push up to this one is on disk.
    durable: u64,
    /// The last batch tried covered pushes up to this one.
    attempted: u64,
    /// Why the last batch failed; `None` once one succeeds.
    error: Option<String>,
    failed_attempts: u64,
}

/// Whether the changes pushed so far are on disk.
#[derive(Debug, Clone, PartialEq)]
pub enum Saved {
    Durable,
    /// The save failed (it is retried); the reason.
    Failed(String),
    /// Not written within the time waited.
    Pending,
}

/// The state directory's health, as `GET /api/health` shows it.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct StoreHealth {
    pub state_dir: String,
    /// The last save succeeded (or nothing was saved yet).
    pub saving: bool,
    /// Files waiting to be written (retried while `saving` is false).
    pub pending_files: usize,
    pub last_error: Option<String>,
    /// Failed save attempts since start.
    pub failed_attempts: u64,
    /// Missions loaded at start.
    pub missions_loaded: usize,
    /// Files that could not be read at start, moved to `quarantine/`.
    pub quarantined: Vec<Problem>,
    /// The old `state.json`, migrated at start to one file per mission.
    pub migrated: Option<String>,
}

/// The way to the writer thread. Cheap to clone.
#[derive(Clone)]
pub struct Sink {
    inner: Arc<Inner>,
    progress: watch::Receiver<Progress>,
}

fn lock(queue: &Mutex<Queue>) -> MutexGuard<'_, Queue> {
    queue.lock().unwrap_or_else(PoisonError::into_inner)
}

impl Sink {
    /// Starts the writer thread for the state directory `root` (already loaded: `report`).
    pub fn start(root: &Path, report: LoadReport) -> std::io::Result<Self> {
        let inner = Arc::new(Inner {
            root: root.to_path_buf(),
            queue: Mutex::default(),
            wake: Condvar::new(),
            report,
        });
        let (tx, progress) = watch::channel(Progress::default());
        let thread_inner = inner.clone();
        std::thread::Builder::new()
            .name("kestrel-store".into())
            .spawn(move || write_forever(&thread_inner, &tx))?;
        Ok(Self { inner, progress })
    }

    /// Queues changes for the writer; never waits for the disk.
    pub fn push(&self, changes: Vec<Change>) {
        if changes.is_empty() {
            return;
        }
        let mut queue = lock(&self.inner.queue);
        for change in changes {
            queue.pending.insert(change.file(), change);
        }
        queue.queued += 1;
        drop(queue);
        self.inner.wake.notify_one();
    }

    /// Waits (at most `within`) until everything pushed so far is on disk, or a save of it
    /// failed.
    pub async fn saved(&self, within: Duration) -> Saved {
        let target = lock(&self.inner.queue).queued;
        let mut progress = self.progress.clone();
        let wait = async {
            progress
                .wait_for(|p| p.durable >= target || p.attempted >= target)
                .await
                .map(|p| p.clone())
        };
        match tokio::time::timeout(within, wait).await {
            Ok(Ok(p)) if p.durable >= target => Saved::Durable,
            Ok(Ok(p)) => Saved::Failed(p.error.clone().unwrap_or_default()),
            Ok(Err(_)) => Saved::Failed("the writer thread stopped".into()),
            Err(_) => Saved::Pending,
        }
    }

    pub fn health(&self) -> StoreHealth {
        let progress = self.progress.borrow().clone();
        let report = &self.inner.report;
        StoreHealth {
            state_dir: self.inner.root.display().to_string(),
            saving: progress.error.is_none(),
            pending_files: lock(&self.inner.queue).pending.len(),
            last_error: progress.error,
            failed_attempts: progress.failed_attempts,
            missions_loaded: report.missions,
            quarantined: report.problems.clone(),
            migrated: report.migrated.clone(),
        }
    }
}

/// The writer thread: takes everything pending, writes it as one batch, and on failure puts
/// back what no newer change replaced and tries again later. Ends with the process.
fn write_forever(inner: &Inner, progress: &watch::Sender<Progress>) {
    let mut retry = RETRY_FIRST;
    loop {
        let (batch, number) = {
            let mut queue = lock(&inner.queue);
            while queue.pending.is_empty() {
                queue = inner
                    .wake
                    .wait(queue)
                    .unwrap_or_else(PoisonError::into_inner);
            }
            (std::mem::take(&mut queue.pending), queue.queued)
        };
        let changes: Vec<Change> = batch.values().cloned().collect();
        match layout::write_all(&inner.root, &changes) {
            Ok(()) => {
                progress.send_modify(|p| {
                    p.durable = number;
                    p.attempted = number;
                    p.error = None;
                });
                retry = RETRY_FIRST;
            }
            Err(e) => {
                tracing::error!("saving the state: {e}; trying again in {retry:?}");
                // Back in the queue before the failure is published, so whoever sees the
                // failure also sees what waits to be written.
                let mut queue = lock(&inner.queue);
                for (file, change) in batch {
                    queue.pending.entry(file).or_insert(change);
                }
                drop(queue);
                progress.send_modify(|p| {
                    p.attempted = number;
                    p.error = Some(e.to_string());
                    p.failed_attempts += 1;
                });
                std::thread::sleep(retry);
                retry = (retry * 2).min(RETRY_MAX);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::executor::ExecutorMeta;

    fn meta(next_id: u32) -> Change {
        Change::Meta {
            drone: "drone_0".into(),
            meta: ExecutorMeta {
                next_id,
                ..ExecutorMeta::default()
            },
        }
    }

    #[tokio::test]
    async fn a_failed_save_is_reported_then_retried_until_it_succeeds() {
        let dir = tempfile::tempdir().unwrap();
        // A file where the drones' directory must go: every save fails.
        std::fs::write(dir.path().join("drones"), b"in the way").unwrap();
        let sink = Sink::start(dir.path(), LoadReport::default()).unwrap();
        sink.push(vec![meta(5)]);
        let Saved::Failed(reason) = sink.saved(Duration::from_secs(5)).await else {
            panic!("the save should fail");
        };
        assert!(reason.contains("drones"), "{reason}");
        let health = sink.health();
        assert!(!health.saving);
        assert_eq!(health.pending_files, 1);
        assert!(health.failed_attempts >= 1);

        std::fs::remove_file(dir.path().join("drones")).unwrap();
        sink.push(vec![meta(6)]);
        // The retry (within RETRY_FIRST) writes the newest content.
        assert_eq!(sink.saved(Duration::from_secs(10)).await, Saved::Durable);
        let written = std::fs::read(dir.path().join("drones/drone_0/executor.json")).unwrap();
        let meta: ExecutorMeta = serde_json::from_slice(&written).unwrap();
        assert_eq!(meta.next_id, 6);
        let health = sink.health();
        assert!(health.saving && health.last_error.is_none() && health.pending_files == 0);
    }
}
