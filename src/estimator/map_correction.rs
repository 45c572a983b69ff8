//! The map correction: an offset from the position estimate the vehicle reports (the simulator's
//! drifting one, an autopilot's, in the fleet's shared frame) to the map's frame, learnt from
//! where the range sensor's hits fall against obstacles already mapped.
//!
//! In: time steps while flying, the hits of the range sensor (ENU m, placed at the reported
//! pose), and a score of how well the hits, moved by an offset, fit the map
//! (`mapping::registration`: on obstacles it has held for a while, not in space it holds free).
//! Out: the offset (ENU m, horizontal) the core adds to the reported position before mapping,
//! planning and control, and subtracts from every position setpoint it sends. The reported
//! estimate is never changed: the correction is Kestrel's own, so it works the same over the
//! simulator and over an autopilot that drifts.
//!
//! Every [`FIT_PERIOD_S`] the hits of the last [`WINDOW_S`] are fitted: every offset within
//! `search_radius_m` of the current one is tried, on a [`COARSE_STEP_M`] grid and then a
//! [`FIT_STEP_M`] one around the best, and the offsets of the best score (at least `min_hits`
//! and [`MIN_FIT_SHARE`] of the hits, resting on obstacles `min_span_m` apart, all close
//! together) give the measured offset, their mean, when they score clearly better than the
//! offset as it is ([`MIN_GAIN_SHARE`]); else the fit confirms the offset. Obstacles mapped long
//! ago weigh most (`mapping::registration`), and the older the map a fit rests on, the more the
//! drift since may have moved the offset: the filter trusts its own offset that much less.
//! A fit farther off the offset than the drift since the fits it agrees with allows
//! ([`JUMP_SIGMAS`]) is a jump: among dense obstacles a wrong fit to an old map can score best
//! (a pole where another stood), and one such fit moved the offset a metre and back. A jump is
//! taken only once a fit of hits it did not see (at least [`WINDOW_S`] later, within
//! [`CONFIRM_WITHIN_S`]) measures the same offset, and no fit in between held the offset as it is
//! or measured another. A wrong fit that holds over more than a window of fresh hits is still
//! taken: the gate delays a true loop closure by a window to reject the fleeting ones.
//! A Kalman filter of the 2D offset takes the fits: the offset wanders as a drift does (process
//! noise from the drift speed expected), a fit far from the filter's offset is clipped to
//! [`CLIP_SIGMAS`] standard deviations (one wrong fit moves it little), and the offset never
//! exceeds `max_offset_m` (past it, a fit is wrong, not the drift).
//!
//! The filter's past is kept too, one step a fit: [`MapCorrection::smoothed_track`] is the offset
//! at each past step as every fit since makes it out (a Rauch-Tung-Striebel smoother). When a
//! drone comes back to ground it mapped long ago and a fit moves its offset, the offsets of the
//! flight since the last fit it could trust move with it, most near the return and least near
//! that fit, as a random walk tied at both ends does: what the map was drawn with while the
//! drone flew uncorrected (`mapping::history` redraws it so).

use crate::types::{Vec2, Vec3};
use nalgebra::Matrix2;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;

