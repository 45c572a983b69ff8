//! A host for real vehicles flying in a virtual world (`kestrel run --virtual-world`, their
//! platforms wrapped in `sim::virtual_world`).
//!
//! In: cores and their platforms, the config, the world. Out: a [`Host`] whose merged map is
//! framed on the world's bounds unless `[map]` gives its extent (as in the simulator; the cores'
//! maps must be built from the same section and bounds), with the world as the truth the
//! exploration report judges runs against.

use crate::config::Config;
use crate::core::DroneCore;
use crate::host::vehicle::framed_host;
use crate::host::Host;
use crate::platform::Platform;
use crate::sim::world::World;

pub fn virtual_world_host(
    vehicles: Vec<(DroneCore, Box<dyn Platform>)>,
    config: &Config,
    world: World,
) -> Host {
    let mut host = framed_host(vehicles, config, Some(world.bounds_m.corners()));
    host.set_true_world(world);
    host
}
