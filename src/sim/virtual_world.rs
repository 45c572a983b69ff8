//! A real vehicle's range sensor cast against a world file's obstacles: `kestrel run
//! --virtual-world` flies exploration on autopilots (PX4 or ArduPilot SITL without Gazebo, a
//! real drone in an empty hall) as if the world's poles and walls stood there.
//!
//! In: the wrapped platform's feedback, whose poses must be in the fleet's shared frame (wrap
//! outside `platform::shifted`), the world's obstacles, the vehicle's sensor and radius. Out:
//! the same feedback with the scans that sensor makes from the reported pose, at its rate, in
//! place of the autopilot's own `DISTANCE_SENSOR`/`OBSTACLE_DISTANCE` scans (those are dropped,
//! with one warning: obstacles that are not in the world would otherwise be mapped too), and a
//! `virtual_collision` once per episode when the airborne vehicle comes within its radius of an
//! obstacle. Setpoints and requests pass through unchanged.
//!
//! A scan is what the MAVLink model makes of a `DISTANCE_SENSOR` reading: a [`RangeScan`] from
//! the pose the vehicle reported last (taken when the reading is polled, as the model takes the
//! pose at a reading's arrival), `None` beams for no return within range, and none at all
//! without a usable position or link.
//!
//! [`VirtualRanges`] is the math (obstacle index, sensor, radius; no I/O, no clock);
//! [`VirtualSensors`] the thin `Platform` adapter.

use super::sensors;
use super::spatial::ShapeIndex;
use crate::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use crate::types::{
    FlightStatus, LinkHealth, Measurement, RangeScan, SensorConfig, Setpoint, Vec3,
};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use std::sync::Arc;
use std::time::Duration;

/// A collision episode ends once the vehicle is this much farther out than its radius (m), so
/// a vehicle held at the edge does not collide again with every jitter.
const EPISODE_MARGIN_M: f64 = 0.1;

/// A landing vehicle this high or lower (shared frame, the world's ground at 0, m) has touched
/// down: what still moves its reported position there is the estimator settling on the ground
/// before the autopilot's land detector says so (PX4 SIH: 0.4 m in 3 s), not flight.
const TOUCHDOWN_HEIGHT_M: f64 = 0.05;

/// One vehicle's sensor and radius against the world's obstacles (shared frame).
#[derive(Debug, Clone)]
pub struct VirtualRanges {
    obstacles: Arc<ShapeIndex>,
    sensor: SensorConfig,
    radius_m: f64,
}

impl VirtualRanges {
    pub fn new(obstacles: Arc<ShapeIndex>, sensor: SensorConfig, radius_m: f64) -> Self {
        Self {
            obstacles,
            sensor,
            radius_m,
        }
    }

    /// Time between two scans; `None` for a vehicle without a sensor.
    pub fn period(&self) -> Option<Duration> {
        sensors::period_s(&self.sensor).map(Duration::from_secs_f64)
    }

    /// The scan the sensor makes from `position_enu_m` heading `yaw_rad` (ENU); `None` without
    /// a sensor.
    pub fn scan<R: Rng>(
        &self,
        position_enu_m: &Vec3,
        yaw_rad: f64,
        rng: &mut R,
    ) -> Option<RangeScan> {
        sensors::scan(&self.sensor, &self.obstacles, position_enu_m, yaw_rad, rng)
    }

    /// The obstacle closer than the vehicle's radius plus `margin_m` to `position_enu_m`, said
    /// for people (which, where); `None` when clear.
    pub fn touching(&self, position_enu_m: &Vec3, margin_m: f64) -> Option<String> {
        let p = position_enu_m;
        self.obstacles
            .touching(p, self.radius_m + margin_m)
            .map(|k| {
                format!(
                    "virtual collision with obstacle {k} of the virtual world at ({:.2}, {:.2}, \
                     {:.2}) m (vehicle radius {} m)",
                    p.x, p.y, p.z, self.radius_m
                )
            })
    }
}