/// How often the hits are fitted to the map (s).
pub const FIT_PERIOD_S: f64 = 0.5;
/// The hits of this long are fitted at once (s): several faces seen, few of them mapped since.
pub const WINDOW_S: f64 = 3.0;
/// The grids of offsets tried (m): a map cell of the usual 0.1 m over the whole search, then a
/// quarter of one around the best.
pub const COARSE_STEP_M: f64 = 0.1;
pub const FIT_STEP_M: f64 = 0.025;
/// Innovations beyond this many standard deviations are clipped to it.
pub const CLIP_SIGMAS: f64 = 2.5;
/// How far a fit may be off the true offset (m, one standard deviation): the map's cells and
/// the grid of offsets quantise it.
const FIT_SIGMA_M: f64 = 0.05;
/// The best offsets of a fit lie at most this far from their mean (m), else it is ambiguous.
const FIT_SPREAD_M: f64 = 0.1;
/// A fit counts when its score is at least this share of the hits: most hits of a drone among
/// mapped obstacles fall on them; a few on a new face fit some offset by chance.
const MIN_FIT_SHARE: f64 = 0.3;
/// A fit moves the offset only when it scores this share better than the offset as it is
/// (at least [`MIN_GAIN_HITS`]): else it confirms the offset. Small gains by chance otherwise
/// walk the offset off, and the map drawn at a wrong offset then holds it there.
const MIN_GAIN_SHARE: f64 = 0.2;
const MIN_GAIN_HITS: f64 = 3.0;
/// Scores this close are as good (the weights of hits are fractions).
const TIE: f64 = 1e-9;
/// The process noise per second is the drift speed squared times this (s): the offset's spread
/// grows as a random walk's of steps this long. Over the second or two between fits it allows
/// about the drift speed times that; over a minute without fits, 0.33 m at 3 cm/s (less than a
/// drift can go: the clip then only slows the first fits back).
const RANDOM_WALK_S: f64 = 2.0;
/// A fit farther than this many standard deviations (the filter's own, before a fit's map age
/// widens them, with the fit's) from the offset is a jump, taken only when confirmed.
pub const JUMP_SIGMAS: f64 = 3.0;
/// A jump is confirmed by a fit at least [`WINDOW_S`] and at most this long after it (s)...
pub const CONFIRM_WITHIN_S: f64 = 3.0 * WINDOW_S;
/// ... that measures an offset this close to it (m).
const CONFIRM_AGREE_M: f64 = 2.0 * FIT_SPREAD_M;
/// Most hits kept (a 3 s window of a 20 Hz lidar of 16 beams).
const MAX_HITS: usize = 1000;
/// A fit against obstacles mapped this long ago (s, on average) closes a loop: the drone is back
/// where it mapped before it drifted. A fit against younger ones, most of them the drone's own
/// of the last seconds, drawn where its drifting estimate put them, says nothing of its past.
pub const LOOP_AGE_S: f64 = 30.0;
/// Most steps of the filter's past kept: two hours of flight at a fit every [`FIT_PERIOD_S`].
pub const MAX_TRACK_STEPS: usize = 14_400;
/// The most a drone's corrected estimate is taken to be off the fleet's map where it flies (m):
/// the drift of its flight, up to this. The fits hold a drone to the map around it, but that
/// map was drawn by drones whose estimates drifted apart, so two drones' estimates near each
/// other disagree by up to about twice this (1.35 m the most, over the 3-drone runs of 2 cm/s of
/// BENCHMARKS.md "What a real drone has, seventh").
pub const MAX_UNCERTAINTY_M: f64 = 0.75;

/// `[estimator.map_correction]`: correcting the position estimate against the map.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapCorrectionSettings {
    /// Learn and apply the offset (needs mapping and a range sensor).
    pub enabled: bool,
    /// How fast the estimate may drift (m/s, 0..=1): how quickly the offset may change, and
    /// at 0 it never does. Absent: the vehicle's, as an estimator's noise settings are (the
    /// simulator's `[sim] position_drift_mps`; [`AUTOPILOT_DRIFT_MPS`] for an autopilot).
    pub drift_mps: Option<f64>,
    /// Only obstacles occupied at least this long count (s, 3..=600, not less than the 3 s
    /// of hits fitted): newer ones are where the drifting estimate put them.
    pub settle_s: f64,
    /// Offsets are tried this far around the current one (m, 0.1..=2): as far as the drift may
    /// go between two visits of a place.
    pub search_radius_m: f64,
    /// The offset never grows beyond this (m, 0.1..=100).
    pub max_offset_m: f64,
    /// Draw the drone's map again from its kept scans when later fits show the offsets it was
    /// drawn at were others (`mapping::history`).
    pub redraw: bool,
    /// A fit counts with at least this many hits on obstacles mapped a while ago (1..=1000).
    pub min_hits: u32,
    /// A fit counts when its hits on mapped obstacles lie at least this far apart (m, 0..=20, the
    /// diagonal of their box): it rests on two obstacles at least, not on one pole, whose far
    /// face fits a near one seen now as well as the near face does.
    pub min_span_m: f64,
}

impl Default for MapCorrectionSettings {
    fn default() -> Self {
        Self {
            enabled: true,
            drift_mps: None,
            settle_s: 5.0,
            search_radius_m: 1.0,
            max_offset_m: 10.0,
            redraw: true,
            min_hits: 10,
            min_span_m: 1.0,
        }
    }
}

/// How fast an autopilot's estimate is taken to drift when the settings do not say (m/s): not
/// at all, so nothing is corrected. An EKF on GPS or vision holds its frame; a vehicle whose
/// estimate drifts (an optical-flow deck's few cm/s) sets `drift_mps` (0.03 for the issue's
/// 2 cm/s and a margin). Left on by default, it failed the fake-PX4 explorations of
/// `tests/run_explore.rs` and `tests/fleet_bus_e2e.rs` (BENCHMARKS.md, "What a real drone has,
/// third"), not yet understood.
pub const AUTOPILOT_DRIFT_MPS: f64 = 0.0;

impl MapCorrectionSettings {
    /// These settings with `drift_mps` the vehicle's where they give none.
    pub fn for_vehicle(self, vehicle_drift_mps: f64) -> Self {
        Self {
            drift_mps: self.drift_mps.or(Some(vehicle_drift_mps)),
            ..self
        }
    }

