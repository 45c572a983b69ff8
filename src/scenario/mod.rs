//! Flights made up for a fleet rather than given by an operator: the built-in simulator as a
//! host (`sim_host`), the demo flight (`demo`), and scenario files (`file`: frames and a
//! mission) with a coverage area split among several drones (`coverage`). Above the host and the simulator, and imported by
//! neither: the command line and the tests build hosts and missions from here, handing each
//! host the world it is judged against.

pub mod coverage;
pub mod demo;
pub mod file;
pub mod sim_host;

pub use sim_host::{simulated_host, SimulatedHost};
