//! Plans off the control tick: one worker thread per host runs the drones' path requests on
//! snapshots of their maps, each with a cancel flag and (in real time) a deadline, and keeps one
//! planning map per drone, rebuilt only when that drone's map changed.
//!
//! In: [`PlanJob`]s (drone index, ticket, request, map snapshot, cancel flag). Out:
//! [`PlanAnswer`]s, collected by the host with [`PlanWorker::collect`]: in real time whatever is
//! done (a tick never waits for a plan), in simulated time every job submitted so far (so a
//! seeded run is reproducible whatever the machine's load).

use std::collections::HashMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, SyncSender, TrySendError};
use std::sync::{Arc, Condvar, Mutex, PoisonError};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use super::{PathPlanner, PlanBudget, PlanError, PlanRequest, PlannedPath, Planners, PlanningMap};
use crate::mapping::server::MapSnapshot;

/// Jobs waiting for the worker before a new one is refused with [`PlanError::Unavailable`].
const QUEUE_DEPTH: usize = 64;

/// Expansions allowed per map cell: enough for any path the grid holds (each cell is expanded
/// at most once per heading class), so only a deadline or a cancel stops a plan early.
const EXPANSIONS_PER_CELL: usize = 4;

/// One path request of one drone.
#[derive(Debug)]
pub struct PlanJob {
    pub ticket: u64,
    pub request: PlanRequest,
    pub map: Arc<MapSnapshot>,
    /// Set by the requester when it no longer wants the answer.
    pub cancel: Arc<AtomicBool>,
}

/// The outcome of one [`PlanJob`].
#[derive(Debug)]
pub struct PlanAnswer {
    pub drone: usize,
    pub ticket: u64,
    pub result: Result<PlannedPath, PlanError>,
    /// The job's cancel flag, so the receiver can drop answers nobody waits for.
    pub cancel: Arc<AtomicBool>,
}

/// How answers reach the host.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Delivery {
    /// Wall-clock time: answers are taken when ready; each plan has a deadline.
    RealTime { deadline: Duration },
    /// Simulated time: `collect` waits for every job submitted, no wall-clock deadline.
    Lockstep,
}

/// The worker thread and its queues.
pub struct PlanWorker {
    jobs: Option<SyncSender<(usize, PlanJob)>>,
    answers: Receiver<PlanAnswer>,
    /// Answers made without the worker (queue full, worker gone).
    refused: Vec<PlanAnswer>,
    outstanding: usize,
    delivery: Delivery,
    thread: Option<JoinHandle<()>>,
    watchdog: Arc<Watchdog>,
    watchdog_thread: Option<JoinHandle<()>>,
}

impl PlanWorker {
    pub fn new(delivery: Delivery) -> Self {
        let (job_tx, job_rx) = mpsc::sync_channel::<(usize, PlanJob)>(QUEUE_DEPTH);
        // Bounded by the job queue: one answer per job taken from it.
        #[allow(clippy::disallowed_methods)]
        let (answer_tx, answer_rx) = mpsc::channel();
        let watchdog = Arc::new(Watchdog::default());
        let deadline = match delivery {
            Delivery::RealTime { deadline } => Some(deadline),
            Delivery::Lockstep => None,
        };
        let thread = {
            let watchdog = watchdog.clone();
            std::thread::Builder::new()
                .name("kestrel-planner".into())
                .spawn(move || serve(&job_rx, &answer_tx, &watchdog, deadline))
                .ok()
        };
        let watchdog_thread = {
            let watchdog = watchdog.clone();
            std::thread::Builder::new()
                .name("kestrel-plan-deadline".into())
                .spawn(move || watchdog.run())
                .ok()
        };
        if thread.is_none() {
            tracing::error!("no planner thread could be started: every plan will fail");
        }
        PlanWorker {
            jobs: thread.as_ref().map(|_| job_tx),
            answers: answer_rx,
            refused: Vec::new(),
            outstanding: 0,
            delivery,
            thread,
            watchdog,
            watchdog_thread,
        }
    }

    pub fn delivery(&self) -> Delivery {
        self.delivery
    }

    /// Queues a job of `drone`; a full queue or a missing worker answers at once.
    pub fn submit(&mut self, drone: usize, job: PlanJob) {
        let refuse = |job: PlanJob, why: &str| PlanAnswer {
            drone,
            ticket: job.ticket,
            result: Err(PlanError::Unavailable(why.into())),
            cancel: job.cancel,
        };
        let Some(tx) = self.jobs.as_ref() else {
            self.refused.push(refuse(job, "no planner thread"));
            return;
        };
        match tx.try_send((drone, job)) {
            Ok(()) => self.outstanding += 1,
            Err(TrySendError::Full((_, job))) => self
                .refused
                .push(refuse(job, "too many plans waiting; try again")),
            Err(TrySendError::Disconnected((_, job))) => {
                self.refused.push(refuse(job, "the planner thread stopped"));
            }
        }
    }

