//! The safety stage: the last step of the tick, after the behaviors and the controller and
//! before the platform. Whatever a behavior asked (in any frame, however the frame moved), the
//! setpoint that leaves the core is finite, within the vehicle's limits, inside the geofence and
//! keeps its distance from the other drones of the fleet view; otherwise it is replaced, and the
//! override is reported with its reason. The link-loss policy lives in the mission executor.
//!
//! In: the controller's setpoint, the vehicle's state and home, the fleet view, the time.
//! Out: the setpoint to send and, when it changed, an [`Override`] saying why.

pub mod geofence;
mod obstacles;
mod seen;
mod separation;

use crate::control::{ControllerConfig, Setpoint, SpeedCaps, YawTarget};
use crate::types::FleetView;
use crate::types::{EstimatedState, PositionLoop, Vec3};
use geofence::Fence;
pub use geofence::GeofenceSection;
pub use obstacles::{Around, Obstacles};
pub use seen::{Seen, SeenHits};
use separation::Heard;
use serde::Serialize;
use std::time::Duration;

/// What the stage enforces (from `[geofence]`, `[safety]`, `[controller]`, `[behaviors]`).
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyConfig {
    pub geofence: GeofenceSection,
    /// Clamped targets are put this far inside the fence (m).
    pub geofence_margin_m: f64,
    /// Least distance kept from another flying drone (m, centre to centre).
    pub min_separation_m: f64,
    /// Drones slow down to stop this much farther out than `min_separation_m` (m): room for
    /// what the braking model leaves out (the tick, the estimate, the other drone's own lag).
    pub separation_margin_m: f64,
    /// Speed and turn-rate limits; a setpoint beyond them by more than 10 % is scaled back.
    pub limits: ControllerConfig,
    /// Braking acceleration used to look ahead of a velocity setpoint (m/s^2).
    pub braking_mps2: f64,
    /// Least distance (m, vehicle centre to the centre of an occupied cell of its map) a
    /// motion the stage makes itself (a separation's slide or push) keeps from an obstacle.
    pub obstacle_keep_m: f64,
    /// How far the vehicle's height estimate may be off (m); `None`: the platform's.
    pub height_error_m: Option<f64>,
}

/// Height kept between the ground and the lowest the vehicle may truly be, given its height
/// estimate's error (m): the lowest flight height a mission may ask is the error plus this.
pub const GROUND_CLEARANCE_M: f64 = 0.5;

/// The lowest height above home a mission may fly a vehicle at, and why.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LowestHeight {
    /// The vehicle's height estimate error plus [`GROUND_CLEARANCE_M`] (m).
    pub height_m: f64,
    /// How far its height estimate may be off (m).
    pub error_m: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            geofence: GeofenceSection::default(),
            geofence_margin_m: 0.5,
            min_separation_m: 1.0,
            separation_margin_m: 0.2,
            limits: ControllerConfig::default(),
            braking_mps2: 2.0,
            obstacle_keep_m: OBSTACLE_KEEP_M,
            height_error_m: None,
        }
    }
}

/// Why the stage changed a setpoint.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum OverrideKind {
    NonFinite,
    Limit,
    Geofence,
    Separation,
    /// Off what the range sensor hit in the last seconds (a drone whose estimate drifts).
    Obstacle,
}

/// What the vehicle is doing, as far as the stage is concerned.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Flight {
    /// On the ground or disarmed: setpoints pass (only a non-finite one is replaced).
    OnGround,
    Flying,
    /// Flying down to touchdown on Kestrel's own setpoints (the behavior `land` without the
    /// autopilot's land mode): a hold for a silent peer still lets it descend, straight down.
    Landing,
}

/// One change to a setpoint, reported once per episode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct Override {
    pub kind: OverrideKind,
    pub reason: String,
}

/// Setpoints leave the core through this stage, one per drone.
#[derive(Debug, Clone)]
pub struct SafetyStage {
    config: SafetyConfig,
    /// The platform's own position loop, when it is given position targets: what it commands
    /// for one is `v_ff + gain * (p - here)`; without one, a target's pull is taken as `p - here`.
    position_loop: PositionLoop,
    /// The override of the previous tick (an episode is reported when it starts).
    active: Option<OverrideKind>,
    /// Per kind: when an episode was last reported, and how many started since unreported.
    reported: [(Option<Duration>, u32); 5],
}

