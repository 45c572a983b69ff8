//! Smooth time-parameterised trajectory along a polyline of waypoints.
//!
//! In: waypoints (ENU metres), a cruise speed, an acceleration limit. Out: each tick, the
//! reference point, velocity and acceleration along the path. Speed is planned per corner (the
//! sharper the turn the slower, never zero at interior waypoints so the vehicle does not stop)
//! with forward/backward acceleration passes; the reference waits for the vehicle when it lags,
//! so a slow vehicle is never dragged into a corner cut.

use crate::types::Vec3;

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectoryLimits {
    pub cruise_speed_mps: f64,
    pub max_acceleration_mps2: f64,
    /// Lowest speed planned through an interior waypoint (a full reversal).
    pub min_corner_speed_mps: f64,
    /// When the vehicle is farther than this behind the reference, the reference waits.
    pub max_lag_m: f64,
}

impl Default for TrajectoryLimits {
    fn default() -> Self {
        Self {
            cruise_speed_mps: 1.0,
            max_acceleration_mps2: 1.5,
            min_corner_speed_mps: 0.15,
            max_lag_m: 0.3,
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TrajectorySample {
    pub position_enu_m: Vec3,
    pub velocity_enu_mps: Vec3,
    pub acceleration_enu_mps2: Vec3,
    /// Index of the next waypoint not yet passed by the reference.
    pub next_waypoint: usize,
    pub finished: bool,
}

#[derive(Debug, Clone)]
pub struct PathTrajectory {
    points: Vec<Vec3>,
    /// Arc length at each point.
    s_at: Vec<f64>,
    /// Planned speed at each point.
    v_at: Vec<f64>,
    limits: TrajectoryLimits,
    s: f64,
    /// Reference speed now; rises at most at the acceleration limit.
    v: f64,
    /// Acceleration of the last step, along the path.
    a: f64,
    /// Points before the waypoints besides the start: 1 when the reference brakes first.
    lead_in: usize,
}

/// Moving slower than this, a vehicle turns onto a reversed path without braking along its motion
/// first (m/s).
const REVERSAL_MIN_SPEED_MPS: f64 = 0.2;

impl PathTrajectory {
    /// `start` is where the vehicle is now; the path runs start -> waypoints[0] -> ... .
    /// Consecutive duplicate points are dropped.
    pub fn new(start: Vec3, waypoints: &[Vec3], limits: TrajectoryLimits) -> Self {
        Self::moving(start, Vec3::zeros(), waypoints, limits)
    }

    /// The same from a vehicle already moving at `velocity_enu_mps`: the reference starts at the
    /// part of that velocity along the first segment (at most the cruise speed, and no more than
    /// allows stopping at the end), so a new path taken in flight does not brake first. A path
    /// that starts against the motion (a turn of more than 90 degrees) starts with the braking
    /// along the motion, then turns back.
    pub fn moving(
        start: Vec3,
        velocity_enu_mps: Vec3,
        waypoints: &[Vec3],
        limits: TrajectoryLimits,
    ) -> Self {
        let mut points = vec![start];
        // A vehicle moving against the first leg cannot turn on the spot: the reference first
        // brakes along the motion (where the vehicle goes anyway) and comes back, so the vehicle
        // follows it instead of cutting across from where it overshot to where the reference
        // went (a corner cut that can take it inside the path's clearance).
        let speed = velocity_enu_mps.norm().min(limits.cruise_speed_mps);
        let first_leg = waypoints
            .iter()
            .map(|w| w - start)
            .find(|leg| leg.norm() > 1e-6);
        let brakes_first = speed > REVERSAL_MIN_SPEED_MPS
            && first_leg.is_some_and(|leg| leg.dot(&velocity_enu_mps) < 0.0);
        if brakes_first {
            let braking_m = speed * speed / (2.0 * limits.max_acceleration_mps2.max(0.1));
            points.push(start + velocity_enu_mps.normalize() * braking_m);
        }
        for w in waypoints {
            if points.last().is_none_or(|p| (p - w).norm() > 1e-6) {
                points.push(*w);
            }
        }
        let mut s_at = vec![0.0];
        for pair in points.windows(2) {
            let last = s_at.last().copied().unwrap_or(0.0);
            s_at.push(last + (pair[1] - pair[0]).norm());
        }
        let initial = match (points.first(), points.get(1)) {
            (Some(a), Some(b)) => (b - a)
                .try_normalize(1e-9)
                .map_or(0.0, |d| velocity_enu_mps.dot(&d))
                .clamp(0.0, limits.cruise_speed_mps),
            _ => 0.0,
        };
        let v_at = plan_speeds(&points, &s_at, &limits, initial);
        let v = v_at.first().copied().unwrap_or(0.0);
        Self {
            points,
            s_at,
            v_at,
            limits,
            s: 0.0,
            v,
            a: 0.0,
            lead_in: usize::from(brakes_first),
        }
    }

    pub fn length_m(&self) -> f64 {
        self.s_at.last().copied().unwrap_or(0.0)
    }

    pub fn remaining_m(&self) -> f64 {
        (self.length_m() - self.s).max(0.0)
    }

    /// Number of input waypoints (excluding the start point and a braking lead-in).
    pub fn waypoint_count(&self) -> usize {
        self.points.len().saturating_sub(1 + self.lead_in)
    }

    pub fn final_point(&self) -> Vec3 {
        self.points.last().copied().unwrap_or_else(Vec3::zeros)
    }

    /// Advances the reference by `dt_s` and returns it. `vehicle_m` is the current position, used
    /// only to hold the reference back when the vehicle lags.
    pub fn advance(&mut self, dt_s: f64, vehicle_m: &Vec3) -> TrajectorySample {
        let here = self.position_at(self.s);
        let lag = (here - vehicle_m).norm();
        let warp = if lag > self.limits.max_lag_m {
            (2.0 - lag / self.limits.max_lag_m).max(0.0)
        } else {
            1.0
        };
        let allowed = self.speed_at(self.s) * warp;
        let v = allowed.min(self.v + self.limits.max_acceleration_mps2 * dt_s);
        self.a = if dt_s > 0.0 { (v - self.v) / dt_s } else { 0.0 };
        self.v = v;
        self.s = (self.s + v * dt_s).min(self.length_m());
        self.sample()
    }

    pub fn sample(&self) -> TrajectorySample {
        let seg = self.segment_at(self.s);
        let direction = self.direction(seg);
        TrajectorySample {
            position_enu_m: self.position_at(self.s),
            velocity_enu_mps: direction * self.v,
            acceleration_enu_mps2: direction * self.a,
            next_waypoint: seg.saturating_sub(self.lead_in),
            finished: self.s >= self.length_m() - 1e-9,
        }
    }

    /// Index of the segment containing arc length `s` (segment i runs from point i to i+1).
    fn segment_at(&self, s: f64) -> usize {
        let n = self.s_at.len();
        if n < 2 {
            return 0;
        }
        match self.s_at.iter().position(|&si| si > s) {
            Some(i) => i.saturating_sub(1).min(n - 2),
            None => n - 2,
        }
    }

    fn direction(&self, seg: usize) -> Vec3 {
        match (self.points.get(seg), self.points.get(seg + 1)) {
            (Some(a), Some(b)) => (b - a).try_normalize(1e-9).unwrap_or_else(Vec3::zeros),
            _ => Vec3::zeros(),
        }
    }

    fn position_at(&self, s: f64) -> Vec3 {
        let seg = self.segment_at(s);
        match (self.points.get(seg), self.s_at.get(seg)) {
            (Some(p), Some(s0)) => p + self.direction(seg) * (s - s0),
            _ => self.final_point(),
        }
    }

    /// Speed allowed at arc length `s`: cruise, or the accel-limited ramp to the next/previous corner.
    fn speed_at(&self, s: f64) -> f64 {
        let seg = self.segment_at(s);
        let a = self.limits.max_acceleration_mps2;
        let (s0, s1) = (
            self.s_at.get(seg).copied().unwrap_or(0.0),
            self.s_at.get(seg + 1).copied().unwrap_or(0.0),
        );
        let (v0, v1) = (
            self.v_at.get(seg).copied().unwrap_or(0.0),
            self.v_at.get(seg + 1).copied().unwrap_or(0.0),
        );
        let from_start = (v0 * v0 + 2.0 * a * (s - s0).max(0.0)).sqrt();
        let to_end = (v1 * v1 + 2.0 * a * (s1 - s).max(0.0)).sqrt();
        // Never zero before the end, or the reference would stall at the start.
        let floor = if s < self.length_m() - 1e-9 {
            self.limits
                .min_corner_speed_mps
                .min(self.limits.cruise_speed_mps)
        } else {
            0.0
        };
        self.limits
            .cruise_speed_mps
            .min(from_start)
            .min(to_end)
            .max(floor)
    }
}

/// Corner speeds from the turn angle, then forward/backward passes for the acceleration limit.
fn plan_speeds(points: &[Vec3], s_at: &[f64], limits: &TrajectoryLimits, initial: f64) -> Vec<f64> {
    let n = points.len();
    let cruise = limits.cruise_speed_mps;
    let mut v = vec![cruise; n];
    if let Some(first) = v.first_mut() {
        *first = initial;
    }
    if let Some(last) = v.last_mut() {
        *last = 0.0;
    }
    for i in 1..n.saturating_sub(1) {
        let a = (points[i] - points[i - 1]).try_normalize(1e-9);
        let b = (points[i + 1] - points[i]).try_normalize(1e-9);
        if let (Some(a), Some(b)) = (a, b) {
            // cos of the turn: 1 straight on, -1 full reversal.
            let cos_turn = a.dot(&b).clamp(-1.0, 1.0);
            let factor = ((1.0 + cos_turn) / 2.0).powi(2);
            v[i] = (cruise * factor)
                .max(limits.min_corner_speed_mps)
                .min(cruise);
        }
    }
    let a = limits.max_acceleration_mps2;
    for i in 1..n {
        let ds = s_at[i] - s_at[i - 1];
        v[i] = v[i].min((v[i - 1] * v[i - 1] + 2.0 * a * ds).sqrt());
    }
    for i in (0..n.saturating_sub(1)).rev() {
        let ds = s_at[i + 1] - s_at[i];
        v[i] = v[i].min((v[i + 1] * v[i + 1] + 2.0 * a * ds).sqrt());
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fly_perfectly(traj: &mut PathTrajectory, dt: f64) -> (Vec<TrajectorySample>, f64) {
        let mut samples = Vec::new();
        let mut t = 0.0;
        let mut pos = traj.sample().position_enu_m;
        while t < 1000.0 {
            let s = traj.advance(dt, &pos);
            pos = s.position_enu_m;
            samples.push(s);
            t += dt;
            if s.finished {
                break;
            }
        }
        (samples, t)
    }

    #[test]
    fn straight_line_reaches_cruise_and_respects_acceleration() {
        let limits = TrajectoryLimits {
            cruise_speed_mps: 2.0,
            max_acceleration_mps2: 1.0,
            ..Default::default()
        };
        let mut traj = PathTrajectory::new(Vec3::zeros(), &[Vec3::new(20.0, 0.0, 0.0)], limits);
        let (samples, t) = fly_perfectly(&mut traj, 0.01);
        let vmax = samples
            .iter()
            .map(|s| s.velocity_enu_mps.norm())
            .fold(0.0, f64::max);
        assert!((vmax - 2.0).abs() < 1e-6);
        // 20 m at 2 m/s with 2 s ramps each end: 10 s + 2 s = 12 s.
        assert!((t - 12.0).abs() < 0.3, "took {t}");
        for w in samples.windows(2) {
            let dv = (w[1].velocity_enu_mps.norm() - w[0].velocity_enu_mps.norm()).abs() / 0.01;
            assert!(dv < 1.0 + 0.2, "acceleration {dv} exceeds the limit");
        }
        let last = samples.last().unwrap();
        assert!((last.position_enu_m - Vec3::new(20.0, 0.0, 0.0)).norm() < 1e-9);
    }

    #[test]
    fn interior_waypoints_are_passed_without_stopping() {
        let wps = [
            Vec3::new(5.0, 0.0, 0.0),
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(10.0, 5.0, 0.0),
        ];
        let limits = TrajectoryLimits {
            cruise_speed_mps: 1.0,
            ..Default::default()
        };
        let mut traj = PathTrajectory::new(Vec3::zeros(), &wps, limits);
        let (samples, _) = fly_perfectly(&mut traj, 0.01);
        let n = samples.len();
        let min_mid = samples[n / 10..n * 9 / 10]
            .iter()
            .map(|s| s.velocity_enu_mps.norm())
            .fold(f64::MAX, f64::min);
        assert!(
            min_mid >= 0.2,
            "speed dropped to {min_mid} in the middle of the path"
        );
        for w in &wps {
            let closest = samples
                .iter()
                .map(|s| (s.position_enu_m - w).norm())
                .fold(f64::MAX, f64::min);
            assert!(closest < 0.02, "waypoint {w} missed by {closest}");
        }
    }

    /// Speed of the reference where it passes closest to `point`.
    fn speed_near(samples: &[TrajectorySample], point: &Vec3) -> f64 {
        samples
            .iter()
            .min_by(|a, b| {
                let da = (a.position_enu_m - point).norm();
                let db = (b.position_enu_m - point).norm();
                da.total_cmp(&db)
            })
            .map(|s| s.velocity_enu_mps.norm())
            .unwrap()
    }

    #[test]
    fn sharper_corners_are_taken_slower_but_never_stopped_at() {
        let limits = TrajectoryLimits {
            cruise_speed_mps: 2.0,
            ..Default::default()
        };
        // A 45 deg turn, then a 135 deg turn.
        let gentle = Vec3::new(10.0, 0.0, 0.0);
        let sharp = Vec3::new(20.0, 10.0, 0.0);
        let wps = [gentle, sharp, Vec3::new(10.0, 10.0, 0.0)];
        let mut traj = PathTrajectory::new(Vec3::zeros(), &wps, limits);
        let (samples, _) = fly_perfectly(&mut traj, 0.01);
        let (v_gentle, v_sharp) = (speed_near(&samples, &gentle), speed_near(&samples, &sharp));
        assert!(v_gentle > v_sharp, "{v_gentle} vs {v_sharp}");
        assert!(v_sharp >= limits.min_corner_speed_mps - 1e-9, "{v_sharp}");
        assert!(
            v_gentle < limits.cruise_speed_mps,
            "slows for a turn at all"
        );
    }

    #[test]
    fn speed_changes_respect_the_acceleration_limit_through_corners() {
        let limits = TrajectoryLimits {
            cruise_speed_mps: 3.0,
            max_acceleration_mps2: 1.0,
            ..Default::default()
        };
        let wps = [
            Vec3::new(8.0, 0.0, 0.0),
            Vec3::new(8.0, 8.0, 2.0),
            Vec3::new(0.0, 8.0, 2.0),
            Vec3::new(0.0, 0.0, 0.0),
        ];
        let mut traj = PathTrajectory::new(Vec3::zeros(), &wps, limits);
        let (samples, _) = fly_perfectly(&mut traj, 0.01);
        for w in samples.windows(2) {
            let dv = (w[1].velocity_enu_mps.norm() - w[0].velocity_enu_mps.norm()).abs() / 0.01;
            assert!(dv < 1.0 + 0.2, "speed changed at {dv} m/s^2");
        }
        assert!(samples.last().unwrap().finished);
        assert!(samples.last().unwrap().velocity_enu_mps.norm() < 0.2);
    }

    #[test]
    fn duplicate_waypoints_are_dropped() {
        let p = Vec3::new(3.0, 4.0, 0.0);
        let traj = PathTrajectory::new(Vec3::zeros(), &[p, p, p], TrajectoryLimits::default());
        assert_eq!(traj.waypoint_count(), 1);
        assert!((traj.length_m() - 5.0).abs() < 1e-12);
        let here = PathTrajectory::new(p, &[p], TrajectoryLimits::default());
        assert_eq!(here.length_m(), 0.0);
        assert!(here.sample().finished);
    }

    #[test]
    fn reference_waits_for_a_lagging_vehicle() {
        let mut traj = PathTrajectory::new(
            Vec3::zeros(),
            &[Vec3::new(10.0, 0.0, 0.0)],
            TrajectoryLimits::default(),
        );
        let stuck = Vec3::zeros();
        for _ in 0..2000 {
            traj.advance(0.01, &stuck);
        }
        let s = traj.sample();
        assert!(
            s.position_enu_m.x <= 2.0 * TrajectoryLimits::default().max_lag_m + 1e-9,
            "ran away to {}",
            s.position_enu_m.x
        );
    }
    #[test]
    fn a_path_against_the_motion_brakes_along_it_first_then_turns_back() {
        let limits = TrajectoryLimits {
            cruise_speed_mps: 0.75,
            ..TrajectoryLimits::default()
        };
        let back = [Vec3::new(-3.0, 0.0, 0.0)];
        let mut traj =
            PathTrajectory::moving(Vec3::zeros(), Vec3::new(0.75, 0.0, 0.0), &back, limits);
        assert_eq!(traj.waypoint_count(), 1);
        let first = traj.sample();
        assert!((first.velocity_enu_mps.x - 0.75).abs() < 1e-9, "{first:?}");
        let (samples, _) = fly_perfectly(&mut traj, 0.01);
        let farthest = samples
            .iter()
            .map(|s| s.position_enu_m.x)
            .fold(f64::NEG_INFINITY, f64::max);
        // 0.75^2 / (2 * 1.5) = 0.1875 m of braking, and never sideways.
        assert!((farthest - 0.1875).abs() < 0.01, "{farthest}");
        assert!(samples.iter().all(|s| s.position_enu_m.y.abs() < 1e-9));
        let last = samples.last().unwrap();
        assert!(last.finished && (last.position_enu_m.x + 3.0).abs() < 1e-6);
        assert!(samples.iter().all(|s| s.next_waypoint == 0));
        // Moving along the path, or a turn of less than 90 degrees: no lead-in.
        let ahead = PathTrajectory::moving(
            Vec3::zeros(),
            Vec3::new(0.0, 0.5, 0.0),
            &[Vec3::new(2.0, 1.0, 0.0)],
            limits,
        );
        assert!((ahead.length_m() - 5.0_f64.sqrt()).abs() < 1e-9);
        // Slower than the threshold: no lead-in either.
        let slow = PathTrajectory::moving(Vec3::zeros(), Vec3::new(0.1, 0.0, 0.0), &back, limits);
        assert!((slow.length_m() - 3.0).abs() < 1e-9);
    }
}
