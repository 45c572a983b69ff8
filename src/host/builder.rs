//! The one way to build a host, whatever it flies: the simulator's fleet (`scenario::sim_host`),
//! real vehicles (`kestrel run`), real vehicles in a virtual world.
//!
//! In: the cores and the fleet they fly (or each core with its platform), the config, and the
//! world the vehicles fly in when there is one. Out: a [`Host`] with the config's mission
//! limits, executor and tick, the fleet's merged map on the `[map]` grid (framed on the world's
//! bounds unless `[map]` gives its extent, so the frontier allocator and the map routes work
//! the same everywhere), and the world as the truth its exploration reports are judged against.

use super::engine::{Host, HostConfig};
use crate::config::Config;
use crate::core::DroneCore;
use crate::exploration::offline::evaluate::TrueWorld;
use crate::mapping::merged::FleetMap;
use crate::platform::fleet::Fleet;
use crate::platform::Platform;
use std::time::Duration;

pub struct HostBuilder<'a> {
    cores: Vec<DroneCore>,
    fleet: Box<dyn Fleet>,
    config: &'a Config,
    world: Option<TrueWorld>,
}

impl<'a> HostBuilder<'a> {
    /// `cores`: one per vehicle of `fleet`, in the same order.
    pub fn new(cores: Vec<DroneCore>, fleet: Box<dyn Fleet>, config: &'a Config) -> Self {
        Self {
            cores,
            fleet,
            config,
            world: None,
        }
    }

    /// Each core with the platform it flies, in order.
    pub fn vehicles(vehicles: Vec<(DroneCore, Box<dyn Platform>)>, config: &'a Config) -> Self {
        let (cores, platforms): (Vec<DroneCore>, Vec<Box<dyn Platform>>) =
            vehicles.into_iter().unzip();
        Self::new(cores, Box::new(platforms), config)
    }

    /// The world the vehicles fly in (the simulator's, or a virtual world around real
    /// vehicles): the merged map is framed on its bounds unless `[map]` gives its extent (the
    /// cores' maps must be built from the same section and bounds), and exploration reports
    /// are judged against it.
    pub fn world(mut self, world: TrueWorld) -> Self {
        self.world = Some(world);
        self
    }

    pub fn build(self) -> Host {
        let config = self.config;
        let bounds = self.world.as_ref().map(|w| w.bounds_m.corners());
        let mut host = Host::new(self.cores, self.fleet, host_config(config));
        if let Some(world) = self.world {
            host.set_true_world(world);
        }
        // Without a world to frame it: the section's extent, centred on the `earth` origin
        // unless it says where.
        match config
            .map
            .config(bounds)
            .map(|m| m.map(|m| FleetMap::new(&m)))
        {
            Ok(Some(Ok(map))) => host.set_map(map),
            Ok(None) => {}
            Ok(Some(Err(e))) | Err(e) => tracing::error!("no merged map: {e}"),
        }
        host
    }
}

/// What the config says of hosting: mission limits, the executor's settings, the tick.
fn host_config(config: &Config) -> HostConfig {
    HostConfig {
        limits: config.mission_limits(),
        executor: config.executor_config(),
        tick: Duration::from_secs_f64(1.0 / config.drone.control_rate_hz),
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::Registry;
    use crate::core::CoreConfig;
    use crate::platform::{Capabilities, PlatformFeedback, PlatformRequest};
    use crate::types::{Setpoint, Vec3};

    /// A vehicle that stays on the ground and reports nothing: what hosting needs of one.
    struct Grounded;

    impl Platform for Grounded {
        fn capabilities(&self) -> Capabilities {
            Capabilities::setpoints_only()
        }
        fn poll(&mut self, _now: Duration) -> PlatformFeedback {
            PlatformFeedback::default()
        }
        fn command(&mut self, _: Duration, _: Option<Setpoint>, _: &[PlatformRequest]) {}
    }

    #[test]
    fn any_platform_can_be_hosted() {
        let vehicle = Grounded;
        let core = DroneCore::new(
            CoreConfig::new("drone_0"),
            vehicle.capabilities(),
            Registry::with_motion_behaviors(),
        );
        let mut host =
            HostBuilder::vehicles(vec![(core, Box::new(vehicle))], &Config::default()).build();
        host.step_at(Duration::from_millis(10));
        assert_eq!(host.drone_ids(), ["drone_0"]);
        assert!(!host.is_simulated());
    }

    /// `kestrel run`'s host keeps the merged map the frontier allocator answers on: a scan
    /// the vehicle's core maps reaches it, on the same grid.
    #[test]
    fn a_vehicle_host_merges_its_drone_map() {
        let mut config = Config::default();
        config.map.size_m = Some([12.0, 12.0]);
        let mut core_config = CoreConfig::new("drone_0");
        core_config.map = config.map.config(None).unwrap();
        let vehicle = Grounded;
        let core = DroneCore::new(
            core_config,
            vehicle.capabilities(),
            Registry::with_motion_behaviors(),
        );
        let mut host = HostBuilder::vehicles(vec![(core, Box::new(vehicle))], &config).build();
        let spec = *host.map().unwrap().merged().spec();
        assert_eq!(spec.origin_enu_m, nalgebra::Vector2::new(-6.0, -6.0));
        assert_eq!(spec.width_cells, 120);
        let scan = crate::mapping::scan::from_multiranger(
            Vec3::new(0.0, 0.0, 1.0),
            0.0,
            [Some(2.0), None, None, None],
            0.05,
            4.0,
        );
        host.queue_scans(None, vec![scan]).unwrap();
        host.step_at(Duration::from_millis(10));
        let known =
            |g: &crate::mapping::grid::OccupancyGrid| g.data().iter().filter(|&&v| v >= 0).count();
        let merged = known(host.map().unwrap().merged());
        assert!(merged > 100, "{merged} known cells");
        let own = host.cores()[0].map().unwrap().grid();
        assert_eq!(own.spec(), &spec);
        assert_eq!(known(own), merged);
    }

    /// With a world (a virtual one around real vehicles), the merged map is framed on it as the
    /// cores' maps are when built from the same section and bounds (and `[map]`'s own extent
    /// still wins over the world's).
    #[test]
    fn a_world_frames_the_merged_map_as_the_cores_maps_are() {
        let world = TrueWorld::empty();
        let bounds = world.bounds_m.corners();
        let hosted = |config: &Config, world: Option<TrueWorld>| {
            let vehicle = Grounded;
            let core = DroneCore::new(
                CoreConfig::new("drone_0"),
                vehicle.capabilities(),
                Registry::with_motion_behaviors(),
            );
            let builder = HostBuilder::vehicles(vec![(core, Box::new(vehicle))], config);
            let host = match world {
                Some(w) => builder.world(w),
                None => builder,
            }
            .build();
            *host.map().unwrap().merged().spec()
        };
        let cores =
            |config: &Config, bounds| *config.map.config(bounds).unwrap().unwrap().initial.spec();
        let mut sized = Config::default();
        sized.map.size_m = Some([12.0, 12.0]);
        for config in [Config::default(), sized] {
            assert_eq!(
                hosted(&config, Some(world.clone())),
                cores(&config, Some(bounds))
            );
        }
        let framed = hosted(&Config::default(), Some(world));
        assert_ne!(
            framed,
            hosted(&Config::default(), None),
            "the world frames it"
        );
        assert!(framed.origin_enu_m.x < bounds.0.x && framed.origin_enu_m.y < bounds.0.y);
    }
}
