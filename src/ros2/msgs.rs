//! The ROS 2 messages Kestrel sends and reads, in CDR (`cdr`), with the names and Jazzy type
//! hashes rmw_zenoh puts in its key expressions.
//!
//! In: poses, velocities, paths, frames and grids in Kestrel's ENU world frame and FLU body
//! frame, which are REP-103's ENU and FLU as they are: no axis is changed. Out: bytes. And the
//! other way for `PoseStamped` (`goal_pose`), with every length bounded.

use super::cdr::{CdrError, CdrReader, CdrWriter};

/// A ROS message type as rmw_zenoh names it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct MsgType {
    /// `geometry_msgs/msg/PoseStamped`
    pub ros_name: &'static str,
    /// `geometry_msgs::msg::dds_::PoseStamped_` (the name in keys and tokens)
    pub dds_name: &'static str,
    /// REP-2011 type hash of the Jazzy type description.
    pub hash: &'static str,
}

// The hashes are Jazzy's, as its generated C headers carry them (`*__TYPE_HASH` in
// `<pkg>/msg/detail/<type>__struct.h`, e.g. micro-ROS/micro_ros_arduino's copies) and as
// `ros2 topic info -v` prints them; the unit tests pin each one.
pub const POSE_STAMPED: MsgType = MsgType {
    ros_name: "geometry_msgs/msg/PoseStamped",
    dds_name: "geometry_msgs::msg::dds_::PoseStamped_",
    hash: "RIHS01_10f3786d7d40fd2b54367835614bff85d4ad3b5dab62bf8bca0cc232d73b4cd8",
};
pub const ODOMETRY: MsgType = MsgType {
    ros_name: "nav_msgs/msg/Odometry",
    dds_name: "nav_msgs::msg::dds_::Odometry_",
    hash: "RIHS01_3cc97dc7fb7502f8714462c526d369e35b603cfc34d946e3f2eda2766dfec6e0",
};
pub const PATH: MsgType = MsgType {
    ros_name: "nav_msgs/msg/Path",
    dds_name: "nav_msgs::msg::dds_::Path_",
    hash: "RIHS01_1957a5bb3cee5da65c4e52e52b65a93df227efce4c20f8458b36e73066ca334b",
};
pub const TF_MESSAGE: MsgType = MsgType {
    ros_name: "tf2_msgs/msg/TFMessage",
    dds_name: "tf2_msgs::msg::dds_::TFMessage_",
    hash: "RIHS01_e369d0f05a23ae52508854b66f6aa0437f3449d652e8cbf22d5abe85d020f087",
};
pub const OCCUPANCY_GRID: MsgType = MsgType {
    ros_name: "nav_msgs/msg/OccupancyGrid",
    dds_name: "nav_msgs::msg::dds_::OccupancyGrid_",
    hash: "RIHS01_8d348150c12913a31ee0ec170fbf25089e4745d17035792a1ba94d6f0bc0cfc7",
};

/// Longest `frame_id` read from outside.
pub const MAX_FRAME_ID_LEN: usize = 256;

/// `builtin_interfaces/Time`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Stamp {
    pub sec: i32,
    pub nanosec: u32,
}

impl Stamp {
    /// Nanoseconds since the Unix epoch (wall clock), as ROS stamps them.
    pub fn from_unix_ns(ns: i64) -> Self {
        let sec = ns.div_euclid(1_000_000_000);
        Self {
            sec: i32::try_from(sec).unwrap_or(i32::MAX),
            nanosec: u32::try_from(ns.rem_euclid(1_000_000_000)).unwrap_or(0),
        }
    }
}

/// `geometry_msgs/Pose`: position (m) and orientation (x, y, z, w).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pose {
    pub position_m: [f64; 3],
    pub orientation_xyzw: [f64; 4],
}

impl Pose {
    /// At `p`, turned `yaw_rad` about the up axis (CCW from east).
    pub fn from_yaw(p: [f64; 3], yaw_rad: f64) -> Self {
        let (s, c) = (yaw_rad / 2.0).sin_cos();
        Self {
            position_m: p,
            orientation_xyzw: [0.0, 0.0, s, c],
        }
    }

    /// Yaw (rad) of the orientation, `None` for a quaternion that is not near unit length.
    pub fn yaw_rad(&self) -> Option<f64> {
        let [x, y, z, w] = self.orientation_xyzw;
        let norm2 = x * x + y * y + z * z + w * w;
        if !(0.81..=1.21).contains(&norm2) {
            return None;
        }
        Some((2.0 * (w * z + x * y)).atan2(1.0 - 2.0 * (y * y + z * z)))
    }
}

fn header(w: &mut CdrWriter, stamp: Stamp, frame_id: &str) {
    w.i32(stamp.sec);
    w.u32(stamp.nanosec);
    w.string(frame_id);
}

