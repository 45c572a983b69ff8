//! An exploration run as operators follow it: which drones explore since when, the known area
//! over time, the path each drone flew, the least separation seen, and an estimate of the time
//! left. Plain data, stepped by the host with the time and the fleet's poses; no I/O.
//!
//! In: `record(now, known_pct, poses)` every tick (a pose sample every [`POSE_EVERY`], an area
//! point every [`CURVE_EVERY`]), `finish(now)` when no drone of the run explores any more.
//! Out: the elapsed time, the area curve, [`ExplorationRun::remaining_s`], per-drone paths and
//! the pose samples the evaluator (`exploration::offline::evaluate`) can judge against a true world.

use std::sync::Arc;
use std::time::Duration;

use serde::Serialize;

use super::super::offline::evaluate::{CurvePoint, PoseSample};
use crate::types::Vec3;

/// Spacing of the pose samples kept for paths, separation and the evaluator.
pub const POSE_EVERY: Duration = Duration::from_millis(100);
/// Spacing of the points of the area curve.
pub const CURVE_EVERY: Duration = Duration::from_secs(1);
/// The area rate of the estimate is measured over this much of the latest curve.
pub const RATE_WINDOW: Duration = Duration::from_secs(30);
/// No estimate before the curve spans this long.
pub const RATE_MIN_SPAN: Duration = Duration::from_secs(10);
/// Most pose samples kept (about 14 h of one drone at 10 Hz); later ones are counted, not kept.
pub const MAX_SAMPLES: usize = 500_000;
/// Pose samples are kept in shared chunks of this many, so a report copies only the last one.
const CHUNK: usize = 8192;

/// One drone's pose at a tick, as the host hands it in.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DronePose<'a> {
    pub drone: &'a str,
    pub position_enu_m: Vec3,
    pub yaw_rad: f64,
    /// Armed and in the air.
    pub airborne: bool,
}

/// A drone of the run.
#[derive(Debug, Clone, PartialEq)]
pub struct RunDrone {
    pub drone: String,
    /// The mission its `explore` item runs in.
    pub mission_id: u32,
    /// Stopped by an operator (not finished by itself).
    pub stopped: bool,
    /// Horizontal path flown since it joined the run (m).
    pub path_m: f64,
    last_xy: Option<[f64; 2]>,
}

/// The run, from its start to the moment no drone of it explores any more.
#[derive(Debug, Clone, PartialEq)]
pub struct ExplorationRun {
    started_at: Duration,
    ended_at: Option<Duration>,
    drones: Vec<RunDrone>,
    curve: Vec<CurvePoint>,
    /// Full chunks of pose samples, shared with reports.
    chunks: Vec<Arc<[PoseSample]>>,
    /// The chunk being filled.
    open_chunk: Vec<PoseSample>,
    samples_kept: usize,
    samples_dropped: usize,
    min_separation_m: Option<f64>,
    next_pose: Duration,
    next_curve: Duration,
}

impl ExplorationRun {
    /// A run started at `now` by `drones` (drone id, mission id).
    pub fn new(now: Duration, drones: Vec<(String, u32)>) -> Self {
        let mut run = Self {
            started_at: now,
            ended_at: None,
            drones: Vec::new(),
            curve: Vec::new(),
            chunks: Vec::new(),
            open_chunk: Vec::new(),
            samples_kept: 0,
            samples_dropped: 0,
            min_separation_m: None,
            next_pose: now,
            next_curve: now,
        };
        run.join(drones);
        run
    }

    /// More drones join the running exploration (a drone already in it starts over as active).
    pub fn join(&mut self, drones: Vec<(String, u32)>) {
        for (drone, mission_id) in drones {
            self.drones.retain(|d| d.drone != drone);
            self.drones.push(RunDrone {
                drone,
                mission_id,
                stopped: false,
                path_m: 0.0,
                last_xy: None,
            });
        }
        self.ended_at = None;
    }

    pub fn drones(&self) -> &[RunDrone] {
        &self.drones
    }

