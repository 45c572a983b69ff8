//! The host's exploration service: the fleet's frontier allocator on its thread with the
//! questions of this tick, the exploration run started over the API (the last one), and the
//! true world its report is judged against.
//!
//! In: the drones' explore jobs, the merged map once a tick, the run's drones as they start and
//! stop, poses and whether each drone's mission still runs. Out: the allocator's answers, the
//! frontiers and claims it last published, the run (progress, samples) and what its report is
//! made of ([`ReportInput`]).

use super::explore::ReportInput;
use crate::exploration::offline::evaluate::TrueWorld;
use crate::exploration::online::progress::{
    DronePose, ExplorationRun, LiveReport, ProgressView, RunDrone,
};
use crate::exploration::online::service::{ClaimView, FrontierView, RemoteClaim};
use crate::exploration::online::worker::{ExploreJob, FrontierAnswer, FrontierWorker};
use crate::mapping::merged::FleetMap;
use crate::planning::worker::Delivery;
use std::time::Duration;

pub(super) struct ExplorationRuns {
    /// The fleet's frontier allocator on its thread, asked after every core ticked.
    frontiers: FrontierWorker,
    /// This tick's questions to the allocator, by drone index.
    jobs: Vec<(usize, ExploreJob)>,
    /// The exploration started over the API (`POST /api/exploration/start`), the last one.
    run: Option<ExplorationRun>,
    /// The true world the report judges runs against, handed in by whoever built the host over
    /// a simulated fleet or a virtual world; `None` in the real world.
    truth: Option<Box<TrueWorld>>,
}

impl ExplorationRuns {
    /// No run yet; the allocator answers in lock step until told otherwise.
    pub(super) fn new() -> Self {
        Self {
            frontiers: FrontierWorker::new(Delivery::Lockstep),
            jobs: Vec::new(),
            run: None,
            truth: None,
        }
    }

    /// How the allocator's answers reach the behaviors; a new delivery starts a new allocator.
    pub(super) fn set_delivery(&mut self, delivery: Delivery) {
        if self.frontiers.delivery() != delivery {
            self.frontiers = FrontierWorker::new(delivery);
        }
    }

    /// The merged map was replaced: the allocator is handed it whole next time.
    pub(super) fn resync(&mut self) {
        self.frontiers.resync();
    }

    /// Drone `drone`'s question, asked with the others after every core ticked.
    pub(super) fn queue(&mut self, drone: usize, job: ExploreJob) {
        self.jobs.push((drone, job));
    }

    /// Hands the allocator this tick's questions and the map's changes.
    pub(super) fn ask(&mut self, now: Duration, map: Option<&mut FleetMap>) {
        let jobs = std::mem::take(&mut self.jobs);
        self.frontiers.submit(now, jobs, map);
    }

    /// The allocator's answers due now.
    pub(super) fn collect(&mut self) -> Vec<FrontierAnswer> {
        self.frontiers.collect()
    }

    /// The goals of drones other Kestrel processes fly; each set replaces the last.
    pub(super) fn set_remote_claims(&mut self, claims: Vec<RemoteClaim>) {
        self.frontiers.set_remote_claims(claims);
    }

    pub(super) fn frontiers(&self) -> &[FrontierView] {
        self.frontiers.frontiers()
    }

    pub(super) fn claims(&self) -> &[ClaimView] {
        self.frontiers.claims()
    }

    /// The goal `drone` held when the allocator last answered.
    pub(super) fn claim_of(&self, drone: &str) -> Option<[f64; 2]> {
        self.claims()
            .iter()
            .find(|c| c.drone == drone)
            .map(|c| c.goal_enu_m)
    }

    pub(super) fn run(&self) -> Option<&ExplorationRun> {
        self.run.as_ref()
    }

    /// The run's mission of `drone`, unless it was stopped (whether that mission still runs is
    /// the executor's to say).
    pub(super) fn mission_of(&self, drone: &str) -> Option<u32> {
        let d = self.run()?.drones().iter().find(|d| d.drone == drone)?;
        (!d.stopped).then_some(d.mission_id)
    }

    /// `started` (drone, mission) join the run while it runs; otherwise they start a new one at
    /// `now`.
    pub(super) fn start(&mut self, now: Duration, started: Vec<(String, u32)>) -> &ExplorationRun {
        let run = match self.run.take() {
            Some(mut run) if !run.is_finished() => {
                run.join(started);
                run
            }
            _ => ExplorationRun::new(now, started),
        };
        self.run.insert(run)
    }

    /// Marks `drone` as stopped by an operator.
    pub(super) fn stop(&mut self, drone: &str) {
        if let Some(run) = self.run.as_mut() {
            run.stop(drone);
        }
    }

