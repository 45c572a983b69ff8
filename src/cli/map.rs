//! `kestrel map export`: a map in the ROS `map_server` format (PGM + YAML), from a running
//! Kestrel's API or from a saved `GET /api/map` answer. The YAML is what `[map] known_map`
//! loads back at start.

use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use kestrel::mapping::{GridSpec, OccupancyGrid};
use serde_json::Value;
use std::path::{Path, PathBuf};

#[derive(Subcommand, Debug)]
pub enum MapCommand {
    /// Write a map as NAME.pgm + NAME.yaml (ROS map_server format) into --out.
    Export(ExportArgs),
}

#[derive(Args, Debug)]
pub struct ExportArgs {
    /// Folder to write into (created if missing).
    #[arg(long)]
    out: PathBuf,
    /// A drone's own map; absent = the merged map.
    #[arg(long)]
    drone: Option<String>,
    /// Base URL of a running Kestrel's API (`http://` only).
    #[arg(long, default_value = "http://127.0.0.1:8080")]
    from: String,
    /// Bearer token of that API (default: KESTREL_API_TOKEN).
    #[arg(long, env = "KESTREL_API_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// File holding the token (e.g. /etc/kestrel/api-token).
    #[arg(long)]
    token_file: Option<PathBuf>,
    /// Read a saved `GET /api/map` answer (JSON) instead of asking a running Kestrel.
    #[arg(long, conflicts_with_all = ["from", "drone", "token_file"])]
    input: Option<PathBuf>,
    /// File name (without extension) of the PGM and YAML.
    #[arg(long, default_value = "map")]
    name: String,
}

pub fn run(command: MapCommand) -> Result<()> {
    match command {
        MapCommand::Export(args) => export(&args),
    }
}

fn export(args: &ExportArgs) -> Result<()> {
    let answer: Value = match &args.input {
        Some(path) => {
            let text = std::fs::read_to_string(path)
                .with_context(|| format!("reading {}", path.display()))?;
            serde_json::from_str(&text).with_context(|| format!("parsing {}", path.display()))?
        }
        None => fetch(args)?,
    };
    let grid = grid_of(&answer)?;
    write(&grid, &args.out, &args.name)
}

/// `GET /api/map` from the running Kestrel.
fn fetch(args: &ExportArgs) -> Result<Value> {
    let token = super::api_client::token(args.token.as_deref(), args.token_file.as_deref())?;
    let remote = crate::cli::api_client::Remote::new(&args.from, token)?;
    let path = match &args.drone {
        Some(d) => format!("/api/map?drone={d}"),
        None => "/api/map".to_string(),
    };
    let (status, body) = tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting tokio")?
        .block_on(remote.call("GET", &path, None))?;
    if status != 200 {
        let message = body["error"]["message"].as_str().unwrap_or("no message");
        bail!("GET {path}: HTTP {status}: {message}");
    }
    Ok(body)
}

/// The grid of a `{spec, data, ..}` answer.
fn grid_of(answer: &Value) -> Result<OccupancyGrid> {
    let spec: GridSpec =
        serde_json::from_value(answer["spec"].clone()).context("the map's `spec`")?;
    let data: Vec<i8> =
        serde_json::from_value(answer["data"].clone()).context("the map's `data`")?;
    Ok(OccupancyGrid::from_data(spec, data)?)
}

fn write(grid: &OccupancyGrid, dir: &Path, name: &str) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let image = format!("{name}.pgm");
    let (pgm, yaml) = grid.to_pgm_yaml(&image);
    let pgm_path = dir.join(&image);
    let yaml_path = dir.join(format!("{name}.yaml"));
    std::fs::write(&pgm_path, pgm).with_context(|| format!("writing {}", pgm_path.display()))?;
    std::fs::write(&yaml_path, yaml).with_context(|| format!("writing {}", yaml_path.display()))?;
    let s = grid.spec();
    println!(
        "wrote {} and {} ({} x {} cells at {} m)",
        yaml_path.display(),
        pgm_path.display(),
        s.width_cells,
        s.height_cells,
        s.resolution_m
    );
    Ok(())
}