/// An episode of the same kind starting within this long of the last one reported is counted,
/// not reported: a vehicle braking on and off near another must not flood the log, the ground
/// station's texts and the WebSocket (a real PX4 SIH exploration once logged 199 in 3 minutes).
const REPORT_EVERY: Duration = Duration::from_secs(5);

/// Headroom over the controller's own limits before a setpoint counts as beyond them.
const LIMIT_HEADROOM: f64 = 1.1;

/// The default [`SafetyConfig::obstacle_keep_m`]: the simulated vehicle's 0.15 m radius, half a
/// 0.1 m cell (a hit marks the cell the surface is in) and a margin.
pub const OBSTACLE_KEEP_M: f64 = 0.3;

impl SafetyStage {
    pub fn new(config: SafetyConfig, position_loop: Option<PositionLoop>) -> Self {
        Self {
            config,
            position_loop: position_loop.unwrap_or(PositionLoop {
                gain_xy_per_s: 1.0,
                gain_z_per_s: 1.0,
            }),
            active: None,
            reported: [(None, 0); 5],
        }
    }

    /// The override the last checked setpoint had (`None` when it passed unchanged).
    pub fn active(&self) -> Option<OverrideKind> {
        self.active
    }

    /// An episode of `kind` starting at `now`: reported, unless one of that kind was within
    /// [`REPORT_EVERY`]; the next report says how many were not.
    fn episode(&mut self, kind: OverrideKind, reason: String, now: Duration) -> Option<Override> {
        let (last, unreported) = &mut self.reported[kind as usize];
        if last.is_some_and(|t| now.saturating_sub(t) < REPORT_EVERY) {
            *unreported += 1;
            return None;
        }
        let reason = match *unreported {
            0 => reason,
            n => format!("{reason} (and {n} more times since the last report)"),
        };
        *last = Some(now);
        *unreported = 0;
        Some(Override { kind, reason })
    }