    /// The drift speed the filter expects (m/s).
    pub fn drift_mps(&self) -> f64 {
        self.drift_mps.unwrap_or(AUTOPILOT_DRIFT_MPS)
    }

    /// Each field within its bounds, else the field's name and why.
    pub fn check(&self) -> Result<(), (&'static str, String)> {
        let within = |name: &'static str, v: f64, lo: f64, hi: f64| {
            if v.is_finite() && (lo..=hi).contains(&v) {
                Ok(())
            } else {
                Err((name, format!("{v} is not within {lo}..={hi}")))
            }
        };
        if let Some(drift) = self.drift_mps {
            within("drift_mps", drift, 0.0, 1.0)?;
        }
        within("settle_s", self.settle_s, WINDOW_S, 600.0)?;
        within("search_radius_m", self.search_radius_m, 0.1, 2.0)?;
        within("max_offset_m", self.max_offset_m, 0.1, 100.0)?;
        within("min_hits", f64::from(self.min_hits), 1.0, 1000.0)?;
        within("min_span_m", self.min_span_m, 0.0, 20.0)
    }
}

/// How well hits fit the map at one offset.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct FitQuality {
    /// The hits on obstacles mapped a while ago (weighted), less those in free space.
    pub score: f64,
    /// How far apart the hits on obstacles lie (m).
    pub span_m: f64,
    /// How long ago the obstacles they hit were mapped (s, their mean).
    pub age_s: f64,
    /// How many hits fall on obstacles mapped a while ago, whatever their weight.
    pub on_obstacles: usize,
}

/// One fit of the hits to the map.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fit {
    /// The offset of the best score (ENU m).
    pub offset_m: Vec2,
    pub quality: FitQuality,
    /// Of how many hits.
    pub hits: usize,
}

/// The best quality of the offsets on a grid of `step_m` within `radius_m` of `center`, and the
/// offsets that have it; `None` without hits.
fn best_on_grid(
    hits: &[Vec2],
    score: impl Fn(&[Vec2], Vec2) -> FitQuality,
    center: Vec2,
    radius_m: f64,
    step_m: f64,
) -> Option<(FitQuality, Vec<Vec2>)> {
    if hits.is_empty() {
        return None;
    }
    let reach = (radius_m / step_m).floor() as i32;
    let mut best: Option<FitQuality> = None;
    let mut at: Vec<Vec2> = Vec::new();
    for i in -reach..=reach {
        for j in -reach..=reach {
            let step = Vec2::new(f64::from(i), f64::from(j)) * step_m;
            if step.norm() > radius_m + 1e-9 {
                continue;
            }
            let offset = center + step;
            let q = score(hits, offset);
            match best {
                Some(b) if q.score < b.score - TIE => continue,
                Some(b) if q.score <= b.score + TIE => {
                    // As good: the fit rests on the smaller span of the two.
                    best = Some(FitQuality {
                        span_m: b.span_m.min(q.span_m),
                        ..b
                    });
                }
                _ => {
                    best = Some(q);
                    at.clear();
                }
            }
            at.push(offset);
        }
    }
    best.map(|b| (b, at))
}

fn mean(points: &[Vec2]) -> Vec2 {
    points.iter().sum::<Vec2>() / points.len().max(1) as f64
}

/// One step of the filter's past, at a fit's time.
#[derive(Debug, Clone, Copy, PartialEq)]
struct TrackStep {
    t_s: f64,
    /// The offset and its covariance after the fit.
    offset_m: Vec2,
    cov_m2: Matrix2<f64>,
    /// The drift's process noise added since the step before (m², on each axis).
    walk_m2: f64,
    /// The fit moved the offset against obstacles mapped at least [`LOOP_AGE_S`] ago: it says
    /// how far the flight since drifted, and the smoother carries it back.
    closes_loop: bool,
}

/// The offset from the reported position to the map's frame, and its uncertainty.
#[derive(Debug, Clone)]
pub struct MapCorrection {
    settings: MapCorrectionSettings,
    offset_m: Vec2,
    cov_m2: Matrix2<f64>,
    /// Recent hits (time s, reported frame ENU m), oldest first.
    hits: VecDeque<(f64, Vec2)>,
    next_fit_s: f64,
    /// The filter's past, oldest first, at most [`MAX_TRACK_STEPS`].
    track: VecDeque<TrackStep>,
    /// Process noise added since the last step of `track` (m², on each axis).
    walk_m2: f64,
    /// Flight time so far (s).
    flown_s: f64,
    /// A jump measured and not yet confirmed: when, and to which offset.
    jump: Option<(f64, Vec2)>,
}

