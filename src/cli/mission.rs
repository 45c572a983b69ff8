//! `kestrel mission validate|run|schema`: check a mission file against this build's behaviors,
//! the config's limits and a scenario's frames; fly it in the simulator; print the schema.

use crate::cli::sim::{self, SimArgs};
use anyhow::{bail, Context, Result};
use clap::{Args, Subcommand};
use kestrel::mission::schema::mission_schema;
use kestrel::scenario::file::Scenario;
use std::path::PathBuf;

#[derive(Subcommand, Debug)]
pub enum MissionCommand {
    /// Check a mission (JSON): every error as a JSON pointer and a message; exit 1 if invalid.
    Validate(ValidateArgs),
    /// Fly a mission until it ends (exit 0 if it succeeded): in the built-in simulator, or with
    /// `--api URL` on a running Kestrel (the vehicle's service).
    Run(RunArgs),
    /// Print the JSON Schema of missions (the source of missions/schema.json).
    Schema,
}

#[derive(Args, Debug)]
pub struct ValidateArgs {
    /// Mission file.
    file: PathBuf,
    /// Scenario whose frames the mission uses.
    #[arg(long)]
    scenario: Option<PathBuf>,
    /// Config file (limits, geofence).
    #[arg(long)]
    config: Option<PathBuf>,
    /// Drones in the simulator (missions may target drone_0 ... drone_{N-1}).
    #[arg(long, default_value_t = 1)]
    drones: usize,
}

#[derive(Args, Debug)]
pub struct RunArgs {
    /// Mission file.
    file: PathBuf,
    /// Scenario whose frames the mission uses.
    #[arg(long)]
    scenario: Option<PathBuf>,
    #[arg(long)]
    config: Option<PathBuf>,
    #[arg(long)]
    world: Option<PathBuf>,
    #[arg(long, default_value_t = 1)]
    drones: usize,
    /// Simulated seconds per wall-clock second, or `max`.
    #[arg(long, default_value = "max")]
    speedup: String,
    /// Flight log (JSON lines).
    #[arg(long)]
    log: Option<PathBuf>,
    /// With --log: replace the file if it exists.
    #[arg(long, requires = "log")]
    log_overwrite: bool,
    /// Serve the API meanwhile on ADDR:PORT (default: any free loopback port).
    #[arg(long, default_value = "127.0.0.1:0")]
    listen: String,
    #[arg(long, default_value_t = 3600.0)]
    max_sim_time_s: f64,
    /// Fly it on the Kestrel serving this API (e.g. http://127.0.0.1:8080) instead.
    #[arg(long)]
    api: Option<String>,
    /// Token for --api (default: KESTREL_API_TOKEN).
    #[arg(long, env = "KESTREL_API_TOKEN", hide_env_values = true)]
    token: Option<String>,
    /// File holding the token for --api (e.g. /etc/kestrel/api-token).
    #[arg(long)]
    token_file: Option<PathBuf>,
}

pub fn run(command: MissionCommand) -> Result<()> {
    match command {
        MissionCommand::Validate(a) => validate(a),
        MissionCommand::Run(a) if a.api.is_some() => remote(a),
        MissionCommand::Run(a) => sim::run(SimArgs {
            world: a.world,
            drones: a.drones,
            speedup: a.speedup,
            seed: 0,
            log: a.log,
            log_overwrite: a.log_overwrite,
            log_format: None,
            exit_when_done: true,
            config: a.config,
            sensor: None,
            max_sim_time_s: a.max_sim_time_s,
            listen: Some(a.listen),
            mission: Some(a.file),
            scenario: a.scenario,
            no_demo: false,
            state_dir: None,
        }),
        MissionCommand::Schema => {
            let schema = mission_schema(&kestrel::behavior::payload::registry());
            println!("{}", serde_json::to_string_pretty(&schema)?);
            Ok(())
        }
    }
}

fn remote(a: RunArgs) -> Result<()> {
    let token = super::api_client::token(a.token.as_deref(), a.token_file.as_deref())?;
    let remote = crate::cli::api_client::Remote::new(a.api.as_deref().unwrap_or_default(), token)?;
    let text = std::fs::read_to_string(&a.file)
        .with_context(|| format!("cannot read {}", a.file.display()))?;
    let mission: serde_json::Value = serde_json::from_str(&text)
        .with_context(|| format!("{} is not valid JSON", a.file.display()))?;
    let frames = match &a.scenario {
        Some(path) => Scenario::load(path)?.frames,
        None => Vec::new(),
    };
    tokio::runtime::Builder::new_current_thread()
        .enable_all()
        .build()
        .context("starting tokio")?
        .block_on(async move {
            for f in frames {
                let body = serde_json::to_value(&f)?;
                let (code, answer) = remote.call("POST", "/api/frames", Some(&body)).await?;
                if code != 200 {
                    bail!("registering frame {}: HTTP {code}: {answer}", f.frame_id);
                }
            }
            crate::cli::api_client::run(remote, mission).await
        })
}

fn validate(a: ValidateArgs) -> Result<()> {
    let config = sim::load_config(a.config.as_deref())?;
    let scenario = a.scenario.as_deref().map(Scenario::load).transpose()?;
    let args = SimArgs {
        world: None,
        drones: a.drones,
        speedup: "max".into(),
        seed: 0,
        log: None,
        log_overwrite: false,
        log_format: None,
        exit_when_done: true,
        config: None,
        sensor: None,
        max_sim_time_s: 0.0,
        listen: None,
        mission: None,
        scenario: None,
        no_demo: true,
        state_dir: None,
    };
    let (host, _) = sim::build(&args, &config, scenario.as_ref())?;
    let text = std::fs::read_to_string(&a.file)
        .with_context(|| format!("cannot read {}", a.file.display()))?;
    let value: serde_json::Value = match serde_json::from_str(&text) {
        Ok(v) => v,
        Err(e) => bail!("{}: not valid JSON: {e}", a.file.display()),
    };
    let target = value.get("target").and_then(|t| t.as_str()).unwrap_or("");
    let index = host
        .drone_ids()
        .iter()
        .position(|d| d == target)
        .unwrap_or(0);
    match host.validate(index, &value) {
        Ok(valid) => {
            for w in &valid.warnings {
                println!("warning: {w}");
            }
            println!(
                "{}: valid ({} items for {})",
                a.file.display(),
                valid.items.len(),
                valid.target
            );
            Ok(())
        }
        Err(kestrel::host::HostError::Invalid(errors)) => {
            for e in &errors {
                println!("{e}");
            }
            bail!("{}: {} error(s)", a.file.display(), errors.len())
        }
        Err(e) => bail!("{e}"),
    }
}
