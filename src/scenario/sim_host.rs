//! A host flying the built-in simulator: N drones (`drone_0` ...) in one world.
//!
//! In: a world, the number of drones, a seed and the config. Out: a [`Host`] whose vehicles
//! are the simulator's ([`SimFleet`]), stepped in simulated time (deterministic for a seed),
//! with the world handed to it as the truth of its exploration reports; [`SimulatedHost`] reads
//! the simulator's world back from such a host.

use crate::behavior::payload;
use crate::config::Config;
use crate::core::{CoreConfig, DroneCore};
use crate::estimator::geodetic::GeodeticOrigin;
use crate::host::{Host, HostBuilder};
use crate::mapping::config::MapConfig;
use crate::platform::Platform;
use crate::sim::fleet::SimFleet;
use crate::sim::world::World;
use crate::sim::{Environment, SimWorld};
use crate::types::Vec3;

/// Physics steps per control tick, as the simulator's own runner does.
const PHYSICS_SUBSTEPS: u32 = 2;

pub fn simulated_host(world: World, drones: usize, seed: u64, config: &Config) -> Host {
    simulated_host_in(sim_world(world, drones, seed, config), config)
}

/// The simulator's world with `drones` vehicles and the config's wind, turbulence, vehicle
/// radius and imperfections (drift, dropped readings).
pub fn sim_world(world: World, drones: usize, seed: u64, config: &Config) -> SimWorld {
    let environment = Environment {
        wind_mps: Vec3::from(config.sim.wind_enu_mps),
        turbulence_mps2: config.sim.turbulence_mps2,
    };
    let mut sim = SimWorld::new(world, drones, seed, environment);
    for v in &mut sim.vehicles {
        v.params.radius_m = config.sim.vehicle_radius_m;
    }
    sim.set_imperfections(config.sim.imperfections());
    sim
}

/// A host flying the vehicles of an existing simulator world.
pub fn simulated_host_in(sim: SimWorld, config: &Config) -> Host {
    simulated_host_with(sim, config, |_| {})
}

/// The same host with each drone's core settings adjusted by `tweak` after the config's
/// (tests: a known map, another estimator).
pub fn simulated_host_with(
    sim: SimWorld,
    config: &Config,
    tweak: impl Fn(&mut CoreConfig),
) -> Host {
    let truth = sim.world.clone();
    let (cores, fleet) = simulated_parts_with(sim, config, tweak);
    HostBuilder::new(cores, Box::new(fleet), config)
        .world(truth)
        .build()
}

/// The `[map]` section framed on the world's bounds when it gives no extent of its own.
fn sim_map_config(sim: &SimWorld, config: &Config) -> Option<MapConfig> {
    match config.map.config(Some(sim.world.bounds_m.corners())) {
        Ok(m) => m,
        Err(e) => {
            tracing::error!("mapping is off: {e}");
            None
        }
    }
}

/// The cores and the fleet of a simulated host, for callers that wrap the fleet (benchmark
/// probes) before they build the host.
pub fn simulated_parts(sim: SimWorld, config: &Config) -> (Vec<DroneCore>, SimFleet) {
    simulated_parts_with(sim, config, |_| {})
}

fn simulated_parts_with(
    sim: SimWorld,
    config: &Config,
    tweak: impl Fn(&mut CoreConfig),
) -> (Vec<DroneCore>, SimFleet) {
    let origin = sim.world.geodetic_origin.or(config.drone.geodetic_origin);
    let registry = payload::registry();
    let map = sim_map_config(&sim, config);
    // The drift its estimator is told of is the one the simulator gives it.
    let drift_mps = sim.imperfections().position_drift_mps;
    let cores = sim
        .vehicles
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let mut c = CoreConfig::new(&format!("drone_{i}"));
            c.controller = config.controller;
            c.behaviors = config.behaviors;
            c.exploration = config.exploration;
            c.estimator = config.estimator.plugin.unwrap_or_default();
            c.map_correction = config.estimator.map_correction.for_vehicle(drift_mps);
            c.map.clone_from(&map);
            c.safety = config.safety_config();
            if let Some(o) = origin {
                c.geo_origin = GeodeticOrigin(o);
            }
            tweak(&mut c);
            DroneCore::new(c, v.capabilities(), registry.clone())
        })
        .collect();
    (cores, SimFleet::new(sim, PHYSICS_SUBSTEPS))
}

/// The simulator's world of a host built over a [`SimFleet`] (ground truth for tests, benches
/// and the demo); `None` for any other fleet.
pub trait SimulatedHost {
    fn sim_world(&self) -> Option<&SimWorld>;
    /// To change the weather or a vehicle (a pilot's takeover, the autopilot's own landing)
    /// mid-run.
    fn sim_world_mut(&mut self) -> Option<&mut SimWorld>;
}

impl SimulatedHost for Host {
    fn sim_world(&self) -> Option<&SimWorld> {
        self.fleet_as::<SimFleet>().map(|f| &f.world)
    }
    fn sim_world_mut(&mut self) -> Option<&mut SimWorld> {
        self.fleet_as_mut::<SimFleet>().map(|f| &mut f.world)
    }
}