/// `inner` flying in a virtual world: its scans cast there, its collisions reported.
pub struct VirtualSensors {
    inner: Box<dyn Platform>,
    ranges: VirtualRanges,
    /// Names the vehicle in the one warning about its own range readings.
    vehicle: String,
    rng: ChaCha8Rng,
    next_scan_at: Duration,
    /// Inside a collision episode (already reported).
    touching: bool,
    warned_real_scans: bool,
}

impl VirtualSensors {
    /// `seed`: the sensor noise's (one per vehicle, so runs repeat).
    pub fn new(inner: Box<dyn Platform>, ranges: VirtualRanges, vehicle: &str, seed: u64) -> Self {
        Self {
            inner,
            ranges,
            vehicle: vehicle.to_string(),
            rng: ChaCha8Rng::seed_from_u64(seed),
            next_scan_at: Duration::ZERO,
            touching: false,
            warned_real_scans: false,
        }
    }
}

/// The position and ENU yaw of the first measurement with a valid position.
fn reported_pose(feedback: &PlatformFeedback) -> Option<(Vec3, f64)> {
    feedback.measurements.iter().find_map(|m| match m {
        Measurement::AutopilotOdometry { valid, .. } if !valid.position => None,
        Measurement::GroundTruth { pose, .. }
        | Measurement::AutopilotOdometry { pose, .. }
        | Measurement::ExternalPose { pose, .. } => {
            Some((pose.position_m, pose.orientation.euler_angles().2))
        }
    })
}

impl Platform for VirtualSensors {
    fn capabilities(&self) -> Capabilities {
        self.inner.capabilities()
    }

