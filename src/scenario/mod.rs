//! Flights made up for a fleet rather than given by an operator: the built-in simulator as a
//! host (`sim_host`), real vehicles in a virtual world (`virtual_world`), the demo flight
//! (`demo`), and scenario files (`file`: frames and a mission) with a coverage area split
//! among several drones (`coverage`). Above the host and the simulator, and imported by
//! neither: the command line and the tests build hosts and missions from here, handing each
//! host the world it is judged against.

pub mod coverage;
pub mod demo;
pub mod file;
pub mod sim_host;
pub mod virtual_world;

pub use sim_host::{simulated_host, SimulatedHost};