impl MapCorrection {
    /// No offset yet.
    pub fn new(settings: MapCorrectionSettings) -> Self {
        Self {
            settings,
            offset_m: Vec2::zeros(),
            cov_m2: Matrix2::zeros(),
            hits: VecDeque::new(),
            next_fit_s: 0.0,
            track: VecDeque::new(),
            walk_m2: 0.0,
            flown_s: 0.0,
            jump: None,
        }
    }

    pub fn settings(&self) -> &MapCorrectionSettings {
        &self.settings
    }

    /// When the next fit is due (s).
    pub fn next_fit_s(&self) -> f64 {
        self.next_fit_s
    }

    /// Reported position plus this is the position in the map's frame (ENU m; z is 0).
    pub fn offset_m(&self) -> Vec3 {
        Vec3::new(self.offset_m.x, self.offset_m.y, 0.0)
    }

    /// The offset grows uncertain over `dt_s` of flight as the drift may move it.
    pub fn predict(&mut self, dt_s: f64) {
        if dt_s > 0.0 && dt_s.is_finite() {
            let q = self.settings.drift_mps().powi(2) * RANDOM_WALK_S * dt_s;
            self.cov_m2 += Matrix2::identity() * q;
            self.walk_m2 += q;
            self.flown_s += dt_s;
        }
    }

    /// How far the corrected estimate may be off the fleet's map here (m, horizontal): what the
    /// drift can have made of the flight so far, at most [`MAX_UNCERTAINTY_M`]; 0 for an
    /// estimate that does not drift. Two drones keep apart by this much more each.
    pub fn uncertainty_m(&self) -> f64 {
        (self.settings.drift_mps() * self.flown_s).min(MAX_UNCERTAINTY_M)
    }

    /// Keeps the hits of `now_s` (reported frame) for the fits of the next [`WINDOW_S`].
    pub fn add_hits(&mut self, now_s: f64, hits: impl IntoIterator<Item = Vec2>) {
        self.hits.extend(hits.into_iter().map(|h| (now_s, h)));
        while self.hits.len() > MAX_HITS
            || self
                .hits
                .front()
                .is_some_and(|(t, _)| *t < now_s - WINDOW_S)
        {
            self.hits.pop_front();
        }
    }

    /// When one is due, fits the recent hits to the map and takes the fit. `score`: how well
    /// the hits, moved by an offset, fit the map.
    pub fn fit(&mut self, now_s: f64, score: impl Fn(&[Vec2], Vec2) -> FitQuality) -> Option<Fit> {
        if now_s < self.next_fit_s || self.settings.drift_mps() <= 0.0 {
            return None;
        }
        self.next_fit_s = now_s + FIT_PERIOD_S;
        let hits: Vec<Vec2> = self.hits.iter().map(|(_, h)| *h).collect();
        let fit = self.best_offset(&hits, score);
        let before = self.offset_m;
        if let Some(fit) = fit {
            if self.confirmed(now_s, fit.offset_m) {
                self.take(fit.offset_m, fit.quality.age_s);
            }
        }
        let closes_loop =
            fit.is_some_and(|f| f.quality.age_s >= LOOP_AGE_S) && self.offset_m != before;
        self.record(now_s, closes_loop);
        fit
    }

    /// Whether a fit measuring `measured_m` at `now_s` may be taken: when it lies within what
    /// the drift allows of the offset, or confirms a jump measured before (else it is kept as
    /// a jump to confirm).
    fn confirmed(&mut self, now_s: f64, measured_m: Vec2) -> bool {
        let s = self.cov_m2 + Matrix2::identity() * FIT_SIGMA_M.powi(2);
        let innovation = measured_m - self.offset_m;
        let within = s
            .try_inverse()
            .is_some_and(|inv| innovation.dot(&(inv * innovation)).sqrt() <= JUMP_SIGMAS);
        if within {
            self.jump = None;
            return true;
        }
        match self.jump {
            Some((t, at))
                if now_s - t >= WINDOW_S
                    && now_s - t <= CONFIRM_WITHIN_S
                    && (measured_m - at).norm() <= CONFIRM_AGREE_M =>
            {
                self.jump = None;
                true
            }
            Some((t, at))
                if now_s - t < WINDOW_S && (measured_m - at).norm() <= CONFIRM_AGREE_M =>
            {
                false
            }
            _ => {
                self.jump = Some((now_s, measured_m));
                false
            }
        }
    }

    /// Keeps the filter's state of `now_s` as a step of its past.
    fn record(&mut self, now_s: f64, closes_loop: bool) {
        self.track.push_back(TrackStep {
            t_s: now_s,
            offset_m: self.offset_m,
            cov_m2: self.cov_m2,
            walk_m2: self.walk_m2,
            closes_loop,
        });
        self.walk_m2 = 0.0;
        while self.track.len() > MAX_TRACK_STEPS {
            self.track.pop_front();
        }
    }

