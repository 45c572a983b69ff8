//! What the drones flew against the limits a run was given: horizontal speed, yaw rate and
//! height flown, clearance to obstacles and separation between drones.
//!
//! In: the [`Tracks`] (true poses where the log has them), the least clearance and separation
//! the motion module measured, and [`FlightLimits`]. Out: [`Flown`]: the maxima (and p99) of
//! speed and yaw rate, the heights, every limit broken in words, and whether all held.
//!
//! Speed and yaw rate are measured over a window of log time (`window_s`), from the positions
//! and headings themselves: a log's reported velocity is the autopilot's belief, and a 10 Hz
//! difference of a real estimate's positions is mostly its noise. Only pairs of airborne
//! samples count, and no pair spans a gap in the log longer than [`MAX_GAP_S`].

use super::motion::Tracks;
use super::PoseSample;
use serde::Serialize;
use std::f64::consts::{PI, TAU};

/// A pair of samples further apart in time than this is a gap in the log, not a motion (s).
const MAX_GAP_S: f64 = 1.0;

/// The limits a run is judged against. Defaults are the thesis's (issue "Exploration, honestly
/// twice as fast as the thesis", item 2).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FlightLimits {
    /// Horizontal speed (m/s).
    pub speed_mps: f64,
    /// Yaw rate (rad/s).
    pub yaw_rate_radps: f64,
    /// Share by which a speed or yaw rate may exceed its limit (0.03: 3 %).
    pub tolerance: f64,
    /// Least distance from a drone's centre to an obstacle's surface (m).
    pub clearance_m: f64,
    /// Least 3-D distance between two airborne drones (m).
    pub separation_m: f64,
    /// Log time over which speed and yaw rate are measured (s).
    pub window_s: f64,
}

impl Default for FlightLimits {
    fn default() -> Self {
        Self {
            speed_mps: 0.75,
            yaw_rate_radps: 0.15,
            tolerance: 0.03,
            clearance_m: 0.4,
            separation_m: 2.0,
            window_s: 0.3,
        }
    }
}

impl FlightLimits {
    /// The first parameter out of range, by name.
    pub fn check(&self) -> Result<(), &'static str> {
        let within = |v: f64, lo: f64, hi: f64| v.is_finite() && (lo..=hi).contains(&v);
        for (ok, name) in [
            (within(self.speed_mps, 0.01, 100.0), "limits.speed_mps"),
            (within(self.yaw_rate_radps, 0.01, 100.0), "limits.yaw_rate_radps"),
            (within(self.tolerance, 0.0, 1.0), "limits.tolerance"),
            (within(self.clearance_m, 0.0, 100.0), "limits.clearance_m"),
            (within(self.separation_m, 0.0, 1000.0), "limits.separation_m"),
            (within(self.window_s, 0.05, MAX_GAP_S), "limits.window_s"),
        ] {
            if !ok {
                return Err(name);
            }
        }
        Ok(())
    }
}

/// What was flown, against [`FlightLimits`].
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Flown {
    pub limits: FlightLimits,
    /// Fastest horizontal speed over any window (m/s); none without two airborne samples.
    pub max_speed_mps: Option<f64>,
    pub p99_speed_mps: Option<f64>,
    /// Windows over `speed_mps` + tolerance / all windows x 100.
    pub over_speed_pct: f64,
    /// Fastest turn over any window (rad/s).
    pub max_yaw_rate_radps: Option<f64>,
    pub p99_yaw_rate_radps: Option<f64>,
    /// Windows over `yaw_rate_radps` + tolerance / all windows x 100.
    pub over_yaw_rate_pct: f64,
    /// Median height of the airborne samples (m).
    pub cruise_height_m: Option<f64>,
    pub max_height_m: Option<f64>,
    /// Every limit broken, in words ("horizontal speed 0.83 m/s over 0.7725 m/s (0.75 + 3 %)").
    pub breaches: Vec<String>,
    /// No limit broken.
    pub held: bool,
}

