//! The drone's map frame: the reported estimate corrected against the fleet's map, scans and
//! setpoints moved between the vehicle's frame and the map's, and the map drawn again when the
//! correction finds the offsets of the past were others.
//!
//! In: the reported estimate and scans (vehicle frame), the fleet's merged map. Out: the state
//! and scans in the map's frame, setpoints in the vehicle's, the drone's map redrawn.

use super::DroneCore;
use crate::control::Setpoint;
use crate::estimator::map_correction::{FitQuality, MapCorrection};
use crate::mapping::registration::Reference;
use crate::mapping::scan::RangeScan;
use crate::types::{EstimatedState, Vec2, Vec3};

impl DroneCore {
    /// Reported position plus this is the position in the map's frame (ENU m, 0 without the
    /// map correction).
    pub fn map_offset_m(&self) -> Vec3 {
        self.correction
            .as_ref()
            .map_or_else(Vec3::zeros, MapCorrection::offset_m)
    }

    /// Scans the vehicle reported (placed at its reported pose) moved into the map's frame.
    pub fn to_map_frame(&self, scans: &[RangeScan]) -> Vec<RangeScan> {
        let offset = self.map_offset_m();
        scans.iter().map(|s| shifted(s, offset)).collect()
    }

    /// A setpoint of the map's frame (as [`TickOutput::setpoint`]) in the vehicle's, to send it:
    /// positions less the map offset.
    pub fn to_vehicle_frame(&self, setpoint: Setpoint) -> Setpoint {
        match setpoint {
            Setpoint::Position {
                position_enu_m,
                velocity_ff_enu_mps,
                yaw,
            } => Setpoint::Position {
                position_enu_m: position_enu_m - self.map_offset_m(),
                velocity_ff_enu_mps,
                yaw,
            },
            velocity @ Setpoint::Velocity { .. } => velocity,
        }
    }

    /// Sets the estimate: the `reported` one moved into the map's frame by the map correction,
    /// which first learns from this tick's `scans` against the fleet's `map` while flying.
    /// Returns the scans in the map's frame.
    pub(super) fn correct_against_map(
        &mut self,
        reported: EstimatedState,
        scans: &[RangeScan],
        map: Option<Reference<'_>>,
        dt_s: f64,
    ) -> Vec<RangeScan> {
        let flying =
            self.platform.flight.is_airborne() && self.platform.armed && reported.valid.position;
        if flying && self.config.controller.estimate_drift_mps > 0.0 {
            self.seen
                .add(self.now.as_secs_f64(), scans.iter().flat_map(hits_of));
        } else if !flying {
            self.seen.clear();
        }
        if let (Some(correction), Some(map), true) = (self.correction.as_mut(), map, flying) {
            let now_s = self.now.as_secs_f64();
            correction.predict(dt_s);
            correction.add_hits(now_s, scans.iter().flat_map(hits_of));
            let settle_s = correction.settings().settle_s;
            self.fitted = now_s >= correction.next_fit_s();
            correction.fit(now_s, |hits, offset| {
                let fit = map.fit_score(hits, offset, now_s, settle_s);
                FitQuality {
                    score: fit.score,
                    span_m: fit.span_m,
                    age_s: fit.age_s,
                    on_obstacles: fit.on_obstacles,
                }
            });
        }
        self.state = reported;
        self.state.pose.position_m += self.map_offset_m();
        self.to_map_frame(scans)
    }

    /// Keeps this tick's `reported` scans (vehicle frame) with the offset they were drawn at, and
    /// after a fit draws the map again when the correction's smoothed past moves any kept scan
    /// more than [`REDRAW_AT_M`] from where it is drawn.
    pub(super) fn redraw_if_moved(&mut self, reported: &[RangeScan]) {
        let (Some(history), Some(map), Some(correction)) = (
            self.history.as_mut(),
            self.map.as_mut(),
            self.correction.as_ref(),
        ) else {
            return;
        };
        let offset = correction.offset_m();
        let now_s = self.now.as_secs_f64();
        history.push(now_s, reported, Vec2::new(offset.x, offset.y), map.params());
        if !std::mem::take(&mut self.fitted) {
            return;
        }
        let track = correction.smoothed_track();
        let moved_m = history.deviation_m(&track);
        if moved_m > REDRAW_AT_M {
            let grid = history.redraw(&track, map.params());
            let changed = map.redrawn(self.now, grid);
            tracing::debug!(
                "{}: map drawn again from {} scans at {now_s:.1} s: the map correction moved them up to {moved_m:.2} m ({changed:?})",
                self.config.drone_id,
                history.len()
            );
        }
    }
}

/// Where `scan`'s beams ended on something (ENU m, horizontal).
fn hits_of(scan: &RangeScan) -> impl Iterator<Item = crate::types::Vec2> + '_ {
    let origin = scan.origin_enu_m.xy();
    scan.beams.iter().filter_map(move |beam| {
        let range_m = beam.range_m.filter(|r| r.is_finite())?;
        Some(origin + scan.beam_direction_enu(beam) * range_m)
    })
}

/// Most scans a drone's map can be drawn again from: an hour of a 20 Hz ranger (older ones stay
/// as drawn).
pub(super) const MAX_KEPT_SCANS: usize = 72_000;
/// The map is drawn again when the map correction moves a past scan farther than this (m): a
/// cell and a half.
const REDRAW_AT_M: f64 = 0.15;

/// `scan` moved by `offset_m`.
fn shifted(scan: &RangeScan, offset_m: Vec3) -> RangeScan {
    RangeScan {
        origin_enu_m: scan.origin_enu_m + offset_m,
        ..scan.clone()
    }
}
