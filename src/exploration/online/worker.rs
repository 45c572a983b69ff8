//! The fleet's frontier allocator off the control thread: one worker thread keeps the
//! [`FrontierService`] and its own copy of the merged map, and answers the drones' questions in
//! batches, one batch per tick at most.
//!
//! In: each tick's [`ExploreJob`]s with the time, and the fleet's merged map, from which a batch
//! takes only the regions changed since the last batch (the whole grid only for the first batch
//! and after the map was replaced). Out: [`FrontierAnswer`]s, collected by the host with
//! [`FrontierWorker::collect`], and the frontiers and claims the allocator last published (for
//! operators). With [`Delivery::Lockstep`] (simulated time) `collect` waits for the batch sent
//! on the last tick, so a seeded run answers exactly as if the allocator ran on the tick; paced
//! to the wall clock it takes what is done and never waits, and the jobs of later ticks wait in
//! the host until the batch in flight is back.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender};
use std::sync::Arc;
use std::thread::JoinHandle;
use std::time::Duration;

use super::service::{
    Allocation, ClaimView, ExploreError, ExploreRequest, FrontierService, FrontierView, RemoteClaim,
};
use crate::mapping::grid::{GridPatch, OccupancyGrid};
use crate::mapping::merged::FleetMap;
use crate::planning::worker::Delivery;

/// Most jobs waiting in the host for the batch in flight; more are answered `Unavailable`.
const MAX_WAITING_JOBS: usize = 256;

/// One drone's question to the frontier allocator, as its behavior filed it (the behavior's
/// ticket and the flag its ticket sets when dropped).
#[derive(Debug)]
pub struct ExploreJob {
    pub ticket: u64,
    pub request: ExploreRequest,
    pub cancel: Arc<AtomicBool>,
}

/// The outcome of one [`ExploreJob`].
#[derive(Debug)]
pub struct FrontierAnswer {
    pub drone: usize,
    pub ticket: u64,
    pub result: Result<Allocation, ExploreError>,
    /// The job's cancel flag, so the receiver can drop answers nobody waits for.
    pub cancel: Arc<AtomicBool>,
}

/// How a batch brings the worker's copy of the map up to date.
enum GridUpdate {
    Whole(OccupancyGrid),
    Changed(Vec<GridPatch>),
}

/// The jobs of one or more ticks, answered together at `now`.
struct Batch {
    now: Duration,
    grid: GridUpdate,
    jobs: Vec<(usize, ExploreJob)>,
    /// Other processes' claims, when new ones were heard since the last batch.
    remote: Option<Vec<RemoteClaim>>,
}

/// A batch's answers and what the allocator looked like after them.
struct Done {
    answers: Vec<FrontierAnswer>,
    frontiers: Vec<FrontierView>,
    claims: Vec<ClaimView>,
}

/// Who waits for the batch in flight (answered `Unavailable` if the worker is lost).
type Owed = Vec<(usize, u64, Arc<AtomicBool>)>;

/// The allocator's thread and what the host keeps of it.
pub struct FrontierWorker {
    batches: Option<SyncSender<Batch>>,
    done: Receiver<Done>,
    in_flight: Option<Owed>,
    /// Jobs of later ticks, sent when the batch in flight is back (wall clock only).
    waiting: Vec<(usize, ExploreJob)>,
    /// Whether the worker's copy of the map is in step; if not, the next batch sends it whole.
    synced: bool,
    /// Other processes' claims heard since the last batch, sent with the next one.
    remote: Option<Vec<RemoteClaim>>,
    refused: Vec<FrontierAnswer>,
    delivery: Delivery,
    frontiers: Vec<FrontierView>,
    claims: Vec<ClaimView>,
    thread: Option<JoinHandle<()>>,
}

