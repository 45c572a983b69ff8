//! Simulated-time driver: ticks every drone core and the shared world in lock step.
//!
//! In: a world, drone cores, a seed, the control rate. Out: per tick, the behavior events of
//! each drone; the flight log. It never sleeps: pacing to wall-clock time (`--speedup`) is the
//! caller's business, so tests and `--speedup max` run as fast as the CPU allows.

use super::{Environment, SimWorld};
use crate::behavior::{BehaviorEvent, Registry, RunState};
use crate::core::{CoreConfig, DroneCore};
use crate::flightlog::FlightLog;
use crate::planning::worker::{Delivery, PlanWorker};
use crate::platform::Platform;
use crate::sim::world::World;
use std::time::Duration;

#[derive(Debug, Clone)]
pub struct SimConfig {
    pub drones: usize,
    pub seed: u64,
    /// Control rate (Hz); the physics runs at `physics_substeps` times this.
    pub rate_hz: f64,
    pub physics_substeps: u32,
    pub environment: Environment,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            drones: 1,
            seed: 0,
            rate_hz: 100.0,
            physics_substeps: 2,
            environment: Environment::default(),
        }
    }
}

pub struct SimRunner {
    pub world: SimWorld,
    pub cores: Vec<DroneCore>,
    pub log: Option<FlightLog>,
    now: Duration,
    tick: Duration,
    substeps: u32,
    reported_crash: Vec<bool>,
    planner: PlanWorker,
}

/// Events of one drone in one tick.
pub type DroneEvents = Vec<BehaviorEvent>;

impl SimRunner {
    pub fn new(
        world: World,
        config: &SimConfig,
        core_config: impl Fn(usize) -> CoreConfig,
        registry: &Registry,
    ) -> Self {
        let mut sim = SimWorld::new(world, config.drones, config.seed, config.environment);
        let origin = sim.world.geodetic_origin;
        let cores = sim
            .vehicles
            .iter_mut()
            .enumerate()
            .map(|(i, v)| {
                let mut cc = core_config(i);
                if let Some(o) = origin {
                    cc.geo_origin = crate::estimator::geodetic::GeodeticOrigin(o);
                }
                DroneCore::new(cc, v.capabilities(), registry.clone())
            })
            .collect();
        Self {
            reported_crash: vec![false; config.drones],
            world: sim,
            cores,
            log: None,
            now: Duration::ZERO,
            tick: Duration::from_secs_f64(1.0 / config.rate_hz.max(1.0)),
            substeps: config.physics_substeps.max(1),
            planner: PlanWorker::new(Delivery::Lockstep),
        }
    }

    pub fn now(&self) -> Duration {
        self.now
    }

    pub fn tick_period(&self) -> Duration {
        self.tick
    }

    /// One control tick for every drone, then the physics up to the next tick.
    pub fn step(&mut self) -> Vec<DroneEvents> {
        let now = self.now;
        let mut all_events = Vec::with_capacity(self.cores.len());
        for answer in self.planner.collect() {
            if let Some(core) = self.cores.get(answer.drone) {
                core.deliver_plan(answer);
            }
        }
        for (i, core) in self.cores.iter_mut().enumerate() {
            let Some(vehicle) = self.world.vehicles.get_mut(i) else {
                continue;
            };
            let feedback = vehicle.poll(now);
            let out = core.tick(now, &feedback);
            vehicle.command(now, out.setpoint, &out.requests);
            for call in out.service_calls {
                call.submit(i, &mut self.planner);
            }
            if let Some(log) = self.log.as_mut() {
                if log.pose_due(now, core.drone_id()) {
                    let active = core.server().active();
                    let motion = active
                        .iter()
                        .find(|a| a.state == RunState::Running || a.state == RunState::Paused)
                        .map(|a| a.behavior.as_str());
                    log.pose(now, &core.vehicle_state(), motion);
                }
                for e in &out.events {
                    log.behavior(now, core.drone_id(), e);
                }
                if let (Some(reason), false) = (vehicle.crashed(), self.reported_crash[i]) {
                    log.event(now, core.drone_id(), "collision", reason);
                }
            }
            if vehicle.crashed().is_some() {
                self.reported_crash[i] = true;
            }
            all_events.push(out.events);
        }
        let dt = self.tick.as_secs_f64() / f64::from(self.substeps);
        for k in 0..self.substeps {
            let t = now + self.tick.mul_f64(f64::from(k) / f64::from(self.substeps));
            self.world.step(t, dt);
        }
        self.now += self.tick;
        all_events
    }
}