    /// The offset at each step of the filter's past (time s, ENU m; oldest first, at most
    /// [`MAX_TRACK_STEPS`]) as all the fits since make it out: the filter's offsets smoothed
    /// backwards (Rauch-Tung-Striebel, the drift a random walk). A step the filter was sure of
    /// keeps its offset; the uncertain steps before a fit that closed a loop move with it. A
    /// fit to the drone's own recent map moves only the steps from it on. The last step is the
    /// filter's offset as it is.
    pub fn smoothed_track(&self) -> Vec<(f64, Vec2)> {
        let mut out: Vec<(f64, Vec2)> = self.track.iter().map(|s| (s.t_s, s.offset_m)).collect();
        for k in (0..self.track.len().saturating_sub(1)).rev() {
            let (here, next) = (&self.track[k], &self.track[k + 1]);
            let prior = here.cov_m2 + Matrix2::identity() * next.walk_m2;
            let gain = match prior.try_inverse() {
                Some(inv) if next.walk_m2 > 0.0 || here.cov_m2.trace() > 0.0 => here.cov_m2 * inv,
                _ => Matrix2::zeros(),
            };
            // What the later fits say of step k+1, and of the drift into it if its own fit
            // closed a loop.
            let mut later = out[k + 1].1 - next.offset_m;
            if next.closes_loop {
                later += next.offset_m - here.offset_m;
            }
            out[k].1 = here.offset_m + gain * later;
        }
        out
    }

    /// The mean of the offsets around the current one with the best score; `None` when it is
    /// below `min_hits`, rests on too small a span, or when they lie apart (two fits as good).
    fn best_offset(
        &self,
        hits: &[Vec2],
        score: impl Fn(&[Vec2], Vec2) -> FitQuality,
    ) -> Option<Fit> {
        let here = score(hits, self.offset_m);
        // Coarse, a map cell a step, over the whole radius; then fine around the best.
        let coarse = best_on_grid(
            hits,
            &score,
            self.offset_m,
            self.settings.search_radius_m,
            COARSE_STEP_M,
        );
        let (_, coarse_at) = coarse?;
        let coarse_mean = mean(&coarse_at);
        if coarse_at
            .iter()
            .any(|o| (o - coarse_mean).norm() > FIT_SPREAD_M)
        {
            return None;
        }
        let (best, at) = best_on_grid(hits, &score, coarse_mean, COARSE_STEP_M, FIT_STEP_M)?;
        let enough = f64::from(self.settings.min_hits).max(MIN_FIT_SHARE * hits.len() as f64);
        if (best.on_obstacles as f64) < enough || best.span_m < self.settings.min_span_m {
            return None;
        }
        let gain = MIN_GAIN_HITS.max(MIN_GAIN_SHARE * best.score);
        if best.score - here.score < gain {
            return Some(Fit {
                offset_m: self.offset_m,
                quality: here,
                hits: hits.len(),
            });
        }
        let measured = mean(&at);
        if at.iter().any(|o| (o - measured).norm() > FIT_SPREAD_M) {
            return None;
        }
        Some(Fit {
            offset_m: measured,
            quality: best,
            hits: hits.len(),
        })
    }