    /// Marks a drone as stopped by an operator.
    pub fn stop(&mut self, drone: &str) {
        if let Some(d) = self.drones.iter_mut().find(|d| d.drone == drone) {
            d.stopped = true;
        }
    }

    /// No drone of the run explores any more: the clock stops (once).
    pub fn finish(&mut self, now: Duration) {
        self.ended_at.get_or_insert(now);
    }

    pub fn is_finished(&self) -> bool {
        self.ended_at.is_some()
    }

    pub fn started_at(&self) -> Duration {
        self.started_at
    }

    /// Time since the start, up to the end once finished.
    pub fn elapsed(&self, now: Duration) -> Duration {
        self.ended_at.unwrap_or(now).saturating_sub(self.started_at)
    }

    /// Records this tick: a pose sample of the run's drones every [`POSE_EVERY`] and a point of
    /// the area curve every [`CURVE_EVERY`] (`known_pct` is asked only then). Nothing once
    /// finished.
    pub fn record(
        &mut self,
        now: Duration,
        known_pct: impl FnOnce() -> Option<f64>,
        poses: &[DronePose],
    ) {
        if self.is_finished() {
            return;
        }
        if now >= self.next_curve {
            self.next_curve = now + CURVE_EVERY;
            if let Some(pct) = known_pct() {
                self.curve.push(CurvePoint {
                    t_s: now.saturating_sub(self.started_at).as_secs_f64(),
                    area_pct: pct,
                });
            }
        }
        if now < self.next_pose {
            return;
        }
        self.next_pose = now + POSE_EVERY;
        let ours: Vec<&DronePose> = poses
            .iter()
            .filter(|p| self.drones.iter().any(|d| d.drone == p.drone && !d.stopped))
            .collect();
        for p in &ours {
            let xy = [p.position_enu_m.x, p.position_enu_m.y];
            if let Some(d) = self.drones.iter_mut().find(|d| d.drone == p.drone) {
                if let Some([x, y]) = d.last_xy {
                    d.path_m += (xy[0] - x).hypot(xy[1] - y);
                }
                d.last_xy = Some(xy);
            }
            if self.samples_kept < MAX_SAMPLES {
                self.samples_kept += 1;
                self.open_chunk.push(PoseSample {
                    t_s: now.as_secs_f64(),
                    drone: p.drone.to_string(),
                    x_m: p.position_enu_m.x,
                    y_m: p.position_enu_m.y,
                    z_m: p.position_enu_m.z,
                    yaw_rad: p.yaw_rad,
                    crashed: false,
                });
                if self.open_chunk.len() >= CHUNK {
                    self.chunks
                        .push(std::mem::take(&mut self.open_chunk).into());
                }
            } else {
                self.samples_dropped += 1;
            }
        }
        let flying: Vec<&&DronePose> = ours.iter().filter(|p| p.airborne).collect();
        for (i, a) in flying.iter().enumerate() {
            for b in flying.iter().skip(i + 1) {
                let d = (a.position_enu_m - b.position_enu_m).norm();
                if self.min_separation_m.is_none_or(|m| d < m) {
                    self.min_separation_m = Some(d);
                }
            }
        }
    }

    /// Known area over time (`t_s` from the start).
    pub fn curve(&self) -> &[CurvePoint] {
        &self.curve
    }

    /// Growth of the known area over the last [`RATE_WINDOW`] (% per second); `None` before
    /// the curve spans [`RATE_MIN_SPAN`].
    pub fn area_rate_pct_per_s(&self) -> Option<f64> {
        let last = self.curve.last()?;
        let from = last.t_s - RATE_WINDOW.as_secs_f64();
        let first = self.curve.iter().find(|p| p.t_s >= from)?;
        let span = last.t_s - first.t_s;
        (span >= RATE_MIN_SPAN.as_secs_f64()).then(|| (last.area_pct - first.area_pct) / span)
    }

