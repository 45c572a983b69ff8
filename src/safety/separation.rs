//! The separation: keeping a drone from closing in on the others of the fleet view faster than
//! it can stop, pushing drones apart that are too near, and keeping what that makes of the
//! motion off the drone's mapped obstacles.
//!
//! In: the asked setpoint, the vehicle's state, the fleet view and the drone's map. Out: the
//! velocity setpoint that keeps the distances, or `None` when the asked one does.

use super::obstacles::{Around, Obstacles};
use super::{intended_velocity, OverrideKind, SafetyConfig, SafetyStage};
use crate::control::Setpoint;
use crate::types::{DroneView, EstimatedState, Vec3};
/// Reaction time of the separation cap beyond the controller's velocity lag (s): a tick or two
/// of the control loop and of the fleet view's age.
const REACTION_EXTRA_S: f64 = 0.05;

/// How far beyond `obstacle_keep_m` mapped obstacles are looked for (m): more than the stopping
/// room at the speeds a separation's slide or push reaches.
const OBSTACLE_REACH_M: f64 = 1.0;

/// Which drones the separation keeps apart from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum Heard {
    All,
    /// Only drones heard now, not silent ones.
    Now,
}

/// One other drone's (or obstacle's) cap on the closing speed along `away` (unit, from it to
/// this drone).
#[derive(Debug, Clone, Copy)]
pub(super) struct Closing {
    pub away: Vec3,
    pub allowed_mps: f64,
    /// A silent drone: no sliding around its spot, only stopping.
    pub stop_only: bool,
}

/// How long the vehicle takes to start braking (s): its velocity lag and a tick.
pub(super) fn reaction_s(config: &SafetyConfig) -> f64 {
    config.limits.velocity_lag().max(0.0) + REACTION_EXTRA_S
}

/// Whether the straight-line motion `w` from relative position `offset` comes nearer than
/// `keep_m`, measured as [`least_distance_m`] with the same drift and hearing uncertainties.
fn passes_within(offset: &Vec3, w: &Vec3, keep_m: f64, drift_m: f64, heard_m: f64) -> bool {
    let approach = offset.dot(w);
    let w2 = w.norm_squared();
    let closest = if approach >= 0.0 || w2 < 1e-12 {
        *offset
    } else {
        offset + w * (-approach / w2)
    };
    least_distance_m(&closest, drift_m, heard_m) < keep_m
}

/// The least distance between two drones `offset` apart (m) when their horizontal positions may
/// be `drift_m` off each other's and the other one anywhere within `heard_m` of its own: a
/// drone held 1 m above another stays 1 m off it, however far their estimates drift.
fn least_distance_m(offset: &Vec3, drift_m: f64, heard_m: f64) -> f64 {
    let horizontal = (offset.xy().norm() - drift_m.max(0.0)).max(0.0);
    horizontal.hypot(offset.z) - heard_m.max(0.0)
}

/// The highest closing speed that can still be braked to zero within `room_m`, reacting after
/// `react_s` and braking at `brake_mps2`: `c * react_s + c^2 / (2 brake) = room_m`.
pub(super) fn stoppable_mps(room_m: f64, react_s: f64, brake_mps2: f64) -> f64 {
    if room_m <= 0.0 {
        return 0.0;
    }
    brake_mps2 * (-react_s + (react_s * react_s + 2.0 * room_m / brake_mps2).sqrt())
}