    /// Checks one setpoint of drone `me` against this tick's speed `caps` (the running
    /// behavior's speed and the vehicle's limits) and what is `around` it (the fleet, and the
    /// drone's map when it has one). Returns the setpoint to send, and an override when one
    /// starts (or changes kind) this tick.
    #[allow(clippy::too_many_arguments)]
    pub fn check<'a>(
        &mut self,
        me: &str,
        state: &EstimatedState,
        home_enu_m: Vec3,
        flight: Flight,
        setpoint: Option<Setpoint>,
        caps: SpeedCaps,
        around: impl Into<Around<'a>>,
    ) -> (Option<Setpoint>, Option<Override>) {
        let around = around.into();
        let fleet = around.fleet;
        let Some(sp) = setpoint else {
            self.active = None;
            return (None, None);
        };
        let here = state.pose.position_m;
        let hold = Setpoint::Position {
            position_enu_m: here,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(state.pose.yaw_rad()),
        };
        let (out, change) = if !finite(&sp) {
            let reason = "a non-finite setpoint was replaced by a hold".to_string();
            (hold, Some((OverrideKind::NonFinite, reason)))
        } else if flight == Flight::OnGround {
            (sp, None)
        } else {
            let fence = Fence {
                section: &self.config.geofence,
                home_enu_m,
                margin_m: self.config.geofence_margin_m,
            };
            self.fenced(&fence, here, sp)
                .or_else(|| {
                    let why = held_for_silence(me, fleet)?;
                    Some(self.held(me, state, sp, around, flight, why))
                })
                .or_else(|| self.separated(me, state, sp, around, Heard::All))
                .or_else(|| self.limited(sp))
                .map_or((sp, None), |(s, kind, why)| (s, Some((kind, why))))
        };
        // Whatever the steps above made of it, the motion keeps off what the beams just hit.
        let off_seen = around
            .seen
            .filter(|_| flight != Flight::OnGround)
            .and_then(|seen| self.off_seen(here, out, seen));
        let (out, change) = match off_seen {
            Some((s, kind, why)) => (s, change.or(Some((kind, why)))),
            None => (out, change),
        };
        // The speed caps are the last word, whatever the steps above made of the setpoint.
        let flying = flight != Flight::OnGround;
        let capped = flying.then(|| self.capped(out, here, caps)).flatten();
        let (out, change) = match capped {
            Some((capped, why)) => (capped, change.or(Some((OverrideKind::Limit, why)))),
            None => (out, change),
        };
        let kind = change.as_ref().map(|(k, _)| *k);
        let report = match change {
            Some((k, reason)) if self.active != Some(k) => self.episode(k, reason, state.stamp),
            _ => None,
        };
        self.active = kind;
        (Some(out), report)
    }

    /// Keeps the vehicle and its target inside the fence.
    fn fenced(
        &self,
        fence: &Fence,
        here: Vec3,
        sp: Setpoint,
    ) -> Option<(Setpoint, OverrideKind, String)> {
        let target_at = |p: Vec3, yaw| Setpoint::Position {
            position_enu_m: p,
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw,
        };
        if let Some(side) = fence.breached_by(&here) {
            let back = fence.clamp(&here);
            let why = format!("the vehicle is outside the geofence ({side}): back inside");
            return Some((target_at(back, yaw_of(&sp)), OverrideKind::Geofence, why));
        }
        let (ahead, yaw) = match sp {
            Setpoint::Position {
                position_enu_m,
                yaw,
                ..
            } => (position_enu_m, yaw),
            Setpoint::Velocity {
                velocity_enu_mps,
                yaw,
            } => {
                let v = velocity_enu_mps.norm();
                let stop_s = v / self.config.braking_mps2.max(0.1) + 0.2;
                (here + velocity_enu_mps * stop_s, yaw)
            }
        };
        let side = fence.breached_by(&ahead).or_else(|| {
            matches!(sp, Setpoint::Position { .. })
                .then_some(())
                .and_then(|()| fence.below_floor(&ahead).then_some("floor"))
        })?;
        let stop = fence.clamp(&ahead);
        let why = format!(
            "setpoint beyond the geofence ({side}) at [{:.1}, {:.1}, {:.1}]: held at [{:.1}, {:.1}, {:.1}]",
            ahead.x, ahead.y, ahead.z, stop.x, stop.y, stop.z
        );
        Some((target_at(stop, yaw), OverrideKind::Geofence, why))
    }

    /// The setpoint while held for a silent peer: in place, still turning as asked (a turn
    /// moves nothing toward anyone and keeps the range beams sweeping). A landing goes on
    /// straight down at the speed it asked, horizontal motion taken out: the silent peer's
    /// drone could be anywhere, but every drone that hears the fleet holds where it is, and a
    /// drone on the ground is a danger to none. Drones heard now are still kept apart from; a
    /// silent one's growing uncertainty would stop the descent for good, which is the very
    /// hold the landing is there to end.
    fn held(
        &self,
        me: &str,
        state: &EstimatedState,
        sp: Setpoint,
        around: Around,
        flight: Flight,
        why: String,
    ) -> (Setpoint, OverrideKind, String) {
        let here = state.pose.position_m;
        let (asked, yaw) = intended_velocity(&sp, here, &self.position_loop);
        let down_mps = match flight {
            Flight::Landing => asked.z.min(0.0),
            Flight::Flying | Flight::OnGround => 0.0,
        };
        let in_place = Setpoint::Velocity {
            velocity_enu_mps: Vec3::new(0.0, 0.0, down_mps),
            yaw,
        };
        if down_mps == 0.0 {
            return (in_place, OverrideKind::Separation, why);
        }
        let why = format!("{why}; landing straight down");
        match self.separated(me, state, in_place, around, Heard::Now) {
            Some((kept, _, apart)) => (kept, OverrideKind::Separation, format!("{why}, {apart}")),
            None => (in_place, OverrideKind::Separation, why),
        }
    }

    /// Holds what the platform will command within `caps`: a velocity setpoint is scaled back;
    /// a position target whose pull (its feed-forward plus the platform's correction toward
    /// it) exceeds them is brought nearer, as a target at most the caps' pull away. Within a
    /// millimetre per second the setpoint is left as it is.
    fn capped(&self, sp: Setpoint, here: Vec3, caps: SpeedCaps) -> Option<(Setpoint, String)> {
        const SLACK_MPS: f64 = 1e-3;
        let over = |v: &Vec3| {
            v.xy().norm() > caps.horizontal_mps + SLACK_MPS
                || v.z > caps.up_mps + SLACK_MPS
                || -v.z > caps.down_mps + SLACK_MPS
        };
        let (v, yaw) = intended_velocity(&sp, here, &self.position_loop);
        if !over(&v) {
            return None;
        }
        let why = format!(
            "setpoint over the speed limit ({:.2} m/s horizontal, {:.2} m/s vertical; limit {:.2} m/s): scaled back",
            v.xy().norm(),
            v.z,
            caps.horizontal_mps
        );
        let out = match sp {
            Setpoint::Velocity { .. } => Setpoint::Velocity {
                velocity_enu_mps: caps.clamp(v),
                yaw,
            },
            Setpoint::Position { .. } => {
                let pull = caps.clamp(v);
                let l = &self.position_loop;
                Setpoint::Position {
                    position_enu_m: here
                        + Vec3::new(
                            pull.x / l.gain_xy_per_s,
                            pull.y / l.gain_xy_per_s,
                            pull.z / l.gain_z_per_s,
                        ),
                    velocity_ff_enu_mps: Vec3::zeros(),
                    yaw,
                }
            }
        };
        Some((out, why))
    }

    /// Scales back a velocity setpoint beyond the vehicle's limits and caps turn rates.
    fn limited(&self, sp: Setpoint) -> Option<(Setpoint, OverrideKind, String)> {
        let l = &self.config.limits;
        let Setpoint::Velocity {
            velocity_enu_mps: v,
            yaw,
        } = sp
        else {
            return None;
        };
        let max_xy = l.max_horizontal_speed_mps * LIMIT_HEADROOM;
        let xy = v.xy().norm();
        let mut out = v;
        if xy > max_xy {
            out.x *= max_xy / xy;
            out.y *= max_xy / xy;
        }
        out.z = out.z.clamp(
            -l.max_down_speed_mps * LIMIT_HEADROOM,
            l.max_up_speed_mps * LIMIT_HEADROOM,
        );
        let max_rate = l.max_yaw_rate_radps * LIMIT_HEADROOM;
        let yaw_out = match yaw {
            YawTarget::Rate(r) => YawTarget::Rate(r.clamp(-max_rate, max_rate)),
            a => a,
        };
        if out == v && yaw_out == yaw {
            return None;
        }
        let why = format!(
            "setpoint beyond the vehicle's limits ({:.1} m/s horizontal, {:.1} m/s vertical): scaled back",
            xy, v.z
        );
        Some((
            Setpoint::Velocity {
                velocity_enu_mps: out,
                yaw: yaw_out,
            },
            OverrideKind::Limit,
            why,
        ))
    }
}

