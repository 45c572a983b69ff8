//! Frames registered over the API: a user frame's pose in its parent and how it moves, checked
//! and bounded, set in every drone (or the one it names) all or none; the [`FrameRegistry`]
//! keeps them (for the API's list, the store and a restart).
//!
//! In: a [`FrameRegistration`]. Out: the drones' frame trees changed, or a [`HostError::Frame`]
//! naming the field, or the loaded mission the new frame would make invalid.

use super::{Host, HostError};
use crate::estimator::frames::{FrameMotion, BASE_LINK, EARTH, MAP, ODOM};
use crate::mission::ValidationContext;
use crate::types::{Pose, Vec3};
use serde::{Deserialize, Serialize};
use serde_json::Value;
use std::time::Duration;

fn earth() -> String {
    EARTH.to_string()
}

/// A user frame: its pose in a parent frame now, and optionally how it moves.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct FrameRegistration {
    pub frame_id: String,
    #[serde(default = "earth")]
    pub parent: String,
    #[serde(default)]
    pub translation_m: [f64; 3],
    #[serde(default)]
    pub yaw_rad: f64,
    /// Constant velocity of the frame in its parent (m/s).
    #[serde(default)]
    pub velocity_mps: [f64; 3],
    /// Constant yaw rate (rad/s), e.g. a nacelle turning into the wind.
    #[serde(default)]
    pub yaw_rate_radps: f64,
    /// Only this drone; absent = every drone.
    #[serde(default)]
    pub drone_id: Option<String>,
}

/// Largest translation of a registered frame from its parent (m): 100 km.
pub const MAX_FRAME_OFFSET_M: f64 = 1e5;
/// Fastest a registered frame may move (m/s) and turn (rad/s).
pub const MAX_FRAME_SPEED_MPS: f64 = 50.0;
pub const MAX_FRAME_YAW_RATE_RADPS: f64 = 10.0;
/// Most frames registered over the API (all drones together, so also per drone); replacing a
/// registered one is always allowed.
pub const MAX_FRAMES: usize = 256;

impl FrameRegistration {
    /// Names and numbers: built-ins are not redefined, every number is finite and bounded.
    fn check(&self) -> Result<(), HostError> {
        let bad = |what: String| Err(HostError::Frame(format!("{}: {what}", self.frame_id)));
        if [EARTH, MAP, ODOM, BASE_LINK].contains(&self.frame_id.as_str()) {
            return bad("a built-in frame cannot be redefined".into());
        }
        let vector = |field: &str, v: &[f64; 3], unit: &str| {
            v.iter()
                .enumerate()
                .find(|(_, c)| !c.is_finite())
                .map(|(k, c)| format!("{field}[{k}] is {c}, not a finite number ({unit})"))
        };
        let scalar = |field: &str, v: f64, unit: &str| {
            (!v.is_finite()).then(|| format!("{field} is {v}, not a finite number ({unit})"))
        };
        let not_finite = vector("translation_m", &self.translation_m, "m")
            .or_else(|| vector("velocity_mps", &self.velocity_mps, "m/s"))
            .or_else(|| scalar("yaw_rad", self.yaw_rad, "rad"))
            .or_else(|| scalar("yaw_rate_radps", self.yaw_rate_radps, "rad/s"));
        if let Some(message) = not_finite {
            return bad(message);
        }
        let norm = |v: &[f64; 3]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
        if norm(&self.translation_m) > MAX_FRAME_OFFSET_M {
            return bad(format!(
                "translation_m is more than {MAX_FRAME_OFFSET_M} m from the parent"
            ));
        }
        if norm(&self.velocity_mps) > MAX_FRAME_SPEED_MPS {
            return bad(format!(
                "velocity_mps is faster than {MAX_FRAME_SPEED_MPS} m/s"
            ));
        }
        if self.yaw_rate_radps.abs() > MAX_FRAME_YAW_RATE_RADPS {
            return bad(format!(
                "yaw_rate_radps is faster than {MAX_FRAME_YAW_RATE_RADPS} rad/s"
            ));
        }
        Ok(())
    }

    fn motion(&self, now: Duration) -> FrameMotion {
        let [x, y, z] = self.translation_m;
        let [vx, vy, vz] = self.velocity_mps;
        FrameMotion {
            pose_in_parent: Pose::from_position_yaw(Vec3::new(x, y, z), self.yaw_rad),
            stamp: now,
            velocity_mps: Vec3::new(vx, vy, vz),
            yaw_rate_radps: self.yaw_rate_radps,
        }
    }
}

/// The frames registered so far, in order, and a revision that moves with every change.
#[derive(Debug, Default)]
pub(super) struct FrameRegistry {
    frames: Vec<FrameRegistration>,
    revision: u64,
}

impl FrameRegistry {
    pub(super) fn list(&self) -> &[FrameRegistration] {
        &self.frames
    }