    /// One tick of the run, if one is going: the poses and the known area recorded (each asked
    /// only then); finished once none of its drones still exploring is `running` its mission.
    pub(super) fn record<'a>(
        &mut self,
        now: Duration,
        known_pct: impl FnOnce() -> Option<f64>,
        poses: impl FnOnce() -> Vec<DronePose<'a>>,
        running: impl Fn(&RunDrone) -> bool,
    ) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        if run.is_finished() {
            return;
        }
        run.record(now, known_pct, &poses());
        if !run.drones().iter().any(|d| !d.stopped && running(d)) {
            run.finish(now);
        }
    }

    /// Judges runs against `world` from now on.
    pub(super) fn set_truth(&mut self, world: TrueWorld) {
        self.truth = Some(Box::new(world));
    }

    /// What the run's report is made of, with its `progress` as the host sees it; `None`
    /// before any run.
    pub(super) fn report(
        &self,
        progress: ProgressView,
        known_pct: impl FnOnce() -> Option<f64>,
    ) -> Option<ReportInput> {
        let run = self.run()?;
        let (kept, dropped) = run.sample_counts();
        let live = LiveReport {
            path_m: progress.drones.iter().map(|d| d.path_m).sum(),
            progress,
            known_pct: known_pct(),
            frontiers_left: self.frontiers().len(),
            area_curve: run.curve().to_vec(),
            min_separation_m: run.min_separation_m(),
            pose_samples: kept,
            pose_samples_dropped: dropped,
        };
        Some(ReportInput {
            live,
            world: self.truth.as_deref().cloned(),
            samples: run.sample_chunks(),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::types::Vec3;

    fn s(t: u64) -> Duration {
        Duration::from_secs(t)
    }

    fn started(drones: &[(&str, u32)]) -> Vec<(String, u32)> {
        drones.iter().map(|(d, m)| (d.to_string(), *m)).collect()
    }

    fn pose(drone: &str) -> DronePose<'_> {
        DronePose {
            drone,
            position_enu_m: Vec3::zeros(),
            yaw_rad: 0.0,
            airborne: true,
        }
    }

    /// Drones started while a run goes join it (its start kept); once it finished, the next
    /// start is a new run.
    #[test]
    fn a_start_joins_a_running_run_or_starts_a_new_one() {
        let mut runs = ExplorationRuns::new();
        assert!(runs.run().is_none());
        runs.start(s(5), started(&[("drone_0", 1)]));
        let run = runs.start(s(9), started(&[("drone_1", 4)]));
        assert_eq!(run.started_at(), s(5));
        assert_eq!(run.drones().len(), 2);
        runs.record(s(10), || None, Vec::new, |_| false);
        assert!(runs.run().is_some_and(ExplorationRun::is_finished));
        let run = runs.start(s(20), started(&[("drone_1", 7)]));
        assert_eq!((run.started_at(), run.drones().len()), (s(20), 1));
    }

    /// A stopped drone has no mission in the run, and its mission running still does not keep
    /// the run going.
    #[test]
    fn a_stopped_drone_leaves_the_run() {
        let mut runs = ExplorationRuns::new();
        runs.start(s(0), started(&[("drone_0", 1), ("drone_1", 2)]));
        assert_eq!(runs.mission_of("drone_0"), Some(1));
        assert_eq!(runs.mission_of("drone_7"), None);
        runs.stop("drone_0");
        assert_eq!(runs.mission_of("drone_0"), None);
        runs.record(s(1), || None, Vec::new, |d| d.drone == "drone_1");
        assert!(!runs.run().unwrap().is_finished());
        runs.record(s(2), || None, Vec::new, |d| d.drone == "drone_0");
        assert!(runs.run().unwrap().is_finished());
    }

    /// A finished run records nothing more: neither poses nor the area are asked for.
    #[test]
    fn a_finished_run_asks_for_nothing() {
        let mut runs = ExplorationRuns::new();
        runs.record(s(0), || panic!("no run"), || panic!("no run"), |_| true);
        runs.start(s(0), started(&[("drone_0", 1)]));
        runs.record(s(0), || Some(12.5), || vec![pose("drone_0")], |_| false);
        let run = runs.run().unwrap();
        assert_eq!((run.curve().len(), run.sample_counts()), (1, (1, 0)));
        runs.record(s(3), || panic!("finished"), || panic!("finished"), |_| true);
    }

    /// The report is there once a run is, with the run's samples and the allocator's frontiers.
    #[test]
    fn the_report_needs_a_run() {
        let mut runs = ExplorationRuns::new();
        let run = ExplorationRun::new(s(0), Vec::new());
        let progress = || ProgressView::of(&run, s(0), Vec::new());
        assert!(runs.report(progress(), || Some(1.0)).is_none());
        runs.start(s(0), started(&[("drone_0", 1)]));
        runs.record(s(0), || Some(40.0), || vec![pose("drone_0")], |_| true);
        let report = runs.report(progress(), || Some(41.0)).unwrap();
        assert_eq!(report.live.known_pct, Some(41.0));
        assert_eq!(report.live.area_curve.len(), 1);
        assert_eq!(
            (report.live.pose_samples, report.live.frontiers_left),
            (1, 0)
        );
        assert!(report.world.is_none());
        assert_eq!(runs.claim_of("drone_0"), None);
    }

    /// The allocator is replaced only when the delivery changes.
    #[test]
    fn a_new_delivery_starts_a_new_allocator() {
        let mut runs = ExplorationRuns::new();
        runs.set_delivery(Delivery::Lockstep);
        assert_eq!(runs.frontiers.delivery(), Delivery::Lockstep);
        let real_time = Delivery::RealTime {
            deadline: Duration::from_millis(50),
        };
        runs.set_delivery(real_time);
        assert_eq!(runs.frontiers.delivery(), real_time);
    }
}
