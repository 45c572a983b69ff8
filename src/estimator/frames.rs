//! Frame tree: named frames linked to a parent by a static or time-varying transform.
//!
//! In: registrations and updates of transforms (from config, the estimator and the API).
//! Out: the pose of any frame in any other at a given time, so a goal can be given in any
//! registered frame, including one that moves (a yawing wind-turbine nacelle, a moving target).
//!
//! Built-in frames: `earth` (root, ENU at the geodetic origin), `map` and `odom` (children of
//! `earth`, identity unless configured) and `base_link` (the vehicle, set by the estimator).

use crate::types::{Pose, Vec3};
use nalgebra::{Isometry3, Translation3, UnitQuaternion};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::time::Duration;

pub const EARTH: &str = "earth";
pub const MAP: &str = "map";
pub const ODOM: &str = "odom";
pub const BASE_LINK: &str = "base_link";

/// How a frame moves relative to its parent: the transform at `stamp`, then constant
/// linear velocity (in the parent frame) and yaw rate, so moving frames are deterministic.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct FrameMotion {
    pub pose_in_parent: Pose,
    pub stamp: Duration,
    pub velocity_mps: Vec3,
    pub yaw_rate_radps: f64,
}

impl FrameMotion {
    pub fn fixed(pose_in_parent: Pose) -> Self {
        Self {
            pose_in_parent,
            stamp: Duration::ZERO,
            velocity_mps: Vec3::zeros(),
            yaw_rate_radps: 0.0,
        }
    }

