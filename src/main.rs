//! `kestrel`: the composition root. Parses the command line, loads config, wires the parts.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod cli;

#[derive(Parser)]
#[command(
    name = "kestrel",
    version,
    about = "Onboard autonomy for multirotor drones: behaviors, missions, mapping and planning over MAVLink"
)]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
    /// Fly in the built-in simulator (no hardware needed). Without options: the demo flight.
    Sim(cli::sim::SimArgs),
    /// Explore a world with N simulated drones until no frontier is left; report the metrics.
    Explore(cli::explore::ExploreArgs),
    /// Fly a PX4 or ArduPilot autopilot over MAVLink (`--platform`, `--connection`).
    Run(cli::run::RunArgs),
    /// Missions: validate a file, fly it in the simulator, print the schema.
    #[command(subcommand)]
    Mission(cli::mission::MissionCommand),
    /// Maps: export one in the ROS map_server format (PGM + YAML).
    #[command(subcommand)]
    Map(cli::map::MapCommand),
    /// Exploration worlds: generate a seeded one.
    #[command(subcommand)]
    World(cli::world::WorldCommand),
    /// Exploration metrics of a flight log against the true world.
    Evaluate(cli::evaluate::EvaluateArgs),
    /// Flight-log files: convert a JSON-lines log to MCAP.
    #[command(subcommand)]
    Log(cli::log::LogCommand),
    /// A flight log as a report: index.html with figures (SVG, PNG), a table and poses.csv.
    Report(cli::report::ReportArgs),
    /// Check a config file as `kestrel run` does at start (platform, token, listen address,
    /// directories) and print a short summary.
    CheckConfig {
        /// Config file (TOML).
        #[arg(long, default_value = "/etc/kestrel/kestrel.toml")]
        config: PathBuf,
        /// Also check this world file as `kestrel run --virtual-world` would load it.
        #[arg(long)]
        virtual_world: Option<PathBuf>,
    },
    /// Make this node's fleet-bus key in FILE (never replacing one) and print its public key
    /// for the fleet's roster; with --public, print the public key of an existing FILE.
    FleetKey {
        file: PathBuf,
        #[arg(long)]
        public: bool,
    },
}

fn main() -> Result<()> {
    cli::console::init_logging();
    let Cli { command } = Cli::parse();
    match command {
        Command::Sim(args) => cli::sim::run(args),
        Command::Run(args) => cli::run::run(args),
        Command::Explore(args) => cli::explore::run(args),
        Command::Mission(command) => cli::mission::run(command),
        Command::Map(command) => cli::map::run(command),
        Command::World(command) => cli::world::run(command),
        Command::Evaluate(args) => cli::evaluate::run(args),
        Command::Report(args) => cli::report::run(args),
        Command::Log(command) => cli::log::run(command),
        Command::CheckConfig {
            config,
            virtual_world,
        } => cli::startup::check(&config, virtual_world),
        Command::FleetKey { file, public } => cli::fleet_key::key(&file, public),
    }
}
