//! A host flying real vehicles: one core per [`Platform`] (a MAVLink autopilot), ticked in
//! real time. `kestrel run` builds its core and platform, then serves this host.
//!
//! In: cores and their platforms, the config, the bounds of a virtual world if any. Out: a
//! [`Host`] over
//! `Vec<Box<dyn Platform>>`, with the fleet's merged map on the `[map]` section's grid (the one
//! the cores map on), so the frontier allocator of exploration and the map routes work as in the
//! simulator.

use super::engine::{Host, HostConfig};
use crate::config::Config;
use crate::core::DroneCore;
use crate::mapping::merged::FleetMap;
use crate::platform::Platform;
use crate::types::Vec2;
use std::time::Duration;

/// `vehicles`: each core with the platform it flies, in order.
pub fn vehicle_host(vehicles: Vec<(DroneCore, Box<dyn Platform>)>, config: &Config) -> Host {
    framed_host(vehicles, config, None)
}

/// The same host with the merged map framed on `world_bounds` (SW and NE corners, ENU m)
/// unless `[map]` gives its extent: for vehicles flying in a virtual world
/// (`scenario::virtual_world`), as in the simulator; the cores' maps must be built from the
/// same section and bounds.
pub fn framed_host(
    vehicles: Vec<(DroneCore, Box<dyn Platform>)>,
    config: &Config,
    world_bounds: Option<(Vec2, Vec2)>,
) -> Host {
    let (cores, platforms): (Vec<DroneCore>, Vec<Box<dyn Platform>>) = vehicles.into_iter().unzip();
    let mut host = Host::new(
        cores,
        Box::new(platforms),
        HostConfig {
            limits: config.mission_limits(),
            executor: config.executor_config(),
            tick: Duration::from_secs_f64(1.0 / config.drone.control_rate_hz),
        },
    );
    // Without a world to frame it: the section's extent, centred on the `earth` origin unless
    // it says where (the cores' own maps are built from the same section).
    match config
        .map
        .config(world_bounds)
        .map(|m| m.map(|m| FleetMap::new(&m)))
    {
        Ok(Some(Ok(map))) => host.set_map(map),
        Ok(None) => {}
        Ok(Some(Err(e))) | Err(e) => tracing::error!("no merged map: {e}"),
    }
    host
}

/// The state directory: `--state-dir`, else `$STATE_DIRECTORY` (set by systemd), else the
/// config's `[mission] state_dir`, else `./kestrel-state`.
pub fn state_dir(flag: Option<std::path::PathBuf>, config: &Config) -> std::path::PathBuf {
    flag.or_else(|| {
        std::env::var_os("STATE_DIRECTORY")
            .map(std::path::PathBuf::from)
            // systemd may list several directories separated by ':'; the first is ours.
            .map(|p| {
                p.to_string_lossy()
                    .split(':')
                    .next()
                    .map(std::path::PathBuf::from)
                    .unwrap_or(p)
            })
    })
    .or_else(|| config.mission.state_dir.clone())
    .unwrap_or_else(|| std::path::PathBuf::from("kestrel-state"))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::behavior::Registry;
    use crate::core::CoreConfig;
    use crate::platform::{Capabilities, PlatformFeedback, PlatformRequest};
    use crate::types::{AcceptedSetpoints, Setpoint, Vec3};

    /// A vehicle that stays on the ground and reports nothing: what hosting needs of one.
    struct Grounded;

    impl Platform for Grounded {
        fn capabilities(&self) -> Capabilities {
            Capabilities {
                setpoints: AcceptedSetpoints {
                    velocity: true,
                    position: true,
                    position_loop: None,
                },
                native_takeoff: false,
                native_land: false,
                velocity_lag_s: None,
            }
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
        let mut host = vehicle_host(vec![(core, Box::new(vehicle))], &Config::default());
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
        let mut host = vehicle_host(vec![(core, Box::new(vehicle))], &config);
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

    #[test]
    fn the_flag_wins_over_the_config() {
        let mut config = Config::default();
        config.mission.state_dir = Some("/var/lib/kestrel".into());
        assert_eq!(
            state_dir(Some("/tmp/x".into()), &config),
            std::path::PathBuf::from("/tmp/x")
        );
    }
}