fn yaw_of(sp: &Setpoint) -> YawTarget {
    match sp {
        Setpoint::Position { yaw, .. } | Setpoint::Velocity { yaw, .. } => *yaw,
    }
}

/// The velocity a setpoint asks for: its own, or the feed-forward plus the platform's
/// correction toward its position target.
fn intended_velocity(sp: &Setpoint, here: Vec3, position_loop: &PositionLoop) -> (Vec3, YawTarget) {
    match *sp {
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw,
        } => (velocity_enu_mps, yaw),
        Setpoint::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            yaw,
        } => (
            velocity_ff_enu_mps + position_loop.correction(position_enu_m - here),
            yaw,
        ),
    }
}

fn finite(sp: &Setpoint) -> bool {
    let yaw_ok = |y: &YawTarget| match y {
        YawTarget::Angle(a) | YawTarget::Rate(a) => a.is_finite(),
    };
    match sp {
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw,
        } => velocity_enu_mps.iter().all(|v| v.is_finite()) && yaw_ok(yaw),
        Setpoint::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            yaw,
        } => {
            position_enu_m.iter().all(|v| v.is_finite())
                && velocity_ff_enu_mps.iter().all(|v| v.is_finite())
                && yaw_ok(yaw)
        }
    }
}

#[cfg(test)]
mod tests;

/// Why to hold, when a remote drone that was flying fell silent and is not accounted for yet:
/// it could be anywhere, and its Kestrel, if alive, holds as well (see `fleet_bus::remote`).
fn held_for_silence(me: &str, fleet: &FleetView) -> Option<String> {
    let other = fleet.others(me).find(|d| d.unaccounted)?;
    Some(format!(
        "{} fell silent while flying: holding until it is heard again or accounted for",
        other.id
    ))
}
