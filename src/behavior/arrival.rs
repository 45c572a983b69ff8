//! When an item that ends on a point has arrived: within the goal threshold and settled there.
//!
//! In: each tick, whether the vehicle is within the goal's threshold, and its state. Out:
//! whether it has arrived. A vehicle passing through the goal at speed has not: an autopilot
//! that answers late carries it on by its velocity times its lag (0.8 m/s through a go_to's goal
//! on the fake ArduPilot with 50-100 ms of latency, then 0.1-0.15 m off at touchdown under its
//! own LAND mode).

use super::server::seconds_since;
use super::BehaviorContext;
use std::time::Duration;

/// Fastest the vehicle may move (m/s) when it arrives.
pub const SETTLED_SPEED_MPS: f64 = 0.25;
/// Or this long within the threshold (s): an autopilot whose own hold wanders faster than
/// [`SETTLED_SPEED_MPS`] (PX4 SIH on a loaded machine) still arrives; a vehicle passing
/// through at speed crosses the threshold's 0.2 m in a fraction of it.
pub const SETTLED_WITHIN_S: f64 = 1.0;

#[derive(Debug, Clone, Default)]
pub struct Arrival {
    within_since: Option<Duration>,
}

impl Arrival {
    /// One tick: `within` says whether the vehicle is within the goal threshold.
    pub fn update(&mut self, within: bool, ctx: &BehaviorContext) -> bool {
        if !within {
            self.within_since = None;
            return false;
        }
        let since = *self.within_since.get_or_insert(ctx.now);
        ctx.state.velocity_enu_mps.norm() <= SETTLED_SPEED_MPS
            || seconds_since(ctx.now, since) >= SETTLED_WITHIN_S
    }

    /// Forget (the goal moved, or the item resumed).
    pub fn reset(&mut self) {
        self.within_since = None;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::testing::Scene;
    use crate::types::Vec3;

    fn at(arrival: &mut Arrival, scene: &Scene, within: bool, t_s: f64) -> bool {
        arrival.update(within, &scene.ctx_at(Duration::from_secs_f64(t_s)))
    }

    #[test]
    fn a_vehicle_passing_through_the_goal_at_speed_has_not_arrived() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::zeros(), Vec3::new(0.8, 0.0, 0.0));
        let mut a = Arrival::default();
        // 0.2 m of threshold crossed at 0.8 m/s: a quarter of a second within.
        assert!(!at(&mut a, &scene, true, 10.0));
        assert!(!at(&mut a, &scene, true, 10.25));
        assert!(!at(&mut a, &scene, false, 10.3));
        // Slowed down within the threshold: arrived.
        scene.set_position(Vec3::zeros(), Vec3::new(0.2, 0.0, 0.0));
        assert!(at(&mut a, &scene, true, 11.0));
    }

    #[test]
    fn a_vehicle_wandering_within_the_goal_arrives_after_a_second() {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::zeros(), Vec3::new(0.0, 0.4, 0.0));
        let mut a = Arrival::default();
        assert!(!at(&mut a, &scene, true, 5.0));
        assert!(!at(&mut a, &scene, true, 5.9));
        assert!(at(&mut a, &scene, true, 6.0));
    }
}