    /// Answers ready now; in [`Delivery::Lockstep`], every answer still owed.
    pub fn collect(&mut self) -> Vec<PlanAnswer> {
        let mut out = std::mem::take(&mut self.refused);
        if self.delivery == Delivery::Lockstep {
            while self.outstanding > 0 {
                match self.answers.recv() {
                    Ok(a) => {
                        self.outstanding -= 1;
                        out.push(a);
                    }
                    Err(_) => {
                        self.outstanding = 0;
                    }
                }
            }
        }
        while let Ok(a) = self.answers.try_recv() {
            self.outstanding = self.outstanding.saturating_sub(1);
            out.push(a);
        }
        out
    }
}

impl Drop for PlanWorker {
    fn drop(&mut self) {
        self.jobs = None;
        self.watchdog.stop();
        for t in [self.thread.take(), self.watchdog_thread.take()]
            .into_iter()
            .flatten()
        {
            if t.join().is_err() {
                tracing::error!("a planner thread panicked");
            }
        }
    }
}

/// The worker loop: one job at a time, planning maps cached per drone.
fn serve(
    jobs: &Receiver<(usize, PlanJob)>,
    answers: &mpsc::Sender<PlanAnswer>,
    watchdog: &Watchdog,
    deadline: Option<Duration>,
) {
    let planners = Planners::default();
    let mut maps: HashMap<usize, (f64, Arc<PlanningMap>)> = HashMap::new();
    while let Ok((drone, job)) = jobs.recv() {
        let result = if job.cancel.load(Ordering::Relaxed) {
            Err(PlanError::Cancelled)
        } else {
            let map = planning_map(&mut maps, drone, &job.map, job.request.shadow_m);
            let passed = Arc::new(AtomicBool::new(false));
            if let Some(d) = deadline {
                watchdog.arm(Instant::now() + d, passed.clone());
            }
            let budget = PlanBudget {
                max_expansions: map
                    .grid()
                    .spec()
                    .cell_count()
                    .saturating_mul(EXPANSIONS_PER_CELL),
                cancel: Some(&job.cancel),
                deadline_passed: Some(&passed),
                now_s: None,
            };
            let result = planners.plan(&job.request, &map, &budget);
            watchdog.disarm();
            result
        };
        let answer = PlanAnswer {
            drone,
            ticket: job.ticket,
            result,
            cancel: job.cancel,
        };
        if answers.send(answer).is_err() {
            return;
        }
    }
}

/// The drone's planning map for this snapshot (unknown cells within `shadow_m` of obstacles
/// made obstacles), rebuilt only when its revision or the shadow changed.
fn planning_map(
    maps: &mut HashMap<usize, (f64, Arc<PlanningMap>)>,
    drone: usize,
    snap: &MapSnapshot,
    shadow_m: f64,
) -> Arc<PlanningMap> {
    if let Some((shadow, m)) = maps.get(&drone) {
        if m.revision() == Some(snap.revision) && *shadow == shadow_m {
            return m.clone();
        }
    }
    let grid = if shadow_m > 0.0 {
        PlanningMap::shadowed(&snap.grid, snap.occupied_threshold, shadow_m)
    } else {
        snap.grid.clone()
    };
    let mut map = PlanningMap::new(grid, snap.occupied_threshold)
        .with_stamp(snap.updated_at_s)
        .with_revision(snap.revision);
    if let Some(g) = &snap.graph {
        map = map.with_graph((**g).clone());
    }
    let map = Arc::new(map);
    maps.insert(drone, (shadow_m, map.clone()));
    map
}

/// Sets the current plan's deadline flag when its time passes.
#[derive(Default)]
struct Watchdog {
    slot: Mutex<WatchSlot>,
    wake: Condvar,
}

#[derive(Default)]
struct WatchSlot {
    armed: Option<(Instant, Arc<AtomicBool>)>,
    stopped: bool,
}

