//! A `goal_pose` from ROS 2 as a `navigate_to` mission.
//!
//! In: the bytes of a `geometry_msgs/msg/PoseStamped` from outside, the drone it was sent to
//! and whether that drone is airborne (and at which height). Out: the mission JSON (a takeoff
//! first when the drone is on the ground), which the host then validates as any mission the API
//! is given (geofence, limits); or a [`GoalError`] saying why the goal is refused.
//!
//! The goal is in `world` (Kestrel's ENU frame, as published on `/tf`); its yaw becomes the
//! fixed yaw to hold. A goal at or below [`MIN_HEIGHT_M`] (RViz's "2D Goal Pose" sends z = 0)
//! keeps the drone's height, or takes off to [`TAKEOFF_HEIGHT_M`].

use super::cdr::CdrError;
use super::msgs::{decode_pose_stamped, PoseStampedMsg};
use serde_json::{json, Value};

/// Largest `goal_pose` payload read: a PoseStamped with a 256-byte frame id is under 340 bytes.
pub const MAX_GOAL_BYTES: usize = 1024;
/// The only frame a goal may be given in.
pub const WORLD_FRAME: &str = "world";
/// A goal at or below this height is read as "at the drone's height" (m).
pub const MIN_HEIGHT_M: f64 = 0.3;
/// Height a grounded drone takes off to for a goal without a height (m).
pub const TAKEOFF_HEIGHT_M: f64 = 2.0;
/// Takeoff climb speed (m/s).
const TAKEOFF_SPEED_MPS: f64 = 1.0;

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum GoalError {
    #[error("{0} bytes, more than the {MAX_GOAL_BYTES} a PoseStamped can take")]
    TooLarge(usize),
    #[error("not a PoseStamped: {0}")]
    Decode(#[from] CdrError),
    #[error("header.frame_id is `{0}`: goals are taken in `{WORLD_FRAME}` only")]
    Frame(String),
    #[error("pose.position is not finite")]
    NotFinite,
    #[error("pose.orientation is not a unit quaternion")]
    Orientation,
}

/// A goal that passed the checks a message can fail on its own.
#[derive(Debug, Clone, PartialEq)]
pub struct Goal {
    pub position_m: [f64; 3],
    pub yaw_rad: f64,
}

/// Reads and checks a goal; the size is checked before anything is decoded.
pub fn read_goal(bytes: &[u8]) -> Result<Goal, GoalError> {
    if bytes.len() > MAX_GOAL_BYTES {
        return Err(GoalError::TooLarge(bytes.len()));
    }
    let PoseStampedMsg { frame_id, pose, .. } = decode_pose_stamped(bytes)?;
    if frame_id != WORLD_FRAME {
        return Err(GoalError::Frame(frame_id));
    }
    if !pose.position_m.iter().all(|v| v.is_finite()) {
        return Err(GoalError::NotFinite);
    }
    let yaw_rad = pose.yaw_rad().ok_or(GoalError::Orientation)?;
    Ok(Goal {
        position_m: pose.position_m,
        yaw_rad,
    })
}

/// Where the drone is when the goal comes: its height when airborne.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Aloft {
    Grounded,
    AtHeight(f64),
}

/// The mission that flies `drone` to `goal`.
pub fn mission(drone: &str, goal: &Goal, aloft: Aloft, speed_mps: f64) -> Value {
    let [x, y, z] = goal.position_m;
    let height = match aloft {
        _ if z > MIN_HEIGHT_M => z,
        Aloft::AtHeight(h) => h.max(MIN_HEIGHT_M),
        Aloft::Grounded => TAKEOFF_HEIGHT_M,
    };
    let mut plan = Vec::new();
    if aloft == Aloft::Grounded {
        plan.push(json!({"behavior": "takeoff",
            "args": {"height": height, "speed": TAKEOFF_SPEED_MPS}}));
    }
    plan.push(json!({"behavior": "navigate_to", "args": {
        "x": x, "y": y, "z": height, "speed": speed_mps, "frame_id": "earth",
        "yaw_mode": "fixed", "yaw_angle": goal.yaw_rad,
    }}));
    json!({"target": drone, "plan": plan})
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ros2::msgs::{pose_stamped, Pose, Stamp};

    fn bytes(frame: &str, p: [f64; 3], q: [f64; 4]) -> Vec<u8> {
        let pose = Pose {
            position_m: p,
            orientation_xyzw: q,
        };
        pose_stamped(Stamp::default(), frame, &pose)
    }

    #[test]
    fn a_good_goal_becomes_a_mission() {
        let goal = read_goal(&bytes("world", [3.0, -1.0, 2.5], [0.0, 0.0, 0.0, 1.0])).unwrap();
        assert_eq!(goal.position_m, [3.0, -1.0, 2.5]);
        let m = mission("drone_0", &goal, Aloft::Grounded, 1.5);
        assert_eq!(m["target"], "drone_0");
        assert_eq!(m["plan"][0]["behavior"], "takeoff");
        assert_eq!(m["plan"][0]["args"]["height"], 2.5);
        assert_eq!(m["plan"][1]["args"]["x"], 3.0);
        assert_eq!(m["plan"][1]["args"]["speed"], 1.5);
        // A flat goal keeps the height it is flown at.
        let flat = Goal {
            position_m: [1.0, 1.0, 0.0],
            yaw_rad: 0.0,
        };
        let m = mission("d", &flat, Aloft::AtHeight(4.0), 1.0);
        assert_eq!(m["plan"].as_array().unwrap().len(), 1);
        assert_eq!(m["plan"][0]["args"]["z"], 4.0);
        let m = mission("d", &flat, Aloft::Grounded, 1.0);
        assert_eq!(m["plan"][1]["args"]["z"], TAKEOFF_HEIGHT_M);
    }

    #[test]
    fn bad_goals_are_refused_with_the_reason() {
        let unit = [0.0, 0.0, 0.0, 1.0];
        assert_eq!(
            read_goal(&vec![0; MAX_GOAL_BYTES + 1]),
            Err(GoalError::TooLarge(MAX_GOAL_BYTES + 1))
        );
        assert!(matches!(read_goal(&[0, 1, 0]), Err(GoalError::Decode(_))));
        assert_eq!(
            read_goal(&bytes("base_link", [0.0; 3], unit)),
            Err(GoalError::Frame("base_link".into()))
        );
        assert_eq!(
            read_goal(&bytes("world", [f64::NAN, 0.0, 1.0], unit)),
            Err(GoalError::NotFinite)
        );
        assert_eq!(
            read_goal(&bytes("world", [0.0; 3], [0.0; 4])),
            Err(GoalError::Orientation)
        );
    }
}
