//! The built-in simulator: several multirotors in one world, stepped in simulated time.
//!
//! In: a [`world::World`], per-drone setpoints and requests (through [`vehicle::SimVehicle`]'s
//! `Platform` impl), a seed. Out: vehicle states, range scans, collisions. Reproducible: the same
//! seed, world and commands give the same flight. `virtual_world` casts a real vehicle's range
//! sensor against a world's obstacles instead (`kestrel run --virtual-world`).

pub mod dynamics;
pub mod fleet;
pub mod sensors;
pub mod shape;
pub mod spatial;
pub mod vehicle;
pub mod virtual_world;
pub mod world;

use crate::types::SensorConfig;
use crate::types::Vec3;
use dynamics::MultirotorParams;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use rand_distr::{Distribution, Normal};
use spatial::ShapeIndex;
use std::time::Duration;
use vehicle::SimVehicle;
use world::{Shape, World};

/// Disturbances applied to every vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Environment {
    pub wind_mps: Vec3,
    /// Standard deviation of a random acceleration on each axis (m/s^2).
    pub turbulence_mps2: f64,
}

pub struct SimWorld {
    pub world: World,
    obstacles: ShapeIndex,
    pub vehicles: Vec<SimVehicle>,
    pub sensor: SensorConfig,
    pub environment: Environment,
    rng: ChaCha8Rng,
}

impl SimWorld {
    /// `n` vehicles at the world's start poses for `n` drones.
    pub fn new(world: World, n: usize, seed: u64, environment: Environment) -> Self {
        let params = MultirotorParams::default();
        let vehicles = world
            .starts(n)
            .into_iter()
            .map(|(xy, yaw)| SimVehicle::new(Vec3::new(xy.x, xy.y, 0.0), yaw, params))
            .collect();
        Self {
            obstacles: ShapeIndex::new(world.shapes()),
            sensor: world.sensor,
            world,
            vehicles,
            environment,
            rng: ChaCha8Rng::seed_from_u64(seed),
        }
    }

    pub fn shapes(&self) -> &[Shape] {
        self.obstacles.shapes()
    }

    /// The obstacles with their spatial index.
    pub fn obstacles(&self) -> &ShapeIndex {
        &self.obstacles
    }

    /// Advances every vehicle by `dt_s`, then checks collisions and produces due scans.
    pub fn step(&mut self, now: Duration, dt_s: f64) {
        let noise = Normal::new(0.0, self.environment.turbulence_mps2.max(0.0)).ok();
        for v in self.vehicles.iter_mut() {
            let mut sample = || noise.map_or(0.0, |n| n.sample(&mut self.rng));
            let disturbance = if v.is_armed() {
                Vec3::new(sample(), sample(), sample())
            } else {
                Vec3::zeros()
            };
            v.step(now, dt_s, &self.environment.wind_mps, &disturbance);
        }
        self.detect_collisions();
        self.produce_scans(now);
    }

    fn detect_collisions(&mut self) {
        for i in 0..self.vehicles.len() {
            let v = &self.vehicles[i];
            if v.crashed().is_some() || v.state.on_ground() {
                continue;
            }
            let p = v.state.position_m;
            if let Some(k) = self.obstacles.touching(&p, v.params.radius_m) {
                let reason = format!(
                    "collision with obstacle {k} at ({:.2}, {:.2}, {:.2})",
                    p.x, p.y, p.z
                );
                self.vehicles[i].crash(reason);
            }
        }
        for i in 0..self.vehicles.len() {
            for j in (i + 1)..self.vehicles.len() {
                let (a, b) = (&self.vehicles[i], &self.vehicles[j]);
                if a.state.on_ground() && b.state.on_ground() {
                    continue;
                }
                if (a.state.position_m - b.state.position_m).norm()
                    < a.params.radius_m + b.params.radius_m
                {
                    let reason = |other: usize| format!("collision with drone_{other}");
                    self.vehicles[i].crash(reason(j));
                    self.vehicles[j].crash(reason(i));
                }
            }
        }
    }

    fn produce_scans(&mut self, now: Duration) {
        let Some(period) = sensors::period_s(&self.sensor) else {
            return;
        };
        for v in self.vehicles.iter_mut() {
            if now >= v.next_scan_at {
                v.next_scan_at = now + Duration::from_secs_f64(period);
                if let Some(scan) = sensors::scan(
                    &self.sensor,
                    &self.obstacles,
                    &v.state.position_m,
                    v.state.yaw_rad,
                    &mut self.rng,
                ) {
                    v.pending_scans.push(scan);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::platform::Platform;
    use world::Cylinder;

    fn world_with(sensor: SensorConfig) -> World {
        let mut w = World::empty();
        w.sensor = sensor;
        w.cylinders.push(Cylinder {
            xy_m: [3.0, 0.0],
            radius_m: 0.5,
            height_m: 5.0,
        });
        w
    }

    /// Scans delivered to drone 0 over one simulated second at 100 Hz.
    fn scans_in_one_second(sensor: SensorConfig) -> Vec<crate::types::RangeScan> {
        let mut sim = SimWorld::new(world_with(sensor), 1, 1, Environment::default());
        let mut scans = Vec::new();
        for k in 0..100u32 {
            let now = Duration::from_millis(u64::from(k) * 10);
            sim.step(now, 0.01);
            scans.extend(sim.vehicles[0].poll(now).scans);
        }
        scans
    }

    #[test]
    fn sensors_scan_at_their_rate_and_see_the_pole() {
        let scans = scans_in_one_second(SensorConfig::multiranger());
        assert_eq!(scans.len(), 20);
        let front = scans[5].beams[0].range_m.unwrap();
        assert!(
            (front - 2.5).abs() < 0.05,
            "pole 2.5 m ahead, seen at {front}"
        );
        let scans = scans_in_one_second(SensorConfig::lidar());
        assert_eq!(scans.len(), 10);
        assert_eq!(scans[0].beams.len(), 360);
        let hits = scans[0]
            .beams
            .iter()
            .filter(|b| b.range_m.is_some())
            .count();
        // A 1 m wide pole 3 m away spans about 19 deg.
        assert!((15..=22).contains(&hits), "{hits} beams hit");
        assert!(scans_in_one_second(SensorConfig::None).is_empty());
    }
}
