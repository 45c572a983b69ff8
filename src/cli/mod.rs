//! The `kestrel` binary's commands: one file per subcommand, and the helpers they share.
//! Everything here is the binary's top level (errors are `anyhow`); the work is the library's.

// Subcommands.
pub mod evaluate;
pub mod explore;
pub mod fleet_key;
pub mod log;
pub mod map;
pub mod mission;
pub mod report;
pub mod run;
pub mod sim;
pub mod world;

// Helpers: the checks before start (and `check-config`), serving a host, what is printed and
// told to the ground station, the flights followed, a client of a running Kestrel's API.
pub mod announce;
pub mod api_client;
pub mod console;
pub mod flights;
pub mod serve;
pub mod startup;