/// Judges `tracks` (airborne above `airborne_z_m`) against `limits`; `clearance_m` and
/// `separation_m` are the least ones measured (none: nothing to measure).
pub fn judge(
    tracks: &Tracks,
    airborne_z_m: f64,
    clearance_m: Option<f64>,
    separation_m: Option<f64>,
    limits: &FlightLimits,
) -> Flown {
    let mut speeds = Vec::new();
    let mut yaw_rates = Vec::new();
    let mut heights = Vec::new();
    for track in tracks.drones() {
        let airborne: Vec<&PoseSample> = track
            .samples
            .iter()
            .filter(|s| s.z_m > airborne_z_m)
            .collect();
        heights.extend(airborne.iter().map(|s| s.z_m));
        for (a, b) in windows(&airborne, limits.window_s) {
            let dt = b.t_s - a.t_s;
            speeds.push((b.x_m - a.x_m).hypot(b.y_m - a.y_m) / dt);
            yaw_rates.push(wrapped(b.yaw_rad - a.yaw_rad).abs() / dt);
        }
    }
    let over = |values: &[f64], limit: f64| {
        let n = values.iter().filter(|v| **v > limit).count();
        100.0 * n as f64 / values.len().max(1) as f64
    };
    let speed_cap = limits.speed_mps * (1.0 + limits.tolerance);
    let yaw_cap = limits.yaw_rate_radps * (1.0 + limits.tolerance);
    let pct = format!("+ {:.0} %", 100.0 * limits.tolerance);
    let mut breaches = Vec::new();
    let max_speed = max(&speeds);
    if let Some(v) = max_speed.filter(|v| *v > speed_cap) {
        breaches.push(format!(
            "horizontal speed {v:.3} m/s over {speed_cap:.4} m/s ({} {pct})",
            limits.speed_mps
        ));
    }
    let max_yaw_rate = max(&yaw_rates);
    if let Some(v) = max_yaw_rate.filter(|v| *v > yaw_cap) {
        breaches.push(format!(
            "yaw rate {v:.3} rad/s over {yaw_cap:.4} rad/s ({} {pct})",
            limits.yaw_rate_radps
        ));
    }
    if let Some(c) = clearance_m.filter(|c| *c < limits.clearance_m) {
        breaches.push(format!(
            "clearance to obstacles {c:.2} m, under {} m",
            limits.clearance_m
        ));
    }
    if let Some(s) = separation_m.filter(|s| *s < limits.separation_m) {
        breaches.push(format!(
            "separation between drones {s:.2} m, under {} m",
            limits.separation_m
        ));
    }
    Flown {
        limits: *limits,
        max_speed_mps: max_speed,
        p99_speed_mps: quantile(&mut speeds, 0.99),
        over_speed_pct: over(&speeds, speed_cap),
        max_yaw_rate_radps: max_yaw_rate,
        p99_yaw_rate_radps: quantile(&mut yaw_rates, 0.99),
        over_yaw_rate_pct: over(&yaw_rates, yaw_cap),
        cruise_height_m: quantile(&mut heights, 0.5),
        max_height_m: max(&heights),
        held: breaches.is_empty(),
        breaches,
    }
}

/// Pairs of samples (by time) each at least `window_s` apart, the second the first one that
/// far on; none across a gap over [`MAX_GAP_S`].
fn windows<'a>(
    samples: &'a [&'a PoseSample],
    window_s: f64,
) -> impl Iterator<Item = (&'a PoseSample, &'a PoseSample)> + 'a {
    let mut j = 0;
    samples.iter().enumerate().filter_map(move |(i, a)| {
        j = j.max(i + 1);
        while samples.get(j).is_some_and(|b| b.t_s - a.t_s < window_s) {
            j += 1;
        }
        let b = samples.get(j)?;
        let spans_gap = samples[i..=j]
            .windows(2)
            .any(|w| w[1].t_s - w[0].t_s > MAX_GAP_S);
        (!spans_gap).then_some((*a, *b))
    })
}

