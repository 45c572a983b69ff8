//! The fleet as every layer sees it: each drone's latest state (pose, velocity, active motion
//! behavior and its goal), read-only.
//!
//! In: filled by the host once per tick from its own cores, before they tick (so every drone
//! sees the same snapshot), and by `fleet_bus::remote` for drones of other Kestrel processes
//! (`local: false`); plain data with a stamp per drone. Out: read by behaviors (separation,
//! frontier allocation, the drone watcher) and the safety stage.

use super::{LinkHealth, Vec3};
use std::sync::Arc;
use std::time::Duration;

/// One drone's latest state.
#[derive(Debug, Clone, PartialEq)]
pub struct DroneView {
    pub id: Arc<str>,
    pub position_enu_m: Vec3,
    pub velocity_enu_mps: Vec3,
    pub yaw_rad: f64,
    /// Airborne and armed.
    pub flying: bool,
    pub link: LinkHealth,
    /// The motion behavior running or paused, if any.
    pub motion_behavior: Option<Arc<str>>,
    /// Where that behavior is taking the drone (`earth` ENU m), when it has one point.
    pub goal_enu_m: Option<Vec3>,
    /// When this state was taken (host time).
    pub stamp: Duration,
    /// Flown by this Kestrel (false: heard from another one over the fleet bus).
    pub local: bool,
    /// How far the drone may be from `position_enu_m` (m): for this Kestrel's drones, how far
    /// its drifting estimate may be off the map (`MapCorrection::uncertainty_m`, 0 for one that
    /// does not drift); for a remote one, how far it could have flown since it was heard (capped).
    pub uncertainty_m: f64,
    /// A remote drone whose Kestrel has not been heard for longer than `[fleet] peer_timeout_s`:
    /// it cannot take part in decisions that need both sides (the drone watcher), only be kept
    /// away from.
    pub silent: bool,
    /// A silent remote drone that was flying and is not accounted for yet: it could be anywhere,
    /// so this Kestrel's flying drones hold where they are (`fleet_bus::remote`).
    pub unaccounted: bool,
}

/// Every drone's latest state, in a stable order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FleetView {
    pub drones: Vec<DroneView>,
}

impl FleetView {
    pub fn get(&self, id: &str) -> Option<&DroneView> {
        self.drones.iter().find(|d| &*d.id == id)
    }

    /// Every drone but `me`.
    pub fn others<'a>(&'a self, me: &'a str) -> impl Iterator<Item = &'a DroneView> + 'a {
        self.drones.iter().filter(move |d| &*d.id != me)
    }

    /// The nearest other flying drone to `point` and its horizontal-and-vertical distance (m).
    pub fn nearest_flying<'a>(&'a self, me: &'a str, point: &Vec3) -> Option<(&'a DroneView, f64)> {
        self.others(me)
            .filter(|d| d.flying)
            .map(|d| (d, (d.position_enu_m - point).norm()))
            .min_by(|a, b| a.1.total_cmp(&b.1))
    }
}

#[cfg(test)]
impl DroneView {
    /// This Kestrel's drone `id`, at rest at `position_enu_m` and heard at time zero (for tests).
    pub fn at_rest(id: &str, position_enu_m: Vec3, flying: bool) -> Self {
        DroneView {
            id: id.into(),
            position_enu_m,
            velocity_enu_mps: Vec3::zeros(),
            yaw_rad: 0.0,
            flying,
            link: LinkHealth::Ok,
            motion_behavior: None,
            goal_enu_m: None,
            stamp: Duration::ZERO,
            local: true,
            uncertainty_m: 0.0,
            silent: false,
            unaccounted: false,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn drone(id: &str, x: f64, flying: bool) -> DroneView {
        DroneView::at_rest(id, Vec3::new(x, 0.0, 1.0), flying)
    }

    #[test]
    fn the_nearest_flying_other_drone_is_found() {
        let view = FleetView {
            drones: vec![
                drone("a", 0.0, true),
                drone("b", 5.0, true),
                drone("c", 1.0, false),
                drone("d", -3.0, true),
            ],
        };
        let (d, dist) = view
            .nearest_flying("a", &Vec3::new(0.0, 0.0, 1.0))
            .unwrap_or_else(|| {
                panic!("a flying drone is near");
            });
        assert_eq!((&*d.id, dist), ("d", 3.0));
        assert_eq!(view.others("a").count(), 3);
        assert!(view.get("c").is_some_and(|c| !c.flying));
    }
}