fn pose(w: &mut CdrWriter, p: &Pose) {
    for v in p.position_m.iter().chain(&p.orientation_xyzw) {
        w.f64(*v);
    }
}

fn vector3(w: &mut CdrWriter, v: [f64; 3]) {
    for c in v {
        w.f64(c);
    }
}

/// `float64[36]` of zeros: the covariance is not known.
fn unknown_covariance(w: &mut CdrWriter) {
    for _ in 0..36 {
        w.f64(0.0);
    }
}

/// `geometry_msgs/msg/PoseStamped`.
pub fn pose_stamped(stamp: Stamp, frame_id: &str, p: &Pose) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    pose(&mut w, p);
    w.finish()
}

/// `nav_msgs/msg/Odometry`: the pose in `frame_id`, the velocity in `child_frame_id` (FLU, as
/// REP-105 has it), covariances unknown (zeros).
pub fn odometry(
    stamp: Stamp,
    frame_id: &str,
    child_frame_id: &str,
    p: &Pose,
    velocity_flu_mps: [f64; 3],
) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    w.string(child_frame_id);
    pose(&mut w, p);
    unknown_covariance(&mut w);
    vector3(&mut w, velocity_flu_mps);
    vector3(&mut w, [0.0; 3]);
    unknown_covariance(&mut w);
    w.finish()
}

/// `nav_msgs/msg/Path`: each point with the path's stamp and frame, orientation unit.
pub fn path(stamp: Stamp, frame_id: &str, points_m: &[[f64; 3]]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    w.len(points_m.len());
    for p in points_m {
        header(&mut w, stamp, frame_id);
        pose(&mut w, &Pose::from_yaw(*p, 0.0));
    }
    w.finish()
}

/// One `geometry_msgs/TransformStamped`: `child` placed at `pose` in `parent`.
pub struct Transform<'a> {
    pub parent: &'a str,
    pub child: &'a str,
    pub pose: Pose,
}

/// `tf2_msgs/msg/TFMessage`.
pub fn tf_message(stamp: Stamp, transforms: &[Transform]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    w.len(transforms.len());
    for t in transforms {
        header(&mut w, stamp, t.parent);
        w.string(t.child);
        pose(&mut w, &t.pose);
    }
    w.finish()
}

/// What `nav_msgs/MapMetaData` says of a grid.
pub struct GridInfo {
    pub resolution_m: f32,
    pub width_cells: u32,
    pub height_cells: u32,
    /// Cell (0, 0)'s corner (x east, y north); rows run north from it, as in Kestrel's grids.
    pub origin_m: [f64; 2],
}

/// `nav_msgs/msg/OccupancyGrid`: row-major, row 0 at the origin, -1 unknown, 0..=100.
pub fn occupancy_grid(stamp: Stamp, frame_id: &str, info: &GridInfo, data: &[i8]) -> Vec<u8> {
    let mut w = CdrWriter::new();
    header(&mut w, stamp, frame_id);
    w.i32(stamp.sec);
    w.u32(stamp.nanosec);
    w.f32(info.resolution_m);
    w.u32(info.width_cells);
    w.u32(info.height_cells);
    pose(
        &mut w,
        &Pose::from_yaw([info.origin_m[0], info.origin_m[1], 0.0], 0.0),
    );
    w.i8_seq(data);
    w.finish()
}

/// A decoded `geometry_msgs/msg/PoseStamped`.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseStampedMsg {
    pub stamp: Stamp,
    pub frame_id: String,
    pub pose: Pose,
}

/// Reads a `PoseStamped`; trailing bytes are refused too (another type sent on the topic).
pub fn decode_pose_stamped(bytes: &[u8]) -> Result<PoseStampedMsg, CdrError> {
    let mut r = CdrReader::new(bytes)?;
    let sec = r.i32("header.stamp.sec")?;
    let nanosec = r.u32("header.stamp.nanosec")?;
    let frame_id = r.string("header.frame_id", MAX_FRAME_ID_LEN)?;
    let mut v = [0.0; 7];
    for (i, slot) in v.iter_mut().enumerate() {
        *slot = r.f64(if i < 3 {
            "pose.position"
        } else {
            "pose.orientation"
        })?;
    }
    // Fast-CDR pads a message to a multiple of 4 bytes; anything longer is not this type.
    if bytes.len() > r.position() + 3 {
        return Err(CdrError::TooLong {
            at: r.position(),
            what: "PoseStamped",
            len: bytes.len(),
            max: r.position() + 3,
        });
    }
    Ok(PoseStampedMsg {
        stamp: Stamp { sec, nanosec },
        frame_id,
        pose: Pose {
            position_m: [v[0], v[1], v[2]],
            orientation_xyzw: [v[3], v[4], v[5], v[6]],
        },
    })
}

#[cfg(test)]
mod tests;