    fn poll(&mut self, now: Duration) -> PlatformFeedback {
        let mut feedback = self.inner.poll(now);
        if !feedback.scans.is_empty() && !self.warned_real_scans {
            self.warned_real_scans = true;
            tracing::warn!(
                "{}: the autopilot sends range readings of its own; they are ignored, the \
                 virtual world's are used instead",
                self.vehicle
            );
        }
        feedback.scans.clear();
        let pose = match feedback.status.link {
            LinkHealth::Lost => None,
            _ => reported_pose(&feedback),
        };
        let Some((position, yaw_rad)) = pose else {
            return feedback;
        };
        if let Some(period) = self.ranges.period() {
            if now >= self.next_scan_at {
                self.next_scan_at = now + period;
                feedback
                    .scans
                    .extend(self.ranges.scan(&position, yaw_rad, &mut self.rng));
            }
        }
        let flight = feedback.status.flight;
        let touched_down = flight == FlightStatus::Landing && position.z <= TOUCHDOWN_HEIGHT_M;
        if !flight.is_airborne() || touched_down {
            self.touching = false;
        } else if self.touching {
            self.touching = self.ranges.touching(&position, EPISODE_MARGIN_M).is_some();
        } else if let Some(reason) = self.ranges.touching(&position, 0.0) {
            self.touching = true;
            feedback.virtual_collision = Some(reason);
        }
        feedback
    }

    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]) {
        self.inner.command(now, setpoint, requests);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::shifted::Shifted;
    use crate::sim::world::{Cylinder, World};
    use crate::types::{Pose, Validity};
    use std::f64::consts::FRAC_PI_2;
    use std::sync::Mutex;

    /// One pole of radius 0.5 m at (3, 0) in the shared frame.
    fn obstacles() -> Arc<ShapeIndex> {
        let mut w = World::empty();
        w.cylinders.push(Cylinder {
            xy_m: [3.0, 0.0],
            radius_m: 0.5,
            height_m: 5.0,
        });
        Arc::new(ShapeIndex::new(w.shapes()))
    }

    fn noiseless(range_max_m: f64) -> SensorConfig {
        SensorConfig::Multiranger {
            range_max_m,
            rate_hz: 20.0,
            noise_std_m: 0.0,
        }
    }

    /// An autopilot at `at` in its own frame, heading `yaw_rad`, airborne or not, sending a
    /// range reading of its own with every poll.
    struct Autopilot {
        at: Arc<Mutex<Vec3>>,
        yaw_rad: f64,
        flight: FlightStatus,
    }

    impl Platform for Autopilot {
        fn capabilities(&self) -> Capabilities {
            Capabilities::setpoints_only()
        }
        fn poll(&mut self, _now: Duration) -> PlatformFeedback {
            let at = *self.at.lock().unwrap();
            let mut feedback = PlatformFeedback {
                measurements: vec![Measurement::AutopilotOdometry {
                    pose: Pose {
                        position_m: at,
                        orientation: nalgebra::UnitQuaternion::from_euler_angles(
                            0.0,
                            0.0,
                            self.yaw_rad,
                        ),
                    },
                    velocity_enu_mps: Vec3::zeros(),
                    angular_velocity_flu_radps: Vec3::zeros(),
                    valid: Validity::ALL,
                    reset_counter: 0,
                }],
                scans: vec![crate::mapping::scan::from_multiranger(
                    at,
                    0.0,
                    [Some(0.5); 4],
                    0.05,
                    4.0,
                )],
                ..PlatformFeedback::default()
            };
            feedback.status.flight = self.flight;
            feedback
        }
        fn command(&mut self, _: Duration, _: Option<Setpoint>, _: &[PlatformRequest]) {}
    }

    /// A vehicle whose autopilot counts from `origin` of the shared frame, standing at `local`
    /// in its own, in the virtual world of [`obstacles`]; its position handle moves it.
    fn vehicle(
        origin: Vec3,
        local: Vec3,
        yaw_rad: f64,
        sensor: SensorConfig,
    ) -> (VirtualSensors, Arc<Mutex<Vec3>>) {
        let at = Arc::new(Mutex::new(local));
        let autopilot = Autopilot {
            at: at.clone(),
            yaw_rad,
            flight: FlightStatus::Flying,
        };
        let shifted = Shifted::new(Box::new(autopilot), origin);
        let ranges = VirtualRanges::new(obstacles(), sensor, 0.15);
        (
            VirtualSensors::new(Box::new(shifted), ranges, "drone_0", 1),
            at,
        )
    }

    #[test]
    fn beams_hit_at_the_right_distance_in_the_shared_frame() {
        // The autopilot counts from (-1, 2): at (1, -2) in its own frame it is at the shared
        // frame's origin, 2.5 m from the pole's surface, facing north.
        let origin = Vec3::new(-1.0, 2.0, 0.0);
        let (mut v, _) = vehicle(origin, Vec3::new(1.0, -2.0, 1.0), FRAC_PI_2, noiseless(4.0));
        let feedback = v.poll(Duration::ZERO);
        let [scan] = feedback.scans.as_slice() else {
            panic!(
                "one scan, the autopilot's own dropped: {:?}",
                feedback.scans
            );
        };
        assert_eq!(scan.origin_enu_m, Vec3::new(0.0, 0.0, 1.0));
        assert!((scan.yaw_rad - FRAC_PI_2).abs() < 1e-9);
        assert_eq!(scan.range_max_m, 4.0);
        let ranges: Vec<Option<f64>> = scan.beams.iter().map(|b| b.range_m).collect();
        // Front, left, back clear; the right beam (east) meets the pole.
        assert_eq!(ranges[..3], [None, None, None]);
        let right = ranges[3].unwrap();
        assert!((right - 2.5).abs() < 1e-9, "{right}");
        assert!(feedback.virtual_collision.is_none());
    }

    #[test]
    fn beyond_the_range_a_beam_has_no_hit_and_scans_come_at_the_sensor_rate() {
        let (mut v, _) = vehicle(Vec3::zeros(), Vec3::new(0.0, 0.0, 1.0), 0.0, noiseless(2.0));
        let mut scans = Vec::new();
        for k in 0..100u64 {
            scans.extend(v.poll(Duration::from_millis(10 * k)).scans);
        }
        assert_eq!(scans.len(), 20, "20 Hz over one second");
        assert!(
            scans
                .iter()
                .flat_map(|s| &s.beams)
                .all(|b| b.range_m.is_none()),
            "the pole's surface is 2.5 m away, the range 2 m"
        );
        let (mut blind, _) = vehicle(
            Vec3::zeros(),
            Vec3::new(0.0, 0.0, 1.0),
            0.0,
            SensorConfig::None,
        );
        assert!(blind.poll(Duration::ZERO).scans.is_empty());
    }

    #[test]
    fn coming_within_the_radius_is_one_virtual_collision_per_episode() {
        // Its own frame starts at (2, 0): at (0.3, 0) it is 0.2 m from the pole's surface.
        let (mut v, at) = vehicle(
            Vec3::new(2.0, 0.0, 0.0),
            Vec3::new(0.3, 0.0, 1.0),
            0.0,
            noiseless(4.0),
        );
        assert!(v.poll(Duration::ZERO).virtual_collision.is_none());
        *at.lock().unwrap() = Vec3::new(0.4, 0.0, 1.0);
        let reason = v.poll(Duration::from_millis(10)).virtual_collision.unwrap();
        assert!(reason.contains("obstacle 0"), "{reason}");
        assert!(reason.contains("(2.40, 0.00, 1.00)"), "{reason}");
        // Still inside, or just out (within the margin): the same episode.
        assert!(v
            .poll(Duration::from_millis(20))
            .virtual_collision
            .is_none());
        *at.lock().unwrap() = Vec3::new(0.33, 0.0, 1.0);
        assert!(v
            .poll(Duration::from_millis(30))
            .virtual_collision
            .is_none());
        *at.lock().unwrap() = Vec3::new(0.4, 0.0, 1.0);
        assert!(v
            .poll(Duration::from_millis(40))
            .virtual_collision
            .is_none());
        // Well out, then in again: a new one.
        *at.lock().unwrap() = Vec3::new(0.0, 0.0, 1.0);
        assert!(v
            .poll(Duration::from_millis(50))
            .virtual_collision
            .is_none());
        *at.lock().unwrap() = Vec3::new(0.4, 0.0, 1.0);
        assert!(v
            .poll(Duration::from_millis(60))
            .virtual_collision
            .is_some());
    }

    #[test]
    fn on_the_ground_nothing_collides() {
        let at = Arc::new(Mutex::new(Vec3::new(2.4, 0.0, 0.0)));
        let landed = Autopilot {
            at,
            yaw_rad: 0.0,
            flight: FlightStatus::Landed,
        };
        let ranges = VirtualRanges::new(obstacles(), noiseless(4.0), 0.15);
        let mut v = VirtualSensors::new(Box::new(landed), ranges, "drone_0", 1);
        let feedback = v.poll(Duration::ZERO);
        assert!(feedback.virtual_collision.is_none());
        assert_eq!(feedback.scans.len(), 1, "the sensor works on the ground");
    }

    #[test]
    fn a_landing_vehicle_settling_on_the_ground_collides_with_nothing() {
        // Landing: 0.2 m from the pole's surface, inside the 0.3 m radius. At 0.5 m up that is
        // a collision; on the ground (the estimate below 0.05 m) it is the estimator settling.
        let at = Arc::new(Mutex::new(Vec3::new(2.3, 0.0, -0.1)));
        let landing = Autopilot {
            at: at.clone(),
            yaw_rad: 0.0,
            flight: FlightStatus::Landing,
        };
        let ranges = VirtualRanges::new(obstacles(), noiseless(4.0), 0.3);
        let mut v = VirtualSensors::new(Box::new(landing), ranges, "drone_0", 1);
        assert!(v.poll(Duration::ZERO).virtual_collision.is_none());
        *at.lock().unwrap() = Vec3::new(2.3, 0.0, 0.5);
        assert!(v
            .poll(Duration::from_millis(10))
            .virtual_collision
            .is_some());
    }
}