    /// Estimated time left: the unknown share of the map over the area rate of the last
    /// [`RATE_WINDOW`]. An upper bound when obstacles hide part of the map (their insides never
    /// become known); `None` before [`RATE_MIN_SPAN`] of data or while the area does not grow;
    /// zero once finished.
    pub fn remaining_s(&self) -> Option<f64> {
        if self.is_finished() {
            return Some(0.0);
        }
        let rate = self.area_rate_pct_per_s().filter(|r| *r > 1e-6)?;
        let known = self.curve.last()?.area_pct;
        Some(((100.0 - known) / rate).max(0.0))
    }

    /// Least 3-D distance between two airborne drones of the run, sampled (m).
    pub fn min_separation_m(&self) -> Option<f64> {
        self.min_separation_m
    }

    /// Pose samples kept and not kept (over [`MAX_SAMPLES`]).
    pub fn sample_counts(&self) -> (usize, usize) {
        (self.samples_kept, self.samples_dropped)
    }

    /// The pose samples kept, in order, as shared chunks: cheap to hand over (only the chunk
    /// being filled is copied).
    pub fn sample_chunks(&self) -> Vec<Arc<[PoseSample]>> {
        let mut out = self.chunks.clone();
        if !self.open_chunk.is_empty() {
            out.push(self.open_chunk.as_slice().into());
        }
        out
    }
}

/// How a drone of the run is doing, for operators.
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct RunDroneView {
    pub drone: String,
    pub mission_id: u32,
    /// The explore behavior's phase while it runs (`takeoff`, `navigating`, `sensing`,
    /// `drone_avoidance`, `end`), `paused`, or how its item ended (`succeeded`, `failed`,
    /// `aborted`, `stopped`).
    pub phase: String,
    /// The frontier goal it holds now (ENU m).
    pub goal_enu_m: Option<[f64; 2]>,
    /// Horizontal path flown since it joined the run (m).
    pub path_m: f64,
}

/// Progress of the exploration run (`GET /api/exploration`, `progress`).
#[derive(Debug, Clone, PartialEq, Serialize, utoipa::ToSchema)]
pub struct ProgressView {
    /// Host time of the start (s).
    pub started_at_s: f64,
    /// Since the start, up to the end once finished (s).
    pub elapsed_s: f64,
    /// No drone of the run explores any more.
    pub finished: bool,
    /// Growth of the known area over the last 30 s (% per minute).
    pub area_rate_pct_per_min: Option<f64>,
    /// Estimated time left (s): the unknown share of the map over the area rate of the last
    /// 30 s; an upper bound when obstacles hide part of the map; null before 10 s of data or
    /// while the area does not grow; 0 once finished.
    pub remaining_s: Option<f64>,
    pub drones: Vec<RunDroneView>,
}

impl ProgressView {
    pub fn of(run: &ExplorationRun, now: Duration, drones: Vec<RunDroneView>) -> Self {
        Self {
            started_at_s: run.started_at().as_secs_f64(),
            elapsed_s: run.elapsed(now).as_secs_f64(),
            finished: run.is_finished(),
            area_rate_pct_per_min: run.area_rate_pct_per_s().map(|r| r * 60.0),
            remaining_s: run.remaining_s(),
            drones,
        }
    }
}