impl Watchdog {
    fn lock(&self) -> std::sync::MutexGuard<'_, WatchSlot> {
        self.slot.lock().unwrap_or_else(PoisonError::into_inner)
    }

    fn arm(&self, at: Instant, flag: Arc<AtomicBool>) {
        if at <= Instant::now() {
            flag.store(true, Ordering::Relaxed);
            return;
        }
        self.lock().armed = Some((at, flag));
        self.wake.notify_one();
    }

    fn disarm(&self) {
        self.lock().armed = None;
    }

    fn stop(&self) {
        self.lock().stopped = true;
        self.wake.notify_one();
    }

    fn run(&self) {
        let mut slot = self.lock();
        while !slot.stopped {
            let wait = match &slot.armed {
                None => None,
                Some((at, flag)) => match at.checked_duration_since(Instant::now()) {
                    Some(left) => Some(left),
                    None => {
                        flag.store(true, Ordering::Relaxed);
                        slot.armed = None;
                        continue;
                    }
                },
            };
            slot = match wait {
                None => self.wake.wait(slot).unwrap_or_else(PoisonError::into_inner),
                Some(left) => {
                    self.wake
                        .wait_timeout(slot, left)
                        .unwrap_or_else(PoisonError::into_inner)
                        .0
                }
            };
        }
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::mapping::grid::{Cell, GridSpec, OccupancyGrid};
    use crate::planning::{PlannerKind, UnknownPolicy};
    use nalgebra::{Vector2, Vector3};

    fn snapshot(revision: u64, wall: bool) -> Arc<MapSnapshot> {
        let spec = GridSpec {
            resolution_m: 0.1,
            width_cells: 100,
            height_cells: 100,
            origin_enu_m: Vector2::new(0.0, 0.0),
        };
        let mut grid = OccupancyGrid::from_data(spec, vec![0; spec.cell_count()]).unwrap();
        if wall {
            for y in 0..90 {
                grid.set(Cell { x: 50, y }, 100).unwrap();
            }
        }
        Arc::new(MapSnapshot {
            grid,
            revision,
            occupied_threshold: 50,
            updated_at_s: 0.0,
            graph: None,
        })
    }

    fn job(ticket: u64, map: Arc<MapSnapshot>) -> PlanJob {
        PlanJob {
            ticket,
            request: PlanRequest {
                start_enu_m: Vector3::new(1.0, 1.0, 1.0),
                goal_enu_m: Vector3::new(9.0, 1.0, 1.0),
                flight_height_m: 1.0,
                safety_distance_m: 0.3,
                unknown: UnknownPolicy::Blocked,
                kind: PlannerKind::AStar,
                max_map_age_s: None,
                shadow_m: 0.0,
            },
            map,
            cancel: Arc::new(AtomicBool::new(false)),
        }
    }

    #[test]
    fn lockstep_collect_returns_every_answer_in_submission_order() {
        let mut w = PlanWorker::new(Delivery::Lockstep);
        w.submit(0, job(1, snapshot(1, false)));
        w.submit(1, job(2, snapshot(1, true)));
        let answers = w.collect();
        assert_eq!(answers.len(), 2);
        assert_eq!((answers[0].drone, answers[0].ticket), (0, 1));
        let straight = answers[0].result.as_ref().unwrap();
        let around = answers[1].result.as_ref().unwrap();
        assert!(straight.length_m < 8.5, "{straight:?}");
        assert!(around.length_m > 12.0, "goes round the wall: {around:?}");
        assert!(w.collect().is_empty());
    }

    #[test]
    fn a_cancelled_job_is_answered_cancelled_without_planning() {
        let mut w = PlanWorker::new(Delivery::Lockstep);
        let j = job(7, snapshot(1, true));
        j.cancel.store(true, Ordering::Relaxed);
        w.submit(0, j);
        let answers = w.collect();
        assert_eq!(answers[0].result, Err(PlanError::Cancelled));
    }

    #[test]
    fn a_passed_deadline_stops_the_plan_with_a_timeout() {
        let mut w = PlanWorker::new(Delivery::RealTime {
            deadline: Duration::ZERO,
        });
        w.submit(0, job(3, snapshot(1, true)));
        let answer = loop {
            if let Some(a) = w.collect().pop() {
                break a;
            }
            std::thread::yield_now();
        };
        assert!(
            matches!(answer.result, Err(PlanError::Timeout { .. })),
            "{:?}",
            answer.result
        );
    }

    #[test]
    fn the_planning_map_is_rebuilt_only_for_a_new_revision() {
        let mut maps = HashMap::new();
        let a = planning_map(&mut maps, 0, &snapshot(4, false), 0.0);
        let b = planning_map(&mut maps, 0, &snapshot(4, true), 0.0);
        assert!(Arc::ptr_eq(&a, &b), "same revision: cached");
        let c = planning_map(&mut maps, 0, &snapshot(5, true), 0.0);
        assert!(!Arc::ptr_eq(&a, &c));
        let d = planning_map(&mut maps, 1, &snapshot(5, true), 0.0);
        assert!(!Arc::ptr_eq(&c, &d), "one map per drone");
    }
}
