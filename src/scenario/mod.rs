//! Flights made up for a fleet rather than given by an operator: the built-in simulator as a
//! host (`sim_host`), real vehicles in a virtual world (`virtual_world`) and the demo flight
//! (`demo`). Above the host and the simulator, and imported by neither: the command line and
//! the tests build hosts from here, handing each the world it is judged against.

pub mod demo;
pub mod sim_host;
pub mod virtual_world;

pub use sim_host::{simulated_host, SimulatedHost};