    /// The Kalman update with a measured offset, clipped and bounded. The map the fit rests on
    /// was drawn `age_s` ago (on average): the drift since may have moved the offset that much
    /// more, which the filter's uncertainty is widened by first.
    fn take(&mut self, measured_m: Vec2, age_s: f64) {
        let since = self.settings.drift_mps() * age_s.max(0.0);
        self.cov_m2 += Matrix2::identity() * (since.powi(2) / 2.0);
        let s = self.cov_m2 + Matrix2::identity() * FIT_SIGMA_M.powi(2);
        let Some(s_inv) = s.try_inverse() else {
            return;
        };
        let mut innovation = measured_m - self.offset_m;
        let sigmas = innovation.dot(&(s_inv * innovation)).sqrt();
        if sigmas > CLIP_SIGMAS {
            innovation *= CLIP_SIGMAS / sigmas;
        }
        let gain = self.cov_m2 * s_inv;
        self.offset_m += gain * innovation;
        self.cov_m2 = (Matrix2::identity() - gain) * self.cov_m2;
        self.cov_m2 = (self.cov_m2 + self.cov_m2.transpose()) / 2.0;
        let norm = self.offset_m.norm();
        if norm > self.settings.max_offset_m {
            self.offset_m *= self.settings.max_offset_m / norm;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn settings() -> MapCorrectionSettings {
        MapCorrectionSettings::default().for_vehicle(0.03)
    }

    #[test]
    fn the_uncertainty_is_the_drift_of_the_flight_so_far_up_to_its_bound() {
        let mut c = MapCorrection::new(settings());
        assert_eq!(c.uncertainty_m(), 0.0, "before any flight");
        c.predict(10.0);
        assert!((c.uncertainty_m() - 0.3).abs() < 1e-9, "3 cm/s for 10 s");
        c.predict(100.0);
        assert_eq!(c.uncertainty_m(), MAX_UNCERTAINTY_M);
        let still = MapCorrection::new(MapCorrectionSettings::default().for_vehicle(0.0));
        assert_eq!(
            still.uncertainty_m(),
            0.0,
            "an estimate that does not drift"
        );
    }

    fn offset(c: &MapCorrection) -> Vec2 {
        Vec2::new(c.offset_m().x, c.offset_m().y)
    }

    /// Mapped obstacles: the faces of three walls of 0.1 m cells, east, north and west.
    fn on_wall(p: Vec2) -> bool {
        let cell = |v: f64| (v / 0.1).floor();
        (cell(p.x) == 20.0 && p.y.abs() < 1.5)
            || (cell(p.y) == 20.0 && p.x.abs() < 1.5)
            || (cell(p.x) == -21.0 && p.y.abs() < 1.5)
    }

    /// A drone at the origin whose reported position is `drift` off the map's frame: its beams'
    /// hits on the three walls, in the reported frame.
    fn hits(drift: Vec2) -> Vec<Vec2> {
        (-10..=10)
            .flat_map(|k| {
                let s = f64::from(k) / 10.0;
                [Vec2::new(2.05, s), Vec2::new(s, 2.05), Vec2::new(-2.05, s)]
            })
            .map(|h| h + drift)
            .collect()
    }

    /// The hits on the walls, which are 4 m apart and were mapped a minute ago.
    fn count(hits: &[Vec2], offset: Vec2) -> FitQuality {
        let n = hits.iter().filter(|&&h| on_wall(h + offset)).count();
        FitQuality {
            score: n as f64,
            span_m: 4.0,
            age_s: 60.0,
            on_obstacles: n,
        }
    }

    /// All the hits fit at `at` (within 3 cm), half of them anywhere else; the map just drawn.
    fn peak(at: Vec2) -> impl Fn(&[Vec2], Vec2) -> FitQuality {
        move |h: &[Vec2], o: Vec2| {
            let all = h.len() as f64;
            let score = if (o - at).norm() < 0.03 {
                all
            } else {
                all / 2.0
            };
            FitQuality {
                score,
                span_m: 4.0,
                age_s: 0.0,
                on_obstacles: score as usize,
            }
        }
    }

    #[test]
    fn a_drift_is_learnt_from_fits_of_the_hits_to_the_map() {
        let mut c = MapCorrection::new(settings());
        // The reported position is 0.3 m west and 0.15 m north of where the map has the drone:
        // the offset to learn is the opposite. It has drifted so far in 30 s without a fit.
        let drift = Vec2::new(-0.3, 0.15);
        c.predict(30.0);
        let mut t = 0.0;
        for _ in 0..100 {
            t += 0.1;
            c.predict(0.1);
            c.add_hits(t, hits(drift));
            c.fit(t, count);
        }
        assert!(
            (offset(&c) + drift).norm() < 0.04,
            "offset {} for a drift of {drift}",
            offset(&c)
        );
    }

    #[test]
    fn without_drift_the_offset_stays_and_a_lone_wrong_fit_moves_it_little() {
        let mut c = MapCorrection::new(settings());
        let mut t = 0.0;
        for _ in 0..100 {
            t += 0.1;
            c.predict(0.1);
            c.add_hits(t, hits(Vec2::zeros()));
            c.fit(t, count);
        }
        assert!(offset(&c).norm() < 0.03, "{}", offset(&c));
        // One fit says 0.4 m east, on a map as new: clipped.
        t += 1.0;
        c.predict(0.1);
        assert!(c.fit(t, peak(Vec2::new(0.4, 0.0))).is_some());
        assert!(offset(&c).norm() < 0.15, "{}", offset(&c));
    }

    #[test]
    fn too_few_hits_two_fits_as_good_or_one_obstacle_tell_nothing() {
        let mut c = MapCorrection::new(settings());
        c.predict(10.0);
        c.add_hits(1.0, hits(Vec2::new(0.2, 0.0)).into_iter().take(5));
        assert_eq!(c.fit(1.0, count), None, "5 hits");
        let mut c = MapCorrection::new(settings());
        c.predict(10.0);
        c.add_hits(1.0, hits(Vec2::zeros()));
        let two = |_: &[Vec2], o: Vec2| {
            let east = (o - Vec2::new(0.3, 0.0)).norm() < 1e-3;
            let west = (o + Vec2::new(0.3, 0.0)).norm() < 1e-3;
            FitQuality {
                score: if east || west { 40.0 } else { 0.0 },
                span_m: 4.0,
                age_s: 0.0,
                on_obstacles: if east || west { 40 } else { 0 },
            }
        };
        assert_eq!(c.fit(1.0, two), None);
        // Many hits, on one pole: its far face fits as well.
        let one_pole = |h: &[Vec2], o: Vec2| FitQuality {
            span_m: 0.6,
            ..count(h, o)
        };
        assert_eq!(c.fit(2.0, one_pole), None);
        assert_eq!(c.offset_m(), Vec3::zeros());
    }

    /// Three seconds of fits to the walls where the map has them: the offset is sure.
    fn settled() -> (MapCorrection, f64) {
        let mut c = MapCorrection::new(settings());
        let mut t = 0.0;
        for _ in 0..30 {
            t += 0.1;
            c.predict(0.1);
            c.add_hits(t, hits(Vec2::zeros()));
            c.fit(t, count);
        }
        (c, t)
    }

    /// Fits every 0.5 s for `seconds`, the hits `drift` off the walls mapped a minute ago.
    fn fit_for(c: &mut MapCorrection, t: &mut f64, seconds: f64, drift: Vec2) {
        let end = *t + seconds;
        while *t < end - 1e-9 {
            *t += 0.5;
            c.predict(0.5);
            c.add_hits(*t, hits(drift));
            c.fit(*t, count);
        }
    }

    #[test]
    fn a_jump_to_a_map_drawn_long_ago_is_taken_once_hits_it_did_not_see_confirm_it() {
        let (mut c, mut t) = settled();
        // Back among walls mapped a minute ago, 0.8 m off them: a minute at 3 cm/s allows it,
        // but the offset was sure a moment ago. One fit is not enough.
        t += 5.0;
        c.add_hits(t, hits(Vec2::new(0.8, 0.0)));
        assert!(c.fit(t, count).is_some());
        assert!(offset(&c).norm() < 0.05, "{}", offset(&c));
        // Fits of the same hits agree and confirm nothing; fresh ones 3 s on do.
        fit_for(&mut c, &mut t, 2.5, Vec2::new(0.8, 0.0));
        assert!(offset(&c).norm() < 0.05, "{}", offset(&c));
        fit_for(&mut c, &mut t, 0.5, Vec2::new(0.8, 0.0));
        assert!(
            (offset(&c) + Vec2::new(0.8, 0.0)).norm() < 0.05,
            "{}",
            offset(&c)
        );
    }

    #[test]
    fn wrong_fits_that_jump_back_and_forth_never_move_the_offset() {
        let (mut c, mut t) = settled();
        // Among dense poles, fits to an old map say 0.6 m east for a second or two, then the
        // offset as it is, then 0.9 m north, then east again (as a flight's log showed: five
        // jumps in 12 s).
        for (seconds, drift) in [
            (1.5, Vec2::new(-0.6, 0.0)),
            (1.0, Vec2::zeros()),
            (2.0, Vec2::new(-0.6, 0.0)),
            (1.5, Vec2::zeros()),
            (1.5, Vec2::new(0.0, -0.9)),
            (1.0, Vec2::new(-0.6, 0.0)),
            (1.0, Vec2::zeros()),
            (2.0, Vec2::new(0.0, -0.9)),
        ] {
            fit_for(&mut c, &mut t, seconds, drift);
            assert!(offset(&c).norm() < 0.05, "at {t} s: {}", offset(&c));
        }
        // A jump confirmed too late (beyond CONFIRM_WITHIN_S) starts over.
        let (mut c, mut t) = settled();
        t += 1.0;
        c.add_hits(t, hits(Vec2::new(0.6, 0.0)));
        c.fit(t, count);
        let nothing = |_: &[Vec2], _: Vec2| FitQuality::default();
        while t < 1.0 + CONFIRM_WITHIN_S + 3.0 {
            t += 0.5;
            c.fit(t, nothing);
        }
        c.add_hits(t, hits(Vec2::new(0.6, 0.0)));
        c.fit(t, count);
        assert!(offset(&c).norm() < 0.05, "{}", offset(&c));
    }

    /// Fits to the walls at `t` 0.1 .. 10 s, a minute with nothing to fit to, then back at
    /// the walls 0.6 m off them, mapped `age_s` ago.
    fn back_after_a_minute(age_s: f64) -> MapCorrection {
        let mut c = MapCorrection::new(settings());
        let mut t = 0.0;
        while t < 10.0 {
            t += 0.5;
            c.predict(0.5);
            c.add_hits(t, hits(Vec2::zeros()));
            c.fit(t, count);
        }
        let nothing = |_: &[Vec2], _: Vec2| FitQuality::default();
        while t < 70.0 {
            t += 0.5;
            c.predict(0.5);
            c.fit(t, nothing);
        }
        t += 0.5;
        c.predict(0.5);
        c.add_hits(t, hits(Vec2::new(0.6, 0.0)));
        c.fit(t, |h: &[Vec2], o: Vec2| FitQuality {
            age_s,
            ..count(h, o)
        });
        c
    }

    fn smoothed_at(track: &[(f64, Vec2)], t_s: f64) -> Vec2 {
        track
            .iter()
            .find(|(t, _)| (*t - t_s).abs() < 1e-9)
            .unwrap()
            .1
    }

    #[test]
    fn a_loop_closed_after_a_stretch_without_fits_moves_the_stretch_along_a_ramp() {
        let c = back_after_a_minute(60.0);
        let now = offset(&c);
        assert!((now + Vec2::new(0.6, 0.0)).norm() < 0.05, "{now}");
        let track = c.smoothed_track();
        assert_eq!(
            track.last().unwrap().1,
            now,
            "the last step is the filter's"
        );
        assert!(
            smoothed_at(&track, 10.0).norm() < 0.05,
            "the sure fits stay"
        );
        // Half-way through the minute, about half of the drift found at its end.
        let mid = smoothed_at(&track, 40.0);
        assert!((mid - now / 2.0).norm() < 0.1, "{mid} against {now}");
        let late = smoothed_at(&track, 69.0);
        assert!((late - now).norm() < 0.05, "{late}");
    }

    #[test]
    fn a_fit_to_the_drones_own_recent_map_leaves_its_past_as_it_was() {
        let c = back_after_a_minute(5.0);
        assert!(offset(&c).norm() > 0.3, "the fit is taken: {}", offset(&c));
        let track = c.smoothed_track();
        let (_, before) = track[track.len() - 2];
        assert!(before.norm() < 0.05, "{before}");
        assert!(smoothed_at(&track, 40.0).norm() < 0.05);
    }

    #[test]
    fn the_past_kept_is_bounded() {
        let mut c = MapCorrection::new(settings());
        let nothing = |_: &[Vec2], _: Vec2| FitQuality::default();
        for k in 0..(MAX_TRACK_STEPS + 10) {
            c.fit(k as f64 * FIT_PERIOD_S, nothing);
        }
        assert_eq!(c.smoothed_track().len(), MAX_TRACK_STEPS);
    }

    #[test]
    fn a_vehicle_that_does_not_drift_keeps_no_offset() {
        let mut c = MapCorrection::new(MapCorrectionSettings::default().for_vehicle(0.0));
        c.predict(30.0);
        c.add_hits(1.0, hits(Vec2::new(0.2, 0.0)));
        assert_eq!(c.fit(1.0, count), None);
        assert_eq!(c.offset_m(), Vec3::zeros());
    }

    #[test]
    fn the_offset_is_bounded_and_old_hits_go() {
        let tight = MapCorrectionSettings {
            max_offset_m: 0.1,
            ..settings()
        };
        let mut c = MapCorrection::new(tight);
        c.predict(30.0);
        let mut t = 0.0;
        for _ in 0..50 {
            t += 0.5;
            c.predict(0.5);
            c.add_hits(t, hits(Vec2::new(0.0, -0.3)));
            c.fit(t, count);
        }
        assert!((c.offset_m().norm() - 0.1).abs() < 1e-9, "{}", c.offset_m());
        assert!(c.hits.iter().all(|(at, _)| *at >= t - WINDOW_S));
    }

    #[test]
    fn settings_out_of_bounds_name_the_field() {
        let bad = MapCorrectionSettings {
            search_radius_m: f64::NAN,
            ..settings()
        };
        assert_eq!(bad.check().unwrap_err().0, "search_radius_m");
        let short = MapCorrectionSettings {
            settle_s: 1.0,
            ..settings()
        };
        assert_eq!(short.check().unwrap_err().0, "settle_s");
        assert!(settings().check().is_ok());
        let own = MapCorrectionSettings {
            drift_mps: Some(0.01),
            ..MapCorrectionSettings::default()
        };
        assert_eq!(
            own.for_vehicle(0.05).drift_mps,
            Some(0.01),
            "the config's wins"
        );
        assert_eq!(
            MapCorrectionSettings::default().for_vehicle(0.05).drift_mps,
            Some(0.05)
        );
    }
}