    fn at(&self, now: Duration) -> Isometry3<f64> {
        let dt = now.as_secs_f64() - self.stamp.as_secs_f64();
        let translation = self.pose_in_parent.position_m + self.velocity_mps * dt;
        let rotation = UnitQuaternion::from_euler_angles(0.0, 0.0, self.yaw_rate_radps * dt)
            * self.pose_in_parent.orientation;
        Isometry3::from_parts(Translation3::from(translation), rotation)
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
struct FrameNode {
    parent: String,
    motion: FrameMotion,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum FrameError {
    #[error("unknown frame `{0}`")]
    Unknown(String),
    #[error("frame `{0}` cannot be redefined: it is built in")]
    BuiltIn(String),
    #[error("frame `{frame}` would create a cycle through `{parent}`")]
    Cycle { frame: String, parent: String },
    #[error("frame id must be non-empty ASCII without spaces, got `{0}`")]
    BadName(String),
}

/// A tree of frames rooted at `earth`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct FrameTree {
    frames: BTreeMap<String, FrameNode>,
}

impl Default for FrameTree {
    fn default() -> Self {
        Self::new()
    }
}

impl FrameTree {
    pub fn new() -> Self {
        let mut frames = BTreeMap::new();
        for (name, parent) in [(MAP, EARTH), (ODOM, MAP), (BASE_LINK, ODOM)] {
            frames.insert(
                name.to_string(),
                FrameNode {
                    parent: parent.to_string(),
                    motion: FrameMotion::fixed(Pose::identity()),
                },
            );
        }
        Self { frames }
    }

    pub fn contains(&self, frame: &str) -> bool {
        frame == EARTH || self.frames.contains_key(frame)
    }

    pub fn names(&self) -> impl Iterator<Item = &str> {
        std::iter::once(EARTH).chain(self.frames.keys().map(String::as_str))
    }

    /// Registers or replaces a user frame. Built-in frames other than `map` and `odom` offsets
    /// are refused; `base_link` belongs to the estimator.
    pub fn set(
        &mut self,
        frame: &str,
        parent: &str,
        motion: FrameMotion,
    ) -> Result<(), FrameError> {
        if frame.is_empty() || !frame.is_ascii() || frame.contains(char::is_whitespace) {
            return Err(FrameError::BadName(frame.to_string()));
        }
        if frame == EARTH || frame == BASE_LINK {
            return Err(FrameError::BuiltIn(frame.to_string()));
        }
        if !self.contains(parent) {
            return Err(FrameError::Unknown(parent.to_string()));
        }
        if self.chain(parent)?.iter().any(|f| f == frame) {
            return Err(FrameError::Cycle {
                frame: frame.to_string(),
                parent: parent.to_string(),
            });
        }
        self.frames.insert(
            frame.to_string(),
            FrameNode {
                parent: parent.to_string(),
                motion,
            },
        );
        Ok(())
    }

    /// The same frames as `other`, the vehicle's own pose (`base_link`) aside.
    pub fn same_frames_as(&self, other: &FrameTree) -> bool {
        self.frames.len() == other.frames.len()
            && self
                .frames
                .iter()
                .zip(&other.frames)
                .all(|((a, na), (b, nb))| a == b && (a == BASE_LINK || na == nb))
    }

    /// Sets the vehicle pose (in `odom`), as estimated at `stamp`.
    pub fn set_base_link(&mut self, pose_in_odom: Pose, stamp: Duration) {
        if let Some(node) = self.frames.get_mut(BASE_LINK) {
            node.motion = FrameMotion {
                stamp,
                ..FrameMotion::fixed(pose_in_odom)
            };
        }
    }

    /// Frames from `frame` up to (and excluding) `earth`.
    fn chain(&self, frame: &str) -> Result<Vec<String>, FrameError> {
        let mut out = Vec::new();
        let mut current = frame;
        while current != EARTH {
            let node = self
                .frames
                .get(current)
                .ok_or_else(|| FrameError::Unknown(current.to_string()))?;
            out.push(current.to_string());
            if out.len() > self.frames.len() {
                return Err(FrameError::Cycle {
                    frame: frame.to_string(),
                    parent: node.parent.clone(),
                });
            }
            current = &node.parent;
        }
        Ok(out)
    }

    /// Transform taking coordinates in `frame` to coordinates in `earth` at time `now`.
    pub fn frame_in_earth(&self, frame: &str, now: Duration) -> Result<Isometry3<f64>, FrameError> {
        let mut iso = Isometry3::identity();
        for name in self.chain(frame)? {
            let node = self
                .frames
                .get(&name)
                .ok_or_else(|| FrameError::Unknown(name.clone()))?;
            iso = node.motion.at(now) * iso;
        }
        Ok(iso)
    }

    /// A point given in `frame` expressed in `earth` at time `now`.
    pub fn point_to_earth(
        &self,
        point_m: &Vec3,
        frame: &str,
        now: Duration,
    ) -> Result<Vec3, FrameError> {
        Ok(self
            .frame_in_earth(frame, now)?
            .transform_point(&(*point_m).into())
            .coords)
    }

    /// A yaw given in `frame` expressed in `earth` (heading of the frame added).
    pub fn yaw_to_earth(
        &self,
        yaw_rad: f64,
        frame: &str,
        now: Duration,
    ) -> Result<f64, FrameError> {
        let rotation = self.frame_in_earth(frame, now)?.rotation;
        Ok(crate::types::wrap_angle_rad(
            rotation.euler_angles().2 + yaw_rad,
        ))
    }

    /// Pose of `frame` in `target` at time `now`.
    pub fn pose_in(&self, frame: &str, target: &str, now: Duration) -> Result<Pose, FrameError> {
        let a = self.frame_in_earth(frame, now)?;
        let b = self.frame_in_earth(target, now)?;
        Ok(Pose::from_isometry(&(b.inverse() * a)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_2;

    fn close(a: &Vec3, b: &Vec3) -> bool {
        (a - b).norm() < 1e-9
    }

    #[test]
    fn point_in_rotated_and_translated_frame() {
        let mut tree = FrameTree::new();
        let pose = Pose::from_position_yaw(Vec3::new(10.0, 0.0, 0.0), FRAC_PI_2);
        tree.set("turbine", EARTH, FrameMotion::fixed(pose))
            .unwrap();
        let p = tree
            .point_to_earth(&Vec3::new(1.0, 0.0, 2.0), "turbine", Duration::ZERO)
            .unwrap();
        assert!(close(&p, &Vec3::new(10.0, 1.0, 2.0)), "{p}");
    }

    #[test]
    fn chained_frames_compose() {
        let mut tree = FrameTree::new();
        tree.set(
            "tower",
            EARTH,
            FrameMotion::fixed(Pose::from_position_yaw(Vec3::new(0.0, 0.0, 50.0), 0.0)),
        )
        .unwrap();
        tree.set(
            "nacelle",
            "tower",
            FrameMotion::fixed(Pose::from_position_yaw(Vec3::new(0.0, 0.0, 5.0), FRAC_PI_2)),
        )
        .unwrap();
        let p = tree
            .point_to_earth(&Vec3::new(-20.0, 0.0, 0.0), "nacelle", Duration::ZERO)
            .unwrap();
        assert!(close(&p, &Vec3::new(0.0, -20.0, 55.0)), "{p}");
    }

    #[test]
    fn moving_frame_follows_its_motion() {
        let mut tree = FrameTree::new();
        let motion = FrameMotion {
            pose_in_parent: Pose::from_position_yaw(Vec3::zeros(), 0.0),
            stamp: Duration::from_secs(2),
            velocity_mps: Vec3::new(1.0, 0.0, 0.0),
            yaw_rate_radps: FRAC_PI_2,
        };
        tree.set("target", EARTH, motion).unwrap();
        let p = tree
            .point_to_earth(&Vec3::new(1.0, 0.0, 0.0), "target", Duration::from_secs(3))
            .unwrap();
        // One second later: moved 1 m east and turned 90 degrees left.
        assert!(close(&p, &Vec3::new(1.0, 1.0, 0.0)), "{p}");
    }

    #[test]
    fn unknown_parent_cycle_and_builtins_are_refused() {
        let mut tree = FrameTree::new();
        let fixed = FrameMotion::fixed(Pose::identity());
        assert_eq!(
            tree.set("a", "nope", fixed),
            Err(FrameError::Unknown("nope".into()))
        );
        tree.set("a", EARTH, fixed).unwrap();
        tree.set("b", "a", fixed).unwrap();
        assert!(matches!(
            tree.set("a", "b", fixed),
            Err(FrameError::Cycle { .. })
        ));
        assert!(matches!(
            tree.set(EARTH, MAP, fixed),
            Err(FrameError::BuiltIn(_))
        ));
        assert!(matches!(
            tree.set("has space", EARTH, fixed),
            Err(FrameError::BadName(_))
        ));
    }

    #[test]
    fn yaw_in_a_turned_frame_is_expressed_in_earth() {
        let mut tree = FrameTree::new();
        tree.set(
            "panel",
            EARTH,
            FrameMotion::fixed(Pose::from_position_yaw(Vec3::zeros(), 3.0)),
        )
        .unwrap();
        let yaw = tree.yaw_to_earth(0.5, "panel", Duration::ZERO).unwrap();
        assert!(
            (yaw - crate::types::wrap_angle_rad(3.5)).abs() < 1e-9,
            "{yaw}"
        );
    }

    #[test]
    fn moving_map_offset_carries_its_children() {
        let mut tree = FrameTree::new();
        let drift = FrameMotion {
            velocity_mps: Vec3::new(0.0, 0.1, 0.0),
            ..FrameMotion::fixed(Pose::from_position_yaw(Vec3::new(1.0, 0.0, 0.0), 0.0))
        };
        tree.set(MAP, EARTH, drift).unwrap();
        tree.set_base_link(
            Pose::from_position_yaw(Vec3::new(2.0, 0.0, 1.0), 0.0),
            Duration::ZERO,
        );
        let p = tree
            .pose_in(BASE_LINK, EARTH, Duration::from_secs(10))
            .unwrap();
        assert!(
            close(&p.position_m, &Vec3::new(3.0, 1.0, 1.0)),
            "{}",
            p.position_m
        );
        // Replacing a user frame keeps one entry with the new transform.
        let fixed = FrameMotion::fixed(Pose::identity());
        tree.set("a", EARTH, fixed).unwrap();
        tree.set("a", MAP, fixed).unwrap();
        assert_eq!(tree.names().filter(|n| *n == "a").count(), 1);
        let a = tree
            .point_to_earth(&Vec3::zeros(), "a", Duration::ZERO)
            .unwrap();
        assert!(close(&a, &Vec3::new(1.0, 0.0, 0.0)));
    }

    #[test]
    fn pose_of_base_link_in_a_user_frame() {
        let mut tree = FrameTree::new();
        tree.set(
            "panel_7",
            EARTH,
            FrameMotion::fixed(Pose::from_position_yaw(Vec3::new(5.0, 5.0, 0.0), 0.0)),
        )
        .unwrap();
        tree.set_base_link(
            Pose::from_position_yaw(Vec3::new(6.0, 5.0, 2.0), 0.0),
            Duration::ZERO,
        );
        let p = tree.pose_in(BASE_LINK, "panel_7", Duration::ZERO).unwrap();
        assert!(close(&p.position_m, &Vec3::new(1.0, 0.0, 2.0)));
    }
}
