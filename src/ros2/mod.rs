//! Kestrel's drones as ROS 2 topics over rmw_zenoh, so that `ros2 topic list`, `ros2 topic
//! echo` and RViz on a ROS 2 machine (Jazzy, `RMW_IMPLEMENTATION=rmw_zenoh_cpp`) see them,
//! without Kestrel becoming a ROS package.
//!
//! In: the `[ros2]` section (`config::ros2`) and the host's handle. Out, per drone under the
//! namespace: `<drone>/pose` (PoseStamped), `<drone>/odom` (Odometry), `<drone>/path` (Path, the
//! planned path); `/tf` (world → `<drone>/base_link`) and `/map` (OccupancyGrid, transient
//! local). In from ROS: `<drone>/goal_pose` (PoseStamped) as a `navigate_to` mission.
//!
//! `cdr` (encoding), `msgs` (message types and their Jazzy hashes), `keys` (rmw_zenoh's key
//! expressions, liveliness tokens and attachment), `goal` (a goal's checks and mission) and
//! `outbox` (state to messages) are plain code; `node` (the Zenoh session, apart from the fleet
//! bus's) is built with the `fleet-bus` feature, which brings Zenoh.

pub mod cdr;
pub mod goal;
pub mod keys;
pub mod msgs;
#[cfg(feature = "fleet-bus")]
pub mod node;
pub mod outbox;