impl SafetyStage {
    /// Keeps this drone from closing in on any other flying drone faster than it can stop short
    /// of `min_separation_m + separation_margin_m`, on the 3-D line between them, and pushes
    /// apart inside `min_separation_m`.
    ///
    /// A drone is a constraint when the straight-line motion relative to it (commanded or
    /// actual, the other drone's velocity included) would pass nearer than the kept distance,
    /// or when it is nearer already. Then the closing speed along the 3-D line between them
    /// (climbs and descents included) is capped to what can still be braked away within the room
    /// left, after the reaction time and the other drone's own closing during it:
    /// `c * t_r + c^2 / (2 a) <= d - keep - c_other * t_r`. A motion that passes the other one
    /// far enough (a descent beside a drone a metre away) is left alone; one that would end
    /// nearer (a climb into a drone holding half a metre to the side) is slowed and slid along
    /// the kept sphere, away from the other drone. Every drone around counts, not only the
    /// nearest; when the caps cannot all be met, the drone stops. What the slide and the push
    /// make of the motion keeps off the drone's mapped obstacles ([`Self::off_obstacles`]).
    pub(super) fn separated(
        &self,
        me: &str,
        state: &EstimatedState,
        sp: Setpoint,
        around: Around,
        heard: Heard,
    ) -> Option<(Setpoint, OverrideKind, String)> {
        let fleet = around.fleet;
        let here = state.pose.position_m;
        let min = self.config.min_separation_m;
        let keep = min + self.config.separation_margin_m.max(0.0);
        let react_s = reaction_s(&self.config);
        let brake = self.config.braking_mps2.max(0.1);
        let (asked, yaw) = intended_velocity(&sp, here, &self.position_loop);
        let actual = state.velocity_enu_mps;
        let mut limits: Vec<Closing> = Vec::new();
        let mut push = Vec3::zeros();
        let mut nearest: Option<(f64, &str)> = None;
        let counted = |d: &&DroneView| heard == Heard::All || !d.silent;
        // This drone's drifting estimate may be off the map (horizontally), as may another one's
        // of this Kestrel: the two may be that much nearer than their estimates say.
        let own_drift_m = fleet.get(me).map_or(0.0, |d| d.uncertainty_m);
        for other in fleet.others(me).filter(|d| d.flying).filter(counted) {
            let offset = here - other.position_enu_m;
            // A remote drone may be up to its uncertainty nearer than where it was heard; a
            // silent one's uncertainty already holds wherever it could have gone.
            let (drift_m, heard_m) = if other.local {
                (own_drift_m + other.uncertainty_m, 0.0)
            } else {
                (own_drift_m, other.uncertainty_m)
            };
            let d = least_distance_m(&offset, drift_m, heard_m);
            let other_v = if other.silent {
                Vec3::zeros()
            } else {
                other.velocity_enu_mps
            };
            let heading_in = passes_within(&offset, &(asked - other_v), keep, drift_m, heard_m)
                || passes_within(&offset, &(actual - other_v), keep, drift_m, heard_m);
            if !heading_in && d >= keep {
                continue;
            }
            let away = offset
                .try_normalize(1e-6)
                .unwrap_or_else(|| Vec3::new(1.0, 0.0, 0.0));
            let other_closing = other_v.dot(&away).max(0.0);
            let room = d - keep - other_closing * react_s;
            limits.push(Closing {
                away,
                allowed_mps: stoppable_mps(room, react_s, brake),
                stop_only: other.silent,
            });
            // Pushed apart only from a drone heard now: from a silent one's last position,
            // pushing could as well be toward it. Sideways where the drones are side by side.
            if d < min && !other.silent {
                let sideways = Vec3::new(offset.x, offset.y, 0.0);
                let dir = if sideways.norm() > 0.5 * offset.norm() {
                    sideways.try_normalize(1e-6).unwrap_or(away)
                } else {
                    away
                };
                push += dir * (min - d).min(min);
            }
            if nearest.is_none_or(|(n, _)| d < n) {
                nearest = Some((d, &other.id));
            }
        }
        let (d, id) = nearest?;
        let mut v = slide(asked, &limits) + push;
        if let Some(obstacles) = around.obstacles.filter(|_| (v - asked).norm() >= 1e-9) {
            v = self.off_obstacles(v, here, &limits, obstacles, react_s, brake);
        }
        if (v - asked).norm() < 1e-9 {
            return None;
        }
        let why = format!("{d:.2} m from {id}: keeping at least {min:.1} m");
        Some((
            Setpoint::Velocity {
                velocity_enu_mps: v,
                yaw,
            },
            OverrideKind::Separation,
            why,
        ))
    }

    /// `v` slid along the mapped obstacles within reach of `here` (and still along the drones'
    /// `limits`), so that it closes on no obstacle cell faster than it can stop
    /// `obstacle_keep_m` short of it; stopped when both cannot be met. Only where the separation
    /// changed the motion: a behavior's own motion is planned clear of the map already.
    fn off_obstacles(
        &self,
        v: Vec3,
        here: Vec3,
        limits: &[Closing],
        obstacles: Obstacles,
        react_s: f64,
        brake_mps2: f64,
    ) -> Vec3 {
        let keep = self.config.obstacle_keep_m.max(0.0);
        let near = obstacles.within(here, keep + OBSTACLE_REACH_M);
        if near.is_empty() {
            return v;
        }
        let mut all: Vec<Closing> = near
            .iter()
            .map(|n| Closing {
                away: n.away,
                allowed_mps: stoppable_mps(n.distance_m - keep, react_s, brake_mps2),
                stop_only: false,
            })
            .collect();
        all.extend_from_slice(limits);
        slide(v, &all)
    }
}

/// `v` with the closing speed along each limit's `away` brought down to its cap, by sliding
/// along it (a few rounds: sliding along one can close in on another), or stopped when a limit
/// of a silent drone is exceeded or the caps cannot all be met.
pub(super) fn slide(mut v: Vec3, limits: &[Closing]) -> Vec3 {
    for _ in 0..4 {
        let mut changed = false;
        for l in limits {
            let closing = -v.dot(&l.away);
            if closing > l.allowed_mps + 1e-9 {
                changed = true;
                if l.stop_only {
                    // Around a silent drone's spot nothing guides a slide: stop instead.
                    v = Vec3::zeros();
                } else {
                    v += l.away * (closing - l.allowed_mps);
                }
            }
        }
        if !changed {
            break;
        }
    }
    if limits
        .iter()
        .any(|l| -v.dot(&l.away) > l.allowed_mps + 1e-6)
    {
        return Vec3::zeros();
    }
    v
}
