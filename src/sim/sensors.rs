//! Simulated range sensors: which sensor a drone carries, and ray casting against obstacles.
//!
//! In: a [`SensorConfig`] (`types`; from the world file, the config or `--sensor`), the vehicle pose, the
//! indexed obstacles, a noise source. Out: a [`RangeScan`] at the sensor's rate (multi-ranger:
//! 4 beams front/left/back/right; lidar: N beams over 360 deg).

use super::spatial::ShapeIndex;
use crate::types::{Beam, RangeScan, SensorConfig};
use crate::types::{Vec2, Vec3};
use rand::Rng;
use rand_distr::{Distribution, Normal};
use std::f64::consts::{FRAC_PI_2, PI, TAU};

/// Shortest beams any sensor reports (m).
const RANGE_MIN_M: f64 = 0.04;
/// One scan from `position` with heading `yaw_rad`, or `None` when the drone carries no sensor.
pub fn scan<R: Rng>(
    config: &SensorConfig,
    obstacles: &ShapeIndex,
    position: &Vec3,
    yaw_rad: f64,
    rng: &mut R,
) -> Option<RangeScan> {
    let (range_max_m, noise, angles): (f64, f64, Vec<f64>) = match *config {
        SensorConfig::Multiranger {
            range_max_m,
            noise_std_m,
            ..
        } => (
            range_max_m,
            noise_std_m,
            vec![0.0, FRAC_PI_2, PI, -FRAC_PI_2],
        ),
        SensorConfig::Lidar360 {
            range_max_m,
            noise_std_m,
            beams,
            ..
        } => {
            let n = beams.max(1);
            (
                range_max_m,
                noise_std_m,
                (0..n)
                    .map(|i| -PI + TAU * f64::from(i) / f64::from(n))
                    .collect(),
            )
        }
        SensorConfig::None => return None,
    };
    let normal = Normal::new(0.0, noise.max(0.0)).ok();
    let candidates = obstacles.near(position.x, position.y, range_max_m);
    let beams = angles
        .into_iter()
        .map(|angle_rad| {
            let world_angle = yaw_rad + angle_rad;
            let dir = Vec2::new(world_angle.cos(), world_angle.sin());
            let hit = obstacles
                .ray_m(&candidates, position, &dir)
                .unwrap_or(f64::INFINITY);
            let noisy = hit + normal.map_or(0.0, |n| n.sample(rng));
            let range_m =
                (noisy.is_finite() && noisy <= range_max_m).then(|| noisy.max(RANGE_MIN_M));
            Beam { angle_rad, range_m }
        })
        .collect();
    Some(RangeScan {
        origin_enu_m: *position,
        yaw_rad,
        range_min_m: RANGE_MIN_M,
        range_max_m,
        beams,
    })
}

/// Drops each beam's reading with probability `fraction` (0 to 1, clamped): the beam stays in
/// the scan and returns nothing (`range_m: None`), as a time-of-flight ranger's invalid reading
/// does: the map cannot tell it from an open view (`mapping::grid`'s rule for beams without a
/// return).
pub fn drop_readings<R: Rng>(scan: &mut RangeScan, fraction: f64, rng: &mut R) {
    // NaN or 0 or less: nothing dropped.
    if fraction.is_nan() || fraction <= 0.0 {
        return;
    }
    let p = fraction.min(1.0);
    for beam in &mut scan.beams {
        if rng.gen_bool(p) {
            beam.range_m = None;
        }
    }
}