/// An angle difference in (-pi, pi].
fn wrapped(d: f64) -> f64 {
    let r = d.rem_euclid(TAU);
    if r > PI {
        r - TAU
    } else {
        r
    }
}

fn max(values: &[f64]) -> Option<f64> {
    values.iter().copied().reduce(f64::max)
}

/// The `q` quantile (nearest rank below), sorting `values`.
fn quantile(values: &mut [f64], q: f64) -> Option<f64> {
    values.sort_by(f64::total_cmp);
    let last = values.len().checked_sub(1)?;
    values
        .get(((last as f64) * q).floor() as usize)
        .copied()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;

    fn sample(t_s: f64, x_m: f64, yaw_rad: f64) -> PoseSample {
        PoseSample {
            t_s,
            drone: "drone_0".into(),
            x_m,
            y_m: 0.0,
            z_m: 1.0,
            yaw_rad,
        }
    }

    fn flight(speed_mps: f64, yaw_rate_radps: f64) -> Vec<PoseSample> {
        (0..100)
            .map(|k| {
                let t = 0.1 * f64::from(k);
                sample(t, speed_mps * t, wrapped(yaw_rate_radps * t))
            })
            .collect()
    }

    #[test]
    fn within_the_limits_holds_and_reports_what_was_flown() {
        let tracks = Tracks::new(&flight(0.75, 0.15), 0.3);
        let f = judge(&tracks, 0.3, Some(0.5), None, &FlightLimits::default());
        assert!(f.held, "{:?}", f.breaches);
        assert!((f.max_speed_mps.unwrap() - 0.75).abs() < 1e-9);
        assert!((f.max_yaw_rate_radps.unwrap() - 0.15).abs() < 1e-9);
        assert_eq!(f.cruise_height_m, Some(1.0));
        assert_eq!(f.over_speed_pct, 0.0);
    }

    #[test]
    fn every_limit_broken_is_named_and_the_run_fails() {
        // Turning on past pi, the heading wraps: each window is still measured the short way.
        let tracks = Tracks::new(&flight(0.8, 0.5), 0.3);
        let f = judge(&tracks, 0.3, Some(0.3), Some(1.0), &FlightLimits::default());
        assert!(!f.held);
        assert_eq!(f.breaches.len(), 4, "{:?}", f.breaches);
        assert!(f.breaches[0].starts_with("horizontal speed 0.800 m/s over 0.7725"));
        assert!(f.breaches[1].starts_with("yaw rate 0.500 rad/s"));
        assert!((f.max_yaw_rate_radps.unwrap() - 0.5).abs() < 1e-9);
        assert_eq!(f.over_speed_pct, 100.0);
    }

    #[test]
    fn the_ground_and_gaps_in_the_log_are_not_flight() {
        let mut s = flight(0.5, 0.0);
        // On the ground it was carried fast (z under the airborne height): not flown.
        s.push(PoseSample {
            z_m: 0.1,
            ..sample(10.0, 100.0, 0.0)
        });
        // After two seconds of silence it reappears 10 m on: a gap, not a speed.
        s.push(sample(12.0, 15.0, 0.0));
        s.push(sample(12.1, 15.05, 0.0));
        s.push(sample(12.2, 15.10, 0.0));
        s.push(sample(12.3, 15.15, 0.0));
        let f = judge(&Tracks::new(&s, 0.3), 0.3, None, None, &FlightLimits::default());
        assert!(f.held, "{:?}", f.breaches);
        assert!((f.max_speed_mps.unwrap() - 0.5).abs() < 1e-9);
    }

    #[test]
    fn limits_out_of_range_are_named() {
        let bad = FlightLimits {
            window_s: 5.0,
            ..FlightLimits::default()
        };
        assert_eq!(bad.check(), Err("limits.window_s"));
        assert_eq!(FlightLimits::default().check(), Ok(()));
    }
}