impl FrontierWorker {
    pub fn new(delivery: Delivery) -> Self {
        let (batch_tx, batch_rx) = mpsc::sync_channel::<Batch>(1);
        // Bounded by the batch queue (depth 1): one answer per batch taken from it.
        #[allow(clippy::disallowed_methods)]
        let (done_tx, done_rx) = mpsc::channel();
        let thread = std::thread::Builder::new()
            .name("kestrel-frontiers".into())
            .spawn(move || serve(&batch_rx, &done_tx))
            .ok();
        if thread.is_none() {
            tracing::error!("no frontier allocator thread could be started: exploring will fail");
        }
        FrontierWorker {
            batches: thread.as_ref().map(|_| batch_tx),
            done: done_rx,
            in_flight: None,
            waiting: Vec::new(),
            synced: false,
            remote: None,
            refused: Vec::new(),
            delivery,
            frontiers: Vec::new(),
            claims: Vec::new(),
            thread,
        }
    }

    pub fn delivery(&self) -> Delivery {
        self.delivery
    }

    /// The map was replaced: the next batch carries it whole.
    pub fn resync(&mut self) {
        self.synced = false;
    }

    /// The goals of drones other Kestrel processes fly, as last heard (see
    /// [`FrontierService::set_remote_claims`]); they reach the allocator with the next question.
    pub fn set_remote_claims(&mut self, claims: Vec<RemoteClaim>) {
        self.remote = Some(claims);
    }

    /// Queues this tick's jobs and, unless a batch is still with the worker, sends every job
    /// waiting with the map's changes since the last batch (taken from `map` only then).
    pub fn submit(
        &mut self,
        now: Duration,
        jobs: Vec<(usize, ExploreJob)>,
        map: Option<&mut FleetMap>,
    ) {
        for (drone, job) in jobs {
            if self.waiting.len() >= MAX_WAITING_JOBS {
                self.refuse(
                    drone,
                    job,
                    "too many questions wait for the frontier allocator",
                );
            } else {
                self.waiting.push((drone, job));
            }
        }
        self.waiting
            .retain(|(_, job)| !job.cancel.load(Ordering::Relaxed));
        if self.waiting.is_empty() || self.in_flight.is_some() {
            return;
        }
        let Some(map) = map else {
            for (drone, job) in std::mem::take(&mut self.waiting) {
                self.answer_now(drone, job, Err(ExploreError::NoMap));
            }
            return;
        };
        let Some(tx) = self.batches.as_ref() else {
            for (drone, job) in std::mem::take(&mut self.waiting) {
                self.refuse(drone, job, "no frontier allocator thread");
            }
            return;
        };
        let grid = if self.synced {
            GridUpdate::Changed(map.take_unsynced())
        } else {
            map.take_unsynced();
            GridUpdate::Whole(map.merged().clone())
        };
        let jobs = std::mem::take(&mut self.waiting);
        let owed: Owed = jobs
            .iter()
            .map(|(d, j)| (*d, j.ticket, j.cancel.clone()))
            .collect();
        let remote = self.remote.take();
        match tx.try_send(Batch {
            now,
            grid,
            jobs,
            remote,
        }) {
            Ok(()) => {
                self.synced = true;
                self.in_flight = Some(owed);
            }
            Err(e) => {
                // The channel holds one batch and none is in flight, so only a lost worker
                // refuses one.
                self.batches = None;
                self.synced = false;
                let batch = match e {
                    mpsc::TrySendError::Full(b) | mpsc::TrySendError::Disconnected(b) => b,
                };
                for (drone, job) in batch.jobs {
                    self.refuse(drone, job, "the frontier allocator thread stopped");
                }
            }
        }
    }

    /// Answers ready now; in [`Delivery::Lockstep`], every answer to the batch in flight.
    pub fn collect(&mut self) -> Vec<FrontierAnswer> {
        let mut out = std::mem::take(&mut self.refused);
        let Some(owed) = self.in_flight.take() else {
            return out;
        };
        let done = match self.delivery {
            Delivery::Lockstep => self.done.recv().ok(),
            Delivery::RealTime { .. } => match self.done.try_recv() {
                Ok(done) => Some(done),
                Err(mpsc::TryRecvError::Empty) => {
                    self.in_flight = Some(owed);
                    return out;
                }
                Err(mpsc::TryRecvError::Disconnected) => None,
            },
        };
        match done {
            Some(done) => {
                out.extend(done.answers);
                self.frontiers = done.frontiers;
                self.claims = done.claims;
            }
            None => {
                self.batches = None;
                self.synced = false;
                out.extend(
                    owed.into_iter()
                        .map(|(drone, ticket, cancel)| FrontierAnswer {
                            drone,
                            ticket,
                            result: Err(ExploreError::Unavailable(
                                "the frontier allocator thread stopped".into(),
                            )),
                            cancel,
                        }),
                );
            }
        }
        out
    }

