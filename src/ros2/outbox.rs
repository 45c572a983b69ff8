//! What Kestrel's state looks like as ROS 2 messages: per drone its pose, odometry and planned
//! path, the frames of every drone, and the merged map.
//!
//! In: the host's latest snapshot (drones' positions, yaw, velocities, active behaviors) or a
//! map view, and the stamp to put on them. Out: topic names and CDR bytes. Plain code: the
//! Zenoh session that sends them is `node`.

use super::msgs::{self, GridInfo, Pose, Stamp, Transform};
use crate::host::map_view::MapView;
use crate::host::DroneStatus;

/// Kestrel's ENU world frame on `/tf`.
pub const WORLD_FRAME: &str = super::goal::WORLD_FRAME;

/// A drone's body frame (FLU) on `/tf`.
pub fn base_link(drone: &str) -> String {
    format!("{drone}/base_link")
}

/// A drone's topics, under the namespace (`""` or `/ns`).
pub fn drone_topic(namespace: &str, drone: &str, leaf: &str) -> String {
    format!("{namespace}/{drone}/{leaf}")
}

/// The pose of a drone that has one (position and yaw known).
fn pose_of(d: &DroneStatus) -> Option<Pose> {
    Some(Pose::from_yaw(d.position_enu_m?, d.yaw_rad?))
}

/// The world-frame velocity turned into the body's FLU frame by the yaw (roll and pitch are not
/// in the snapshot: small in the flight Kestrel commands).
pub fn velocity_flu_mps(velocity_enu_mps: [f64; 3], yaw_rad: f64) -> [f64; 3] {
    let (s, c) = yaw_rad.sin_cos();
    let [e, n, u] = velocity_enu_mps;
    [c * e + s * n, -s * e + c * n, u]
}

/// `pose` (PoseStamped) and `odom` (Odometry) of a drone; `None` before it has a position.
pub fn pose_and_odometry(d: &DroneStatus, stamp: Stamp) -> Option<(Vec<u8>, Vec<u8>)> {
    let pose = pose_of(d)?;
    let yaw = d.yaw_rad?;
    let v = velocity_flu_mps(d.velocity_enu_mps.unwrap_or_default(), yaw);
    Some((
        msgs::pose_stamped(stamp, WORLD_FRAME, &pose),
        msgs::odometry(stamp, WORLD_FRAME, &base_link(&d.drone), &pose, v),
    ))
}

/// `/tf`: world → each drone's base_link, for the drones with a position.
pub fn transforms(drones: &[DroneStatus], stamp: Stamp) -> Option<Vec<u8>> {
    let children: Vec<(String, Pose)> = drones
        .iter()
        .filter_map(|d| Some((base_link(&d.drone), pose_of(d)?)))
        .collect();
    if children.is_empty() {
        return None;
    }
    let list: Vec<Transform> = children
        .iter()
        .map(|(child, pose)| Transform {
            parent: WORLD_FRAME,
            child,
            pose: *pose,
        })
        .collect();
    Some(msgs::tf_message(stamp, &list))
}

/// Most points of a path sent (a plan of a few hundred metres at the map's resolution).
pub const MAX_PATH_POINTS: usize = 10_000;

/// The path `navigate_to` planned (its feedback's `planned_path`); empty without one.
pub fn planned_path(d: &DroneStatus) -> Vec<[f64; 3]> {
    d.active_behaviors
        .iter()
        .filter_map(|b| b.feedback.get("planned_path")?.as_array())
        .flatten()
        .take(MAX_PATH_POINTS)
        .filter_map(|p| {
            let p = p.as_array()?;
            Some([
                p.first()?.as_f64()?,
                p.get(1)?.as_f64()?,
                p.get(2)?.as_f64()?,
            ])
        })
        .collect()
}

/// `path` (nav_msgs/Path) of the points.
pub fn path(points: &[[f64; 3]], stamp: Stamp) -> Vec<u8> {
    msgs::path(stamp, WORLD_FRAME, points)
}

