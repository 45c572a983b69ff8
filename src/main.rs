//! `kestrel`: the composition root. Parses the command line, loads config, wires the parts.

use anyhow::Result;
use clap::{Parser, Subcommand};
use std::path::PathBuf;

mod cli_announce;
mod cli_console;
mod cli_evaluate;
mod cli_explore;
mod cli_fleet;
mod cli_flights;
mod cli_log;
mod cli_map;
mod cli_mission;
mod cli_remote;
mod cli_report;
mod cli_run;
mod cli_serve;
mod cli_sim;
mod cli_startup;
mod cli_world;

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
    Sim(cli_sim::SimArgs),
    /// Explore a world with N simulated drones until no frontier is left; report the metrics.
    Explore(cli_explore::ExploreArgs),
    /// Fly a PX4 or ArduPilot autopilot over MAVLink (`--platform`, `--connection`).
    Run(cli_run::RunArgs),
    /// Missions: validate a file, fly it in the simulator, print the schema.
    #[command(subcommand)]
    Mission(cli_mission::MissionCommand),
    /// Maps: export one in the ROS map_server format (PGM + YAML).
    #[command(subcommand)]
    Map(cli_map::MapCommand),
    /// Exploration worlds: generate a seeded one.
    #[command(subcommand)]
    World(cli_world::WorldCommand),
    /// Exploration metrics of a flight log against the true world.
    Evaluate(cli_evaluate::EvaluateArgs),
    /// Flight-log files: convert a JSON-lines log to MCAP.
    #[command(subcommand)]
    Log(cli_log::LogCommand),
    /// A flight log as a report: index.html with figures (SVG, PNG), a table and poses.csv.
    Report(cli_report::ReportArgs),
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
    cli_console::init_logging();
    let cli = Cli::parse();
    match cli.command {
        Command::Sim(args) => cli_sim::run(args),
        Command::Run(args) => cli_run::run(args),
        Command::Explore(args) => cli_explore::run(args),
        Command::Mission(command) => cli_mission::run(command),
        Command::Map(command) => cli_map::run(command),
        Command::World(command) => cli_world::run(command),
        Command::Evaluate(args) => cli_evaluate::run(args),
        Command::Report(args) => cli_report::run(args),
        Command::Log(command) => cli_log::run(command),
        Command::CheckConfig {
            config,
            virtual_world,
        } => cli_startup::check(&config, virtual_world),
        Command::FleetKey { file, public } => cli_fleet::key(&file, public),
    }
}