    /// Moves with every registration, so the store is handed the frames only when they changed.
    pub(super) fn revision(&self) -> u64 {
        self.revision
    }

    /// Refuses a new frame beyond [`MAX_FRAMES`]; replacing a registered one is always allowed.
    fn check_room(&self, frame: &FrameRegistration) -> Result<(), HostError> {
        let known = self
            .frames
            .iter()
            .any(|f| f.frame_id == frame.frame_id && f.drone_id == frame.drone_id);
        if !known && self.frames.len() >= MAX_FRAMES {
            return Err(HostError::Frame(format!(
                "{}: {MAX_FRAMES} frames are registered already; replace one",
                frame.frame_id
            )));
        }
        Ok(())
    }

    /// Keeps `frame`, in place of the one with its id for the same drone(s).
    pub(super) fn insert(&mut self, frame: FrameRegistration) {
        self.frames
            .retain(|f| !(f.frame_id == frame.frame_id && f.drone_id == frame.drone_id));
        self.frames.push(frame);
        self.revision += 1;
    }
}

impl Host {
    /// Registers or updates a frame in every drone (or the one it names); all or none. A loaded
    /// mission that the new frame would make invalid (a goal beyond the geofence, a frame cycle)
    /// refuses the change, with that mission's errors.
    pub fn set_frame(&mut self, frame: FrameRegistration) -> Result<(), HostError> {
        frame.check()?;
        self.frames.check_room(&frame)?;
        let targets: Vec<usize> = match &frame.drone_id {
            Some(d) => vec![self.route(Some(d))?],
            None => (0..self.cores.len()).collect(),
        };
        let motion = frame.motion(self.now);
        for &i in &targets {
            if let Some(core) = self.cores.get(i) {
                let mut trial = core.frames().clone();
                trial.set(&frame.frame_id, &frame.parent, motion)?;
                self.recheck_missions(i, &frame.frame_id, &trial)?;
            }
        }
        for &i in &targets {
            if let Some(core) = self.cores.get_mut(i) {
                core.set_frame(&frame.frame_id, &frame.parent, motion)?;
            }
        }
        self.frames.insert(frame);
        Ok(())
    }

    /// Validates again, against `frames`, every mission of drone `i` with a goal in `frame_id`.
    fn recheck_missions(
        &self,
        i: usize,
        frame_id: &str,
        frames: &crate::estimator::frames::FrameTree,
    ) -> Result<(), HostError> {
        let (Some(ctx), Some(ex)) = (self.validation_context(i), self.executors.get(i)) else {
            return Ok(());
        };
        let ctx = ValidationContext { frames, ..ctx };
        for (id, loaded) in ex.missions() {
            let uses = loaded.mission.items.iter().any(|item| {
                item.goal()
                    .is_ok_and(|g| g.get("frame_id").and_then(Value::as_str) == Some(frame_id))
            });
            if !uses {
                continue;
            }
            let written = loaded
                .mission
                .as_written()
                .and_then(serde_json::to_value)
                .unwrap_or_default();
            if let Err(errors) = crate::mission::validate::validate_value(&written, &ctx) {
                let first: Vec<String> = errors.iter().take(3).map(ToString::to_string).collect();
                return Err(HostError::Frame(format!(
                    "{frame_id}: loaded mission {id} would no longer be valid: {}",
                    first.join("; ")
                )));
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn frame(id: &str, drone: Option<&str>) -> FrameRegistration {
        let mut f: FrameRegistration =
            serde_json::from_value(serde_json::json!({ "frame_id": id })).unwrap();
        f.drone_id = drone.map(str::to_string);
        f
    }

    /// A frame replaces the one with its id for the same drone(s) only; every change moves the
    /// revision.
    #[test]
    fn the_registry_replaces_by_id_and_drone() {
        let mut r = FrameRegistry::default();
        r.insert(frame("pad", None));
        r.insert(frame("pad", Some("drone_1")));
        let mut moved = frame("pad", None);
        moved.translation_m = [1.0, 2.0, 0.0];
        r.insert(moved.clone());
        assert_eq!(r.list(), [frame("pad", Some("drone_1")), moved]);
        assert_eq!(r.revision(), 3);
    }

    /// The registry is bounded: a new frame beyond [`MAX_FRAMES`] is refused, a registered one
    /// can still be replaced.
    #[test]
    fn the_registry_is_bounded_but_replacing_is_allowed() {
        let mut r = FrameRegistry::default();
        for k in 0..MAX_FRAMES {
            r.insert(frame(&format!("f{k}"), None));
        }
        let refused = r.check_room(&frame("one_more", None)).unwrap_err();
        assert!(refused.to_string().contains("one_more"), "{refused}");
        assert_eq!(r.check_room(&frame("f7", None)), Ok(()));
    }
}