/// Period between scans (s).
pub fn period_s(config: &SensorConfig) -> Option<f64> {
    match *config {
        SensorConfig::Multiranger { rate_hz, .. } | SensorConfig::Lidar360 { rate_hz, .. }
            if rate_hz > 0.0 =>
        {
            Some(1.0 / rate_hz)
        }
        _ => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sim::shape::Shape;
    use crate::sim::world::World;
    use rand::SeedableRng;

    #[test]
    fn multiranger_sees_a_pole_ahead_only() {
        let shapes = ShapeIndex::new(vec![Shape::Cylinder {
            center: Vec2::new(3.0, 0.0),
            radius_m: 0.5,
            height_m: 5.0,
        }]);
        let config = SensorConfig::Multiranger {
            range_max_m: 4.0,
            rate_hz: 20.0,
            noise_std_m: 0.0,
        };
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let s = scan(&config, &shapes, &Vec3::new(0.0, 0.0, 1.0), 0.0, &mut rng).unwrap();
        assert_eq!(s.beams.len(), 4);
        assert!((s.beams[0].range_m.unwrap() - 2.5).abs() < 1e-9);
        assert!(s.beams[1..].iter().all(|b| b.range_m.is_none()));
        // Facing north, the pole is on the right (the fourth beam, -90 deg).
        let s = scan(
            &config,
            &shapes,
            &Vec3::new(0.0, 0.0, 1.0),
            FRAC_PI_2,
            &mut rng,
        )
        .unwrap();
        assert!((s.beams[3].range_m.unwrap() - 2.5).abs() < 1e-9);
    }

    #[test]
    fn dropped_readings_return_nothing_at_their_rate() {
        let shapes = ShapeIndex::new(vec![Shape::Cylinder {
            center: Vec2::new(0.0, 0.0),
            radius_m: 20.0,
            height_m: 5.0,
        }]);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(2);
        // Inside a wide cylinder every lidar beam hits its wall.
        let at = Vec3::new(0.0, 0.0, 1.0);
        let full = scan(&SensorConfig::lidar(), &shapes, &at, 0.0, &mut rng).unwrap();
        let mut hits = 0;
        let mut total = 0;
        for _ in 0..100 {
            let mut s = full.clone();
            drop_readings(&mut s, 0.05, &mut rng);
            assert_eq!(s.beams.len(), 360, "a dropped beam stays in the scan");
            hits += s.beams.iter().filter(|b| b.range_m.is_some()).count();
            total += s.beams.len();
        }
        let dropped = 1.0 - hits as f64 / total as f64;
        assert!((0.04..0.06).contains(&dropped), "{dropped:.4} dropped");
        let mut s = full.clone();
        drop_readings(&mut s, 0.0, &mut rng);
        assert_eq!(s, full, "no dropout: the scan unchanged");
        drop_readings(&mut s, 1.0, &mut rng);
        assert!(s.beams.iter().all(|b| b.range_m.is_none()));
    }

    #[test]
    fn lidar_has_360_beams_and_range_limit() {
        let shapes = ShapeIndex::new(vec![Shape::Cylinder {
            center: Vec2::new(20.0, 0.0),
            radius_m: 0.5,
            height_m: 5.0,
        }]);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        let s = scan(
            &SensorConfig::lidar(),
            &shapes,
            &Vec3::new(0.0, 0.0, 1.0),
            0.0,
            &mut rng,
        )
        .unwrap();
        assert_eq!(s.beams.len(), 360);
        assert!(
            s.beams.iter().all(|b| b.range_m.is_none()),
            "pole beyond 10 m"
        );
    }

    #[test]
    fn a_sensor_kind_alone_takes_its_defaults() {
        let w: World = serde_json::from_str(
            r#"{"bounds_m": {"x": [0, 1], "y": [0, 1]}, "sensor": {"kind": "lidar360", "beams": 90}}"#,
        )
        .unwrap();
        assert_eq!(
            w.sensor,
            SensorConfig::Lidar360 {
                range_max_m: 10.0,
                rate_hz: 10.0,
                noise_std_m: 0.01,
                beams: 90
            }
        );
        assert_eq!(SensorConfig::by_name("lidar"), Some(SensorConfig::lidar()));
        assert!(SensorConfig::Lidar360 {
            range_max_m: 10.0,
            rate_hz: 0.0,
            noise_std_m: 0.0,
            beams: 1
        }
        .validate()
        .is_err());
    }
}