/// The report computable while it runs (`GET /api/exploration/report`), before the evaluator's
/// metrics against a true world are added.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct LiveReport {
    #[serde(flatten)]
    pub progress: ProgressView,
    /// Known cells of the merged map (%).
    pub known_pct: Option<f64>,
    pub frontiers_left: usize,
    /// Known area over time, `t_s` from the start, one point a second.
    pub area_curve: Vec<CurvePoint>,
    /// Sum of the drones' horizontal paths (m).
    pub path_m: f64,
    /// Least 3-D distance between two airborne drones of the run, sampled at 10 Hz (m).
    pub min_separation_m: Option<f64>,
    pub pose_samples: usize,
    /// Pose samples not kept (over the limit); the evaluator saw only the first ones.
    pub pose_samples_dropped: usize,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn pose(drone: &str, x: f64, airborne: bool) -> DronePose<'_> {
        DronePose {
            drone,
            position_enu_m: Vec3::new(x, 0.0, 1.0),
            yaw_rad: 0.0,
            airborne,
        }
    }

    #[test]
    fn paths_separation_and_the_estimate_follow_the_samples() {
        let mut run = ExplorationRun::new(Duration::ZERO, vec![("a".into(), 1), ("b".into(), 2)]);
        // Twenty seconds: the area grows 1 % a second, `a` flies 0.1 m a sample, `b` stays.
        for k in 0..=200u32 {
            let now = POSE_EVERY * k;
            let x = 0.1 * f64::from(k);
            let pct = 10.0 + now.as_secs_f64();
            run.record(
                now,
                || Some(pct),
                &[pose("a", x, true), pose("b", 30.0, true)],
            );
        }
        assert_eq!(run.curve().len(), 21);
        let a = &run.drones()[0];
        assert!((a.path_m - 20.0).abs() < 1e-6, "{}", a.path_m);
        assert_eq!(run.drones()[1].path_m, 0.0);
        // Closest at the end: a at 20 m, b at 30 m.
        assert!((run.min_separation_m().unwrap() - 10.0).abs() < 1e-6);
        let rate = run.area_rate_pct_per_s().unwrap();
        assert!((rate - 1.0).abs() < 1e-9, "{rate}");
        // 30 % known, 70 % left at 1 %/s.
        assert!((run.remaining_s().unwrap() - 70.0).abs() < 1e-6);
        assert_eq!(run.sample_counts(), (402, 0));
        let chunks = run.sample_chunks();
        assert_eq!(chunks.iter().map(|c| c.len()).sum::<usize>(), 402);
        assert_eq!(
            chunks.first().and_then(|c| c.first()).map(|p| p.t_s),
            Some(0.0)
        );
        run.finish(Duration::from_secs(25));
        assert_eq!(run.remaining_s(), Some(0.0));
        assert_eq!(
            run.elapsed(Duration::from_secs(99)),
            Duration::from_secs(25)
        );
    }

    #[test]
    fn samples_over_several_chunks_come_back_in_order() {
        let mut run = ExplorationRun::new(Duration::ZERO, vec![("a".into(), 1)]);
        let n = u32::try_from(CHUNK).unwrap() + 10;
        for k in 0..n {
            run.record(
                POSE_EVERY * k,
                || Some(1.0),
                &[pose("a", f64::from(k), true)],
            );
        }
        let chunks = run.sample_chunks();
        assert_eq!(chunks.len(), 2);
        let xs: Vec<f64> = chunks
            .iter()
            .flat_map(|c| c.iter().map(|p| p.x_m))
            .collect();
        assert_eq!(xs.len(), CHUNK + 10);
        assert!(xs.windows(2).all(|w| w[1] == w[0] + 1.0));
    }

    #[test]
    fn no_estimate_too_early_or_while_nothing_grows_and_stopped_drones_are_not_sampled() {
        let mut run = ExplorationRun::new(Duration::from_secs(5), vec![("a".into(), 1)]);
        for k in 0..50u32 {
            let now = Duration::from_secs(5) + POSE_EVERY * k;
            run.record(now, || Some(40.0 + f64::from(k)), &[pose("a", 0.0, true)]);
        }
        assert_eq!(run.remaining_s(), None, "under 10 s of curve");
        let mut flat = ExplorationRun::new(Duration::ZERO, vec![("a".into(), 1)]);
        for k in 0..200u32 {
            flat.record(POSE_EVERY * k, || Some(40.0), &[pose("a", 0.0, false)]);
        }
        assert_eq!(flat.remaining_s(), None, "the area does not grow");
        assert_eq!(flat.min_separation_m(), None, "one drone");
        flat.stop("a");
        let before = flat.sample_counts().0;
        flat.record(
            Duration::from_secs(60),
            || Some(40.0),
            &[pose("a", 1.0, true)],
        );
        assert_eq!(flat.sample_counts().0, before);
    }
}
