//! `kestrel world generate`: a seeded exploration world (poles, nested starts) as a world file.
//!
//! In: the side, the pole density or count, the seed, `--fence`, `--co-located`. Out: the world
//! JSON (the layout of `sitl/worlds/low.json`) written to `--out`, and one summary line.

use anyhow::{Context, Result};
use clap::{Args, Subcommand};
use kestrel::exploration::offline::worldgen::{self, PoleCount, WorldGenParams};
use std::path::PathBuf;

#[derive(Subcommand, Debug)]
pub enum WorldCommand {
    /// Generate a seeded exploration world (exploration-research §4.1).
    Generate(GenerateArgs),
}

#[derive(Args, Debug)]
pub struct GenerateArgs {
    /// Side of the square world, centred on the origin (m).
    #[arg(long, default_value_t = 20.0)]
    size_m: f64,
    /// Random poles per m^2 (of the fence's inside with --fence).
    #[arg(long, default_value_t = 0.1)]
    density: f64,
    /// Exact number of random poles (overrides --density).
    #[arg(long)]
    poles: Option<usize>,
    /// Seed of the generator; the same arguments and seed give the same world.
    #[arg(long)]
    seed: u64,
    /// Ring the area with poles 0.6 m apart, leaving one 2 m opening.
    #[arg(long)]
    fence: bool,
    /// All starts in one 3 m disc instead of spread over the area.
    #[arg(long)]
    co_located: bool,
    /// World file to write (JSON).
    #[arg(long)]
    out: PathBuf,
}

pub fn run(command: WorldCommand) -> Result<()> {
    match command {
        WorldCommand::Generate(args) => generate(&args),
    }
}

fn generate(args: &GenerateArgs) -> Result<()> {
    let params = WorldGenParams {
        size_m: args.size_m,
        poles: match args.poles {
            Some(n) => PoleCount::Exactly(n),
            None => PoleCount::PerM2(args.density),
        },
        seed: args.seed,
        fence: args.fence,
        co_located: args.co_located,
    };
    let world = worldgen::generate(&params).context("generating the world")?;
    let source = source_of(args);
    let text =
        worldgen::world_file_json(&world, &params, &source).context("writing the world as JSON")?;
    std::fs::write(&args.out, text + "\n")
        .with_context(|| format!("writing {}", args.out.display()))?;
    println!(
        "{}: {} poles in {} m x {} m, 7 starts -> {}",
        world.name,
        world.poles_xy_m.len(),
        args.size_m,
        args.size_m,
        args.out.display()
    );
    Ok(())
}

/// The command line that regenerates the file, recorded in its `source` field.
fn source_of(args: &GenerateArgs) -> String {
    let mut s = format!("kestrel world generate --size-m {}", args.size_m);
    match args.poles {
        Some(n) => s += &format!(" --poles {n}"),
        None => s += &format!(" --density {}", args.density),
    }
    s += &format!(" --seed {}", args.seed);
    if args.fence {
        s += " --fence";
    }
    if args.co_located {
        s += " --co-located";
    }
    s
}
