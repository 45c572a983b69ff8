//! Simulator test harness on the production host: builds the same [`Host`] `kestrel sim`
//! runs (simulated fleet, planner worker in lock step, flight log in memory), sends behavior
//! commands, and steps simulated time until a condition holds (never sleeping).

#![allow(dead_code, clippy::unwrap_used, clippy::expect_used)]

use kestrel::behavior::{BehaviorEvent, BehaviorId, BehaviorResult};
use kestrel::config::Config;
use kestrel::core::{BehaviorCommand, CoreConfig};
use kestrel::flightlog::{self, FlightLog};
use kestrel::host::status::{EventBody, HostEvent};
use kestrel::host::{Host, HostError};
use kestrel::scenario::sim_host::simulated_host_with;
use kestrel::scenario::SimulatedHost;
use kestrel::sim::world::World;
use kestrel::sim::{Environment, SimWorld};
use kestrel::types::{FlightStatus, Vec3};
use serde_json::Value;
use std::io::Write;
use std::sync::{Arc, Mutex};

/// A writer the flight log owns while the test keeps a handle to read it back.
#[derive(Clone, Default)]
pub struct SharedBuffer(Arc<Mutex<Vec<u8>>>);

impl Write for SharedBuffer {
    fn write(&mut self, buf: &[u8]) -> std::io::Result<usize> {
        self.0.lock().unwrap().extend_from_slice(buf);
        Ok(buf.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

/// What a simulated run is made of besides the world.
#[derive(Debug, Clone)]
pub struct SimConfig {
    pub drones: usize,
    pub seed: u64,
    /// Control rate (Hz).
    pub rate_hz: f64,
    pub environment: Environment,
    /// The config the host is built from (its `[drone] control_rate_hz` is `rate_hz`).
    pub settings: Config,
    /// Pose records per second and drone in the flight log.
    pub pose_log_hz: f64,
}

impl Default for SimConfig {
    fn default() -> Self {
        Self {
            drones: 1,
            seed: 0,
            rate_hz: 100.0,
            environment: Environment::default(),
            settings: Config::default(),
            pose_log_hz: 10.0,
        }
    }
}

/// One vehicle state sample, recorded every control tick.
#[derive(Debug, Clone, Copy)]
pub struct Sample {
    pub t_s: f64,
    pub position_m: Vec3,
    pub velocity_mps: Vec3,
    pub yaw_rad: f64,
    pub armed: bool,
    pub flight: FlightStatus,
}

pub struct Harness {
    pub host: Host,
    log: SharedBuffer,
    drone_ids: Vec<String>,
    /// Every behavior event so far, per drone, with its time (s).
    pub events: Vec<Vec<(f64, BehaviorEvent)>>,
    /// Per-drone state at every tick.
    pub samples: Vec<Vec<Sample>>,
    /// Every other host event (alerts, mission status, safety), in order.
    pub host_events: Vec<HostEvent>,
}

impl Harness {
    pub fn new(world: World, drones: usize) -> Self {
        Self::with_config(
            world,
            SimConfig {
                drones,
                ..SimConfig::default()
            },
        )
    }

    pub fn with_config(world: World, config: SimConfig) -> Self {
        Self::with_core_config(world, config, |_| {})
    }

    /// The production simulated host, with each core's settings adjusted by `tweak` (a known
    /// map, another estimator).
    pub fn with_core_config(
        world: World,
        config: SimConfig,
        tweak: impl Fn(&mut CoreConfig),
    ) -> Self {
        let mut settings = config.settings.clone();
        settings.drone.control_rate_hz = config.rate_hz;
        let mut sim = SimWorld::new(world, config.drones, config.seed, config.environment);
        sim.set_imperfections(settings.sim.imperfections());
        let mut host = simulated_host_with(sim, &settings, tweak);
        let log = SharedBuffer::default();
        host.set_log(FlightLog::new(Box::new(log.clone()), config.pose_log_hz));
        let mut h = Self {
            drone_ids: host.drone_ids(),
            host,
            log,
            events: vec![Vec::new(); config.drones],
            samples: vec![Vec::new(); config.drones],
            host_events: Vec::new(),
        };
        // A host ticks its cores continuously; the first tick gives them a state estimate.
        h.step();
        h
    }

    pub fn one_drone() -> Self {
        Self::new(World::empty(), 1)
    }

    /// The simulator's world: ground truth.
    pub fn world(&self) -> &SimWorld {
        self.host.sim_world().expect("a simulated host")
    }

    pub fn world_mut(&mut self) -> &mut SimWorld {
        self.host.sim_world_mut().expect("a simulated host")
    }

    pub fn now_s(&self) -> f64 {
        self.host.now().as_secs_f64()
    }

    pub fn start(&mut self, drone: usize, behavior: &str, goal: Value) -> BehaviorId {
        self.try_command(
            drone,
            BehaviorCommand::Start {
                behavior: behavior.into(),
                goal,
            },
        )
        .unwrap_or_else(|e| panic!("{behavior} rejected: {e}"))
        .expect("start returns an id")
    }

    pub fn try_command(
        &mut self,
        drone: usize,
        cmd: BehaviorCommand,
    ) -> Result<Option<BehaviorId>, HostError> {
        self.host.behavior_command(drone, cmd)
    }

    pub fn command(&mut self, drone: usize, cmd: BehaviorCommand) {
        self.try_command(drone, cmd).unwrap();
    }

    /// One control tick for every drone.
    pub fn step(&mut self) {
        self.host.step();
        let t = self.now_s();
        for e in self.host.drain_events() {
            match e {
                HostEvent::Event {
                    drone,
                    event: EventBody::Behavior(b),
                    ..
                } => {
                    if let Some(i) = self.drone_ids.iter().position(|d| *d == drone) {
                        self.events[i].push((t, b));
                    }
                }
                other => self.host_events.push(other),
            }
        }
        let samples: Vec<Sample> = self
            .world()
            .vehicles
            .iter()
            .map(|v| Sample {
                t_s: t,
                position_m: v.state.position_m,
                velocity_mps: v.state.velocity_mps,
                yaw_rad: v.state.yaw_rad,
                armed: v.is_armed(),
                flight: v.flight_status(),
            })
            .collect();
        for (i, s) in samples.into_iter().enumerate() {
            self.samples[i].push(s);
        }
    }

    /// Steps until `done` holds; panics after `limit_s` more simulated seconds.
    pub fn run_until(&mut self, limit_s: f64, what: &str, mut done: impl FnMut(&Self) -> bool) {
        let end = self.now_s() + limit_s;
        while !done(self) {
            assert!(
                self.now_s() < end,
                "timed out after {limit_s} simulated s waiting for {what}; events: {:?}",
                self.events
            );
            self.step();
        }
    }

    /// Steps for `seconds` of simulated time.
    pub fn run_for(&mut self, seconds: f64) {
        let end = self.now_s() + seconds;
        while self.now_s() < end - 1e-9 {
            self.step();
        }
    }

    /// The result of behavior `id` on `drone`, once it finished.
    pub fn result(&self, drone: usize, id: BehaviorId) -> Option<BehaviorResult> {
        self.events[drone].iter().find_map(|(_, e)| match e {
            BehaviorEvent::Finished { id: i, result, .. } if *i == id => Some(result.clone()),
            _ => None,
        })
    }

    /// When behavior `id` finished (simulated s).
    pub fn finished_at(&self, drone: usize, id: BehaviorId) -> Option<f64> {
        self.events[drone].iter().find_map(|(t, e)| match e {
            BehaviorEvent::Finished { id: i, .. } if *i == id => Some(*t),
            _ => None,
        })
    }

    /// Runs until behavior `id` finishes and returns its result.
    pub fn wait_for(&mut self, drone: usize, id: BehaviorId, limit_s: f64) -> BehaviorResult {
        self.run_until(limit_s, &format!("behavior {id} to finish"), |h| {
            h.result(drone, id).is_some()
        });
        self.result(drone, id).unwrap()
    }

    /// Starts a behavior and waits for it to succeed.
    pub fn fly(&mut self, drone: usize, behavior: &str, goal: Value, limit_s: f64) -> BehaviorId {
        let id = self.start(drone, behavior, goal);
        let result = self.wait_for(drone, id, limit_s);
        assert_eq!(
            result,
            BehaviorResult::Succeeded,
            "{behavior} did not succeed"
        );
        id
    }

    pub fn position(&self, drone: usize) -> Vec3 {
        self.world().vehicles[drone].state.position_m
    }

    pub fn speed(&self, drone: usize) -> f64 {
        self.world().vehicles[drone].state.velocity_mps.norm()
    }

    /// Samples of `drone` between two times (s).
    pub fn samples_between(&self, drone: usize, from_s: f64, to_s: f64) -> Vec<Sample> {
        self.samples[drone]
            .iter()
            .filter(|s| s.t_s >= from_s && s.t_s <= to_s)
            .copied()
            .collect()
    }

    /// The flight log so far, parsed.
    pub fn log_records(&mut self) -> Vec<Value> {
        flightlog::read(&self.log_text()).unwrap()
    }

    /// The flight log so far, as written.
    pub fn log_text(&mut self) -> String {
        self.host.flush_log();
        String::from_utf8(self.log.0.lock().unwrap().clone()).unwrap()
    }

    /// `behavior:event[:result]` for every behavior record of `drone` in the flight log.
    pub fn log_sequence(&mut self, drone: usize) -> Vec<String> {
        let name = format!("drone_{drone}");
        self.log_records()
            .iter()
            .filter(|r| r["type"] == "behavior" && r["drone"] == name.as_str())
            .map(|r| {
                let mut s = format!(
                    "{}:{}",
                    r["behavior"].as_str().unwrap(),
                    r["event"].as_str().unwrap()
                );
                if let Some(result) = r["result"]["result"].as_str() {
                    s.push(':');
                    s.push_str(result);
                }
                s
            })
            .collect()
    }

    /// Asserts the flight log of `drone` holds exactly `expected` (see [`Self::log_sequence`]).
    pub fn assert_log(&mut self, drone: usize, expected: &[&str]) {
        let got = self.log_sequence(drone);
        assert_eq!(got, expected, "behavior sequence in the flight log");
    }

    /// Takes off drone `drone` to `height_m` and waits until it succeeds.
    pub fn take_off(&mut self, drone: usize, height_m: f64) {
        self.fly(
            drone,
            "takeoff",
            serde_json::json!({ "height": height_m, "speed": 1.0 }),
            30.0,
        );
    }
}

/// Largest distance of any sample from `point` (m).
pub fn max_distance(samples: &[Sample], point: &Vec3) -> f64 {
    samples
        .iter()
        .map(|s| (s.position_m - point).norm())
        .fold(0.0, f64::max)
}

/// Smallest distance of any sample from `point` (m), and when.
pub fn closest_approach(samples: &[Sample], point: &Vec3) -> (f64, f64) {
    samples
        .iter()
        .map(|s| ((s.position_m - point).norm(), s.t_s))
        .fold((f64::INFINITY, 0.0), |a, b| if b.0 < a.0 { b } else { a })
}

/// A world with one pole (cylinder) at `xy` and nothing else.
pub fn world_with_pole(x_m: f64, y_m: f64, radius_m: f64) -> World {
    let mut w = World::empty();
    w.cylinders.push(kestrel::sim::world::Cylinder {
        xy_m: [x_m, y_m],
        radius_m,
        height_m: 10.0,
    });
    w
}
