//! The safety stage: the last step of the tick, after the behaviors and the controller and
//! before the platform. Whatever a behavior asked (in any frame, however the frame moved), the
//! setpoint that leaves the core is finite, within the vehicle's limits, inside the geofence and
//! keeps its distance from the other drones of the fleet view; otherwise it is replaced, and the
//! override is reported with its reason. The link-loss policy lives in the mission executor.
//!
//! In: the controller's setpoint, the vehicle's state and home, the fleet view, the time.
//! Out: the setpoint to send and, when it changed, an [`Override`] saying why.

pub mod geofence;

use crate::behavior::fleet::FleetView;
use crate::config::GeofenceSection;
use crate::control::{ControllerConfig, Setpoint, YawTarget};
use crate::types::{EstimatedState, Vec3};
use geofence::Fence;
use serde::Serialize;

/// What the stage enforces (from `[geofence]`, `[safety]`, `[controller]`, `[behaviors]`).
#[derive(Debug, Clone, PartialEq)]
pub struct SafetyConfig {
    pub geofence: GeofenceSection,
    /// Clamped targets are put this far inside the fence (m).
    pub geofence_margin_m: f64,
    /// Least distance kept from another flying drone (m, centre to centre).
    pub min_separation_m: f64,
    /// Speed and turn-rate limits; a setpoint beyond them by more than 10 % is scaled back.
    pub limits: ControllerConfig,
    /// Braking acceleration used to look ahead of a velocity setpoint (m/s^2).
    pub braking_mps2: f64,
}

impl Default for SafetyConfig {
    fn default() -> Self {
        Self {
            geofence: GeofenceSection::default(),
            geofence_margin_m: 0.5,
            min_separation_m: 1.0,
            limits: ControllerConfig::default(),
            braking_mps2: 2.0,
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
    /// The override of the previous tick (an episode is reported when it starts).
    active: Option<OverrideKind>,
}

/// Headroom over the controller's own limits before a setpoint counts as beyond them.
const LIMIT_HEADROOM: f64 = 1.1;

impl SafetyStage {
    pub fn new(config: SafetyConfig) -> Self {
        Self {
            config,
            active: None,
        }
    }

    /// Checks one setpoint of drone `me`. Returns the setpoint to send, and an override when
    /// one starts (or changes kind) this tick.
    pub fn check(
        &mut self,
        me: &str,
        state: &EstimatedState,
        home_enu_m: Vec3,
        flying: bool,
        setpoint: Option<Setpoint>,
        fleet: &FleetView,
    ) -> (Option<Setpoint>, Option<Override>) {
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
        } else if !flying {
            (sp, None)
        } else {
            let fence = Fence {
                section: &self.config.geofence,
                home_enu_m,
                margin_m: self.config.geofence_margin_m,
            };
            self.fenced(&fence, here, sp)
                .or_else(|| {
                    // Held in place, still turning as asked: a turn moves nothing toward anyone
                    // and keeps the range beams sweeping.
                    held_for_silence(me, fleet).map(|why| {
                        let yaw = match sp {
                            Setpoint::Velocity { yaw, .. } | Setpoint::Position { yaw, .. } => yaw,
                        };
                        let in_place = Setpoint::Velocity {
                            velocity_enu_mps: Vec3::zeros(),
                            yaw,
                        };
                        (in_place, OverrideKind::Separation, why)
                    })
                })
                .or_else(|| self.separated(me, state, sp, fleet))
                .or_else(|| self.limited(sp))
                .map_or((sp, None), |(s, kind, why)| (s, Some((kind, why))))
        };
        let kind = change.as_ref().map(|(k, _)| *k);
        let report = match change {
            Some((k, reason)) if self.active != Some(k) => Some(Override { kind: k, reason }),
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

    /// Takes out the part of the motion that closes in on a drone nearer than the guard
    /// distance, and pushes apart inside the minimum separation.
    fn separated(
        &self,
        me: &str,
        state: &EstimatedState,
        sp: Setpoint,
        fleet: &FleetView,
    ) -> Option<(Setpoint, OverrideKind, String)> {
        let here = state.pose.position_m;
        let min = self.config.min_separation_m;
        // A remote drone may be up to its uncertainty nearer than where it was heard.
        let (other, d) = fleet.nearest_flying(me, &here)?;
        let d = d - other.uncertainty_m;
        // From a silent one, whose uncertainty already holds everywhere it could have gone,
        // only the separation itself is kept (no slowing margin on top).
        let guard = if other.silent { min } else { 2.0 * min };
        if d >= guard {
            return None;
        }
        // Apart sideways where the drones are side by side (a climb or a descent is never
        // turned into a sideways drift toward obstacles); along the line between them when one
        // is right above the other.
        let offset = here - other.position_enu_m;
        let sideways = Vec3::new(offset.x, offset.y, 0.0);
        let away = if sideways.norm() > 0.5 * offset.norm() {
            sideways.try_normalize(1e-6)
        } else {
            offset.try_normalize(1e-6)
        }
        .unwrap_or_else(|| Vec3::new(1.0, 0.0, 0.0));
        let (mut v, yaw) =
            intended_velocity(&sp, here, self.config.limits.max_horizontal_speed_mps);
        let closing = -v.dot(&away);
        if closing <= 0.0 && d >= min {
            return None;
        }
        if closing > 0.0 {
            if other.silent {
                // Around a silent drone's spot nothing guides a sideways slide clear of
                // obstacles: stop instead.
                v = Vec3::zeros();
            } else {
                v += away * closing;
            }
        }
        // Pushed apart only from a drone heard now: from a silent one's last position, pushing
        // could as well be toward it.
        if d < min && !other.silent {
            v += away * (min - d).min(min);
        }
        let why = format!("{:.2} m from {}: keeping at least {min:.1} m", d, other.id);
        Some((
            Setpoint::Velocity {
                velocity_enu_mps: v,
                yaw,
            },
            OverrideKind::Separation,
            why,
        ))
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

/// The velocity a setpoint asks for: its own, or toward its position target at up to `max`.
fn intended_velocity(sp: &Setpoint, here: Vec3, max_mps: f64) -> (Vec3, YawTarget) {
    match *sp {
        Setpoint::Velocity {
            velocity_enu_mps,
            yaw,
        } => (velocity_enu_mps, yaw),
        Setpoint::Position {
            position_enu_m,
            velocity_ff_enu_mps,
            yaw,
        } => {
            let to = position_enu_m - here;
            let toward = to.try_normalize(1e-6).unwrap_or_default() * to.norm().min(max_mps);
            (toward + velocity_ff_enu_mps, yaw)
        }
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