    /// The frontiers as the allocator last published them.
    pub fn frontiers(&self) -> &[FrontierView] {
        &self.frontiers
    }

    /// The goal each drone held when the allocator last answered.
    pub fn claims(&self) -> &[ClaimView] {
        &self.claims
    }

    fn refuse(&mut self, drone: usize, job: ExploreJob, why: &str) {
        self.answer_now(drone, job, Err(ExploreError::Unavailable(why.into())));
    }

    fn answer_now(
        &mut self,
        drone: usize,
        job: ExploreJob,
        result: Result<Allocation, ExploreError>,
    ) {
        self.refused.push(FrontierAnswer {
            drone,
            ticket: job.ticket,
            result,
            cancel: job.cancel,
        });
    }
}

impl Drop for FrontierWorker {
    fn drop(&mut self) {
        self.batches = None;
        if let Some(t) = self.thread.take() {
            if t.join().is_err() {
                tracing::error!("the frontier allocator thread panicked");
            }
        }
    }
}

/// The worker loop: one batch at a time, on its own copy of the merged map.
fn serve(batches: &Receiver<Batch>, done: &mpsc::Sender<Done>) {
    let mut service = FrontierService::new();
    let mut grid: Option<OccupancyGrid> = None;
    while let Ok(batch) = batches.recv() {
        if let Some(claims) = batch.remote {
            service.set_remote_claims(claims);
        }
        match batch.grid {
            GridUpdate::Whole(whole) => grid = Some(whole),
            GridUpdate::Changed(patches) => {
                if let Some(g) = grid.as_mut() {
                    for p in &patches {
                        if let Err(e) = g.write_patch(p) {
                            tracing::error!("frontier allocator: map change not applied: {e}");
                        }
                    }
                }
            }
        }
        let answers = batch
            .jobs
            .into_iter()
            .filter(|(_, job)| !job.cancel.load(Ordering::Relaxed))
            .map(|(drone, job)| FrontierAnswer {
                drone,
                ticket: job.ticket,
                result: match grid.as_ref() {
                    Some(g) => service.answer(batch.now, g, &job.request),
                    None => Err(ExploreError::NoMap),
                },
                cancel: job.cancel,
            })
            .collect();
        let out = Done {
            answers,
            frontiers: service.frontiers(),
            claims: service.claims(),
        };
        if done.send(out).is_err() {
            return;
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::exploration::online::allocation::AllocatorKind;
    use crate::exploration::online::space::SpaceParams;
    use crate::mapping::config::MapConfig;
    use crate::mapping::grid::{Cell, CellBox, GridSpec, UNKNOWN};
    use crate::types::Vec3;
    use nalgebra::Vector2;

    /// A fleet map of `w` x `h` cells at 0.1 m whose west `known_w` columns are known free.
    fn fleet_map(w: u32, h: u32, known_w: u32) -> FleetMap {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: w,
            height_cells: h,
            origin_enu_m: Vector2::zeros(),
        };
        let data = (0..h)
            .flat_map(|_| (0..w).map(move |x| if x < known_w { 0 } else { UNKNOWN }))
            .collect();
        let mut config = MapConfig::open_field().unwrap();
        config.initial = Arc::new(OccupancyGrid::from_data(spec, data).unwrap());
        FleetMap::new(&config).unwrap()
    }

    fn job(ticket: u64, drone: &str, x: f64, y: f64) -> ExploreJob {
        ExploreJob {
            ticket,
            request: ExploreRequest {
                drone: drone.into(),
                position_enu_m: Vec3::new(x, y, 1.0),
                flight_height_m: 1.0,
                allocator: AllocatorKind::Kestrel,
                settings: Default::default(),
                space: SpaceParams::default(),
                current_goal_enu_m: None,
                give_up: None,
                sweep_along: false,
                keep_out: Vec::new(),
                claim: true,
            },
            cancel: Arc::new(AtomicBool::new(false)),
        }
    }

    /// Frees the cells of `region` in `drone`'s layer of `map`.
    fn free(map: &mut FleetMap, drone: &str, region: CellBox) {
        let mut own = OccupancyGrid::new(*map.merged().spec()).unwrap();
        for y in region.min.y..=region.max.y {
            for x in region.min.x..=region.max.x {
                own.set(Cell { x, y }, 0).unwrap();
            }
        }
        map.copy_from_drone(drone, &own, region).unwrap();
    }

    #[test]
    fn in_lock_step_the_answers_are_those_of_the_service_on_the_same_map() {
        let mut map = fleet_map(200, 100, 100);
        let mut reference = FrontierService::new();
        let mut w = FrontierWorker::new(Delivery::Lockstep);
        let t1 = Duration::from_secs(1);
        w.submit(
            t1,
            vec![(0, job(1, "a", 2.0, 2.0)), (1, job(2, "b", 2.0, 2.5))],
            Some(&mut map),
        );
        let answers = w.collect();
        assert_eq!(answers.len(), 2);
        for (a, (who, x, y)) in answers.iter().zip([("a", 2.0, 2.0), ("b", 2.0, 2.5)]) {
            let want = reference.answer(t1, map.merged(), &job(0, who, x, y).request);
            assert_eq!(a.result, want);
        }
        assert_eq!((answers[0].drone, answers[0].ticket), (0, 1));
        assert_eq!(w.claims().len(), 2);
        assert!(!w.frontiers().is_empty());
        // The map changes: the worker's copy follows from the changed region alone.
        free(
            &mut map,
            "b",
            CellBox {
                min: Cell { x: 100, y: 0 },
                max: Cell { x: 150, y: 99 },
            },
        );
        let t2 = Duration::from_secs(2);
        w.submit(t2, vec![(0, job(3, "a", 12.0, 5.0))], Some(&mut map));
        let answers = w.collect();
        let want = reference.answer(t2, map.merged(), &job(0, "a", 12.0, 5.0).request);
        assert_eq!(answers[0].result, want);
        assert!(matches!(want, Ok(Allocation::Goal { goal_enu_m, .. }) if goal_enu_m.x > 14.0));
        assert!(w.collect().is_empty(), "nothing owed");
        // A cancelled question is not answered; no map at all is answered `NoMap`.
        let cancelled = job(4, "a", 2.0, 2.0);
        cancelled.cancel.store(true, Ordering::Relaxed);
        w.submit(t2, vec![(0, cancelled)], Some(&mut map));
        assert!(w.collect().is_empty());
        w.submit(t2, vec![(0, job(5, "a", 2.0, 2.0))], None);
        assert_eq!(w.collect()[0].result, Err(ExploreError::NoMap));
    }

    #[test]
    fn paced_to_the_wall_clock_a_slow_allocator_never_holds_the_tick() {
        // 1000 x 1000 cells: reading the space takes the worker a while (a second or so in a
        // debug build), submitting and collecting take the tick a copy of the grid at most.
        let mut map = fleet_map(1000, 1000, 500);
        let mut w = FrontierWorker::new(Delivery::RealTime {
            deadline: Duration::from_millis(100),
        });
        let t = Duration::from_secs(1);
        w.submit(t, vec![(0, job(1, "a", 2.0, 2.0))], Some(&mut map));
        assert!(
            w.collect().is_empty(),
            "the tick went on without the answer"
        );
        // The next tick's question waits in the host while the first batch is with the worker.
        w.submit(t, vec![(1, job(2, "b", 3.0, 3.0))], Some(&mut map));
        assert!(w.collect().is_empty());
        let mut got = Vec::new();
        let start = std::time::Instant::now();
        while got.len() < 2 && start.elapsed() < Duration::from_secs(600) {
            for a in w.collect() {
                got.push((a.drone, a.ticket, a.result.is_ok()));
            }
            // The host submits every tick, with or without questions.
            w.submit(t, Vec::new(), Some(&mut map));
            std::thread::sleep(Duration::from_millis(5));
        }
        assert_eq!(got, [(0, 1, true), (1, 2, true)]);
    }
}