/// `/map` (OccupancyGrid) of the merged map, cut to the rectangle of its known cells (the
/// simulator's default grid is 2040 × 2040 cells, 4 MB, mostly never seen); a map with no known
/// cell is one unknown cell at the grid's origin.
pub fn map(view: &MapView, stamp: Stamp) -> Vec<u8> {
    let spec = view.grid.spec();
    let (w, data) = (spec.width_cells as usize, view.grid.data());
    let mut known = data
        .iter()
        .enumerate()
        .filter(|(_, v)| **v != crate::mapping::grid::UNKNOWN)
        .map(|(i, _)| (i % w.max(1), i / w.max(1)));
    let (x0, y0, x1, y1) = match known.next() {
        Some((x, y)) => known.fold((x, y, x, y), |(a, b, c, d), (x, y)| {
            (a.min(x), b.min(y), c.max(x), d.max(y))
        }),
        None => (0, 0, 0, 0),
    };
    let cells: Vec<i8> = (y0..=y1)
        .flat_map(|y| {
            data.get(y * w + x0..=y * w + x1)
                .unwrap_or(&[])
                .iter()
                .copied()
        })
        .collect();
    let r = spec.resolution_m;
    let info = GridInfo {
        resolution_m: r as f32,
        width_cells: u32::try_from(x1 - x0 + 1).unwrap_or(0),
        height_cells: u32::try_from(y1 - y0 + 1).unwrap_or(0),
        origin_m: [
            spec.origin_enu_m.x + x0 as f64 * r,
            spec.origin_enu_m.y + y0 as f64 * r,
        ],
    };
    msgs::occupancy_grid(stamp, WORLD_FRAME, &info, &cells)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn velocity_is_turned_into_the_body_frame() {
        let v = velocity_flu_mps([0.0, 1.0, 0.5], std::f64::consts::FRAC_PI_2);
        assert!((v[0] - 1.0).abs() < 1e-12 && v[1].abs() < 1e-12 && v[2] == 0.5);
        let v = velocity_flu_mps([1.0, 0.0, 0.0], std::f64::consts::FRAC_PI_2);
        assert!(v[0].abs() < 1e-12 && (v[1] + 1.0).abs() < 1e-12);
    }

    #[test]
    fn the_map_is_cut_to_its_known_cells() {
        use crate::mapping::grid::{GridSpec, OccupancyGrid};
        let spec = GridSpec {
            resolution_m: 0.5,
            width_cells: 4,
            height_cells: 3,
            origin_enu_m: nalgebra::Vector2::new(-1.0, -1.0),
        };
        #[rustfmt::skip]
        let data = vec![
            -1, -1, -1, -1,
            -1,  0, 100, -1,
            -1, -1,  7, -1,
        ];
        let view = |data| MapView {
            drone: None,
            grid: OccupancyGrid::from_data(spec, data).unwrap(),
            layers: Vec::new(),
            revision: None,
            updated_at_s: None,
            occupied_threshold: None,
        };
        let info = GridInfo {
            resolution_m: 0.5,
            width_cells: 2,
            height_cells: 2,
            origin_m: [-0.5, -0.5],
        };
        assert_eq!(
            map(&view(data), Stamp::default()),
            msgs::occupancy_grid(Stamp::default(), "world", &info, &[0, 100, -1, 7])
        );
        let nothing = GridInfo {
            width_cells: 1,
            height_cells: 1,
            origin_m: [-1.0, -1.0],
            ..info
        };
        assert_eq!(
            map(&view(vec![-1; 12]), Stamp::default()),
            msgs::occupancy_grid(Stamp::default(), "world", &nothing, &[-1])
        );
    }

    #[test]
    fn topics_sit_under_the_namespace() {
        assert_eq!(drone_topic("", "drone_0", "pose"), "/drone_0/pose");
        assert_eq!(
            drone_topic("/fleet", "drone_0", "odom"),
            "/fleet/drone_0/odom"
        );
        assert_eq!(base_link("drone_0"), "drone_0/base_link");
    }
}
