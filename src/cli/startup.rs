//! What `kestrel run` checks before it starts anything, shared with `kestrel check-config` so
//! the two cannot disagree: whatever makes `run` refuse to start makes `check-config` fail.
//!
//! In: the config file (or the defaults), the command line's overrides and the environment
//! (`KESTREL_API_TOKEN`, `STATE_DIRECTORY`, `KESTREL_DATA_DIR`). Out: a [`Startup`] (the
//! validated config, each vehicle's platform resolved and loaded with its link, the API's address
//! and token, the fleet bus's credentials, the log and state directories, writable or creatable,
//! and warnings), or the first reason to refuse, naming the file and the key. One vehicle
//! (`[drone] id` over `[mavlink]`) unless the config has a `[[vehicle]]` list; `--connection` is
//! refused with a list (each vehicle names its own), `--platform` then replaces
//! `mavlink.platform`, the profile of the vehicles that name none.
//!
//! `--virtual-world FILE` (`run` and `check-config`) is loaded here too, bounded and checked by
//! the world loader (`sim::world`); it is refused with the built-in simulator, which has a world
//! of its own. With it the map is framed on the world's bounds, as in the simulator.
//!
//! Platform names resolve in this order: a file at that path (relative to the working
//! directory); a built-in name (`px4`, `ardupilot-copter`, `sim`); for a relative path, the
//! installed profiles: `<data dir>/NAME`, `<data dir>/platforms/NAME`, and
//! `<data dir>/platforms/NAME.toml` for a name without extension, where the data dir is
//! `$KESTREL_DATA_DIR` or `/usr/share/kestrel`.

use anyhow::{bail, Context, Result};
use kestrel::config::Config;
use kestrel::mapping::config::MapConfig;
use kestrel::platform::mavlink::Profile;
use kestrel::sim::world::World;
use kestrel::types::SensorConfig;
use serde::Deserialize;
use std::net::SocketAddr;
use std::path::{Path, PathBuf};

/// Where the installed profiles and example missions live (the .deb and systemd/install.sh).
pub const DATA_DIR: &str = "/usr/share/kestrel";

/// The built-in platform names.
const BUILTIN: [&str; 3] = ["px4", "ardupilot-copter", "sim"];

/// `platforms/sim.toml`: the built-in simulator, stepped in real time.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SimPlatformFile {
    /// `sim`: read by [`load_platform`] before this struct.
    #[serde(rename = "platform")]
    _platform: String,
    pub name: String,
    world: Option<PathBuf>,
    #[serde(default)]
    pub seed: u64,
}

/// The platform `run` will start, already loaded and validated.
pub enum PlatformPlan {
    /// The real-time simulator with its world.
    Sim {
        file: SimPlatformFile,
        world: Box<World>,
    },
    /// An autopilot over MAVLink with this profile.
    Mavlink(Box<Profile>),
}

/// One vehicle `run` will fly: its platform, loaded, and where its autopilot is.
pub struct VehiclePlan {
    /// The core's id (missions' `target`, the API).
    pub id: String,
    /// Where the platform came from: `built-in px4` or the file's path.
    pub platform_origin: String,
    pub platform: PlatformPlan,
    /// The MAVLink connection (unused by the simulator).
    pub connection: String,
    pub forward: Vec<String>,
    /// Follow only this autopilot system id.
    pub target_system: Option<u8>,
    /// Its local frame's origin in the shared frame (m, ENU); zero for the single vehicle.
    pub origin_enu_m: [f64; 3],
    /// The sensor its `[[vehicle]]` entry names for the virtual world (`None`: the default).
    pub sensor: Option<SensorConfig>,
}

/// `--virtual-world`: the file, loaded and checked.
pub struct VirtualWorldPlan {
    pub path: PathBuf,
    pub world: World,
}

impl VirtualWorldPlan {
    /// The sensor cast for `vehicle`: its own, else `[sim] sensor`, else the world file's (the
    /// four-beam multi-ranger when the file names none).
    pub fn sensor(&self, vehicle: &VehiclePlan, config: &Config) -> SensorConfig {
        vehicle
            .sensor
            .or(config.sim.sensor)
            .unwrap_or(self.world.sensor)
    }
}

/// Everything `run` needs that can be checked without touching the vehicle or the network.
pub struct Startup {
    pub config: Config,
    /// At least one; several with a `[[vehicle]]` list.
    pub vehicles: Vec<VehiclePlan>,
    pub map: Option<MapConfig>,
    /// `None` with `--no-api`.
    pub listen: Option<SocketAddr>,
    pub token: Option<String>,
    /// What starts but deserves a word: `run` logs each, `check-config` prints each.
    pub warnings: Vec<String>,
    pub log_dir: PathBuf,
    pub state_dir: PathBuf,
    /// `--virtual-world`: the vehicles' range sensors are cast against its obstacles.
    pub virtual_world: Option<VirtualWorldPlan>,
}

/// The command line's say over the config (all `None` for `check-config`, but
/// `virtual_world`).
#[derive(Default)]
pub struct Overrides {
    pub platform: Option<String>,
    pub connection: Option<String>,
    pub listen: Option<String>,
    pub state_dir: Option<PathBuf>,
    pub no_api: bool,
    pub virtual_world: Option<PathBuf>,
}

/// Loads and checks everything `run` checks at start, in the order it uses them.
pub fn prepare(config_path: Option<&Path>, overrides: &Overrides) -> Result<Startup> {
    let file = config_path.map_or_else(|| "the default config".into(), |p| p.display().to_string());
    let mut config = match config_path {
        Some(p) => Config::load(p)?,
        None => Config::default(),
    };
    let platform_key = match &overrides.platform {
        Some(p) => {
            config.mavlink.platform = p.clone();
            "--platform".to_string()
        }
        None => format!("{file}: mavlink.platform"),
    };
    if let Some(c) = &overrides.connection {
        if !config.vehicles.is_empty() {
            bail!(
                "--connection: {file} has a [[vehicle]] list, where each vehicle names its own \
                 connection"
            );
        }
        config.mavlink.connection = c.clone();
    }
    config
        .mavlink
        .validate()
        .map_err(|(field, message)| anyhow::anyhow!("{file}: {field}: {message}"))?;
    let vehicles = vehicle_plans(&config, &platform_key, &file)?;
    let virtual_world = match &overrides.virtual_world {
        Some(path) => Some(virtual_world(path, &vehicles)?),
        None => None,
    };
    let map = config
        .map
        .config(virtual_world.as_ref().map(|v| v.world.bounds_m.corners()))
        .with_context(|| format!("{file}: [map]"))?;
    let (listen, token) = api(&config, overrides, &file)?;
    let mut warnings = token_warnings(&config);
    crate::cli::fleet_key::check(&config, &file, &mut warnings)?;
    let log_dir = config.drone.log_dir.clone().unwrap_or_default();
    directory(&log_dir, &format!("{file}: drone.log_dir"))?;
    let state_dir = kestrel::host::vehicle::state_dir(overrides.state_dir.clone(), &config);
    directory(&state_dir, "the state directory")?;
    Ok(Startup {
        config,
        vehicles,
        map,
        listen,
        token,
        warnings,
        log_dir,
        state_dir,
        virtual_world,
    })
}

/// Loads `--virtual-world`'s file; refused for the built-in simulator, which has its own world.
fn virtual_world(path: &Path, vehicles: &[VehiclePlan]) -> Result<VirtualWorldPlan> {
    if vehicles
        .iter()
        .any(|v| matches!(v.platform, PlatformPlan::Sim { .. }))
    {
        bail!(
            "--virtual-world {}: the built-in simulator flies in its own world (the `world` of \
             its platform file); --virtual-world is for autopilots",
            path.display()
        );
    }
    let world = World::load(path).context("--virtual-world")?;
    Ok(VirtualWorldPlan {
        path: path.to_path_buf(),
        world,
    })
}

/// The vehicles to fly: the `[[vehicle]]` list, or the one of `[drone]` and `[mavlink]`.
fn vehicle_plans(config: &Config, platform_key: &str, file: &str) -> Result<Vec<VehiclePlan>> {
    let m = &config.mavlink;
    if config.vehicles.is_empty() {
        let (platform_origin, platform) =
            load_platform(&m.platform).with_context(|| platform_key.to_string())?;
        return Ok(vec![VehiclePlan {
            id: config.drone.id.clone(),
            platform_origin,
            platform,
            connection: m.connection.clone(),
            forward: m.forward.clone(),
            target_system: m.target_system,
            origin_enu_m: [0.0; 3],
            sensor: None,
        }]);
    }
    config
        .vehicles
        .iter()
        .enumerate()
        .map(|(i, v)| {
            let (name, key) = match &v.platform {
                Some(p) => (p, format!("{file}: vehicle[{i}].platform")),
                None => (&m.platform, platform_key.to_string()),
            };
            let (platform_origin, platform) = load_platform(name).with_context(|| key.clone())?;
            if let PlatformPlan::Sim { .. } = platform {
                bail!(
                    "{key}: the built-in simulator flies one vehicle under `kestrel run`; \
                     `kestrel sim` flies fleets"
                );
            }
            Ok(VehiclePlan {
                id: v.id.clone(),
                platform_origin,
                platform,
                connection: v.connection.clone(),
                forward: v.forward.clone(),
                target_system: v.target_system,
                origin_enu_m: v.origin_enu_m,
                sensor: v.sensor,
            })
        })
        .collect()
}

/// The API's address and token; refuses a listen address beyond loopback without a token.
fn api(
    config: &Config,
    overrides: &Overrides,
    file: &str,
) -> Result<(Option<SocketAddr>, Option<String>)> {
    let token =
        kestrel::api::auth::resolve_token(std::env::var("KESTREL_API_TOKEN").ok(), &config.api)
            .with_context(|| format!("{file}: [api]"))?;
    if overrides.no_api {
        return Ok((None, token));
    }
    let listen: SocketAddr = match &overrides.listen {
        Some(l) => l
            .parse()
            .with_context(|| format!("--listen `{l}`: takes ADDR:PORT, e.g. 127.0.0.1:8080"))?,
        None => config
            .api
            .listen
            .parse()
            .with_context(|| format!("{file}: api.listen"))?,
    };
    kestrel::api::auth::check_listen(listen, token.as_deref())
        .with_context(|| format!("{file}: [api]"))?;
    Ok((Some(listen), token))
}

/// `KESTREL_API_TOKEN` wins over `[api] token_file`: a file that could not be read would go
/// unnoticed until the variable is gone (a service started without it), so it is said now.
fn token_warnings(config: &Config) -> Vec<String> {
    let Some(path) = config.api.token_file.as_ref() else {
        return Vec::new();
    };
    if std::env::var_os("KESTREL_API_TOKEN").is_none() {
        return Vec::new();
    }
    match std::fs::read_to_string(path) {
        Ok(text) if !text.trim().is_empty() => Vec::new(),
        Ok(_) => vec![format!(
            "api.token_file {} is empty; KESTREL_API_TOKEN is used instead, and without it \
             `run` refuses to start",
            path.display()
        )],
        Err(e) => vec![format!(
            "api.token_file {}: {e}; KESTREL_API_TOKEN is used instead, and without it `run` \
             refuses to start",
            path.display()
        )],
    }
}

/// A directory `run` writes in, created if missing: it must be a directory, or be creatable,
/// and writable. Checked without leaving anything behind: a probe file is made and removed in
/// it, or in the nearest directory that exists above it.
fn directory(dir: &Path, what: &str) -> Result<()> {
    let shown = if dir.as_os_str().is_empty() {
        Path::new(".")
    } else {
        dir
    };
    let mut existing = shown;
    while !existing.exists() {
        match existing.parent() {
            Some(p) if !p.as_os_str().is_empty() => existing = p,
            _ => {
                existing = Path::new(".");
                break;
            }
        }
    }
    if !existing.is_dir() {
        if existing == shown {
            bail!("{what}: {} exists and is not a directory", shown.display());
        }
        bail!(
            "{what}: {} cannot be created: {} is not a directory",
            shown.display(),
            existing.display()
        );
    }
    let probe = existing.join(format!(".kestrel-check-{}", std::process::id()));
    let written = std::fs::OpenOptions::new()
        .write(true)
        .create_new(true)
        .open(&probe);
    match written {
        Ok(_) => std::fs::remove_file(&probe)
            .with_context(|| format!("{what}: removing the probe {}", probe.display())),
        Err(e) if existing == shown => bail!("{what}: {} is not writable: {e}", shown.display()),
        Err(e) => bail!(
            "{what}: {} cannot be created in {}: {e}",
            shown.display(),
            existing.display()
        ),
    }
}

/// Where a platform name leads: a file, or a built-in name.
enum Source {
    File(PathBuf),
    Builtin(String),
}

fn data_dir() -> PathBuf {
    std::env::var_os("KESTREL_DATA_DIR").map_or_else(|| PathBuf::from(DATA_DIR), PathBuf::from)
}

fn resolve(name: &str) -> Result<Source> {
    let path = Path::new(name);
    if path.is_file() {
        return Ok(Source::File(path.to_path_buf()));
    }
    if BUILTIN.contains(&name) {
        return Ok(Source::Builtin(name.to_string()));
    }
    let mut tried = vec![path.to_path_buf()];
    if path.is_relative() && !name.is_empty() {
        let data = data_dir();
        tried.push(data.join(path));
        tried.push(data.join("platforms").join(path));
        if path.extension().is_none() {
            tried.push(data.join("platforms").join(format!("{name}.toml")));
        }
    }
    if let Some(found) = tried.iter().skip(1).find(|p| p.is_file()) {
        return Ok(Source::File(found.clone()));
    }
    let places: Vec<String> = tried.iter().map(|p| p.display().to_string()).collect();
    bail!(
        "no platform `{name}`: not a built-in name ({}) and no file at {}",
        BUILTIN.join(", "),
        places.join(", ")
    )
}

/// Resolves and loads a platform: (where it came from, the loaded platform).
fn load_platform(name: &str) -> Result<(String, PlatformPlan)> {
    match resolve(name)? {
        Source::Builtin(b) if b == "sim" => Ok((
            "built-in sim".into(),
            PlatformPlan::Sim {
                file: SimPlatformFile {
                    _platform: "sim".into(),
                    name: "Built-in simulator".into(),
                    world: None,
                    seed: 0,
                },
                world: Box::new(World::empty()),
            },
        )),
        Source::Builtin(b) => {
            let profile =
                Profile::builtin(&b).with_context(|| format!("no built-in profile `{b}`"))??;
            Ok((
                format!("built-in {b}"),
                PlatformPlan::Mavlink(Box::new(profile)),
            ))
        }
        Source::File(path) => {
            let shown = path.display().to_string();
            let text =
                std::fs::read_to_string(&path).with_context(|| format!("reading {shown}"))?;
            let value: toml::Value =
                toml::from_str(&text).with_context(|| format!("parsing {shown}"))?;
            match value.get("platform").and_then(|v| v.as_str()) {
                Some("mavlink") => {
                    let profile = Profile::parse(&text, &shown)?;
                    Ok((shown, PlatformPlan::Mavlink(Box::new(profile))))
                }
                Some("sim") => {
                    let file: SimPlatformFile =
                        toml::from_str(&text).with_context(|| format!("parsing {shown}"))?;
                    let world = match &file.world {
                        Some(p) => World::load(p).with_context(|| format!("{shown}: world"))?,
                        None => World::empty(),
                    };
                    Ok((
                        shown,
                        PlatformPlan::Sim {
                            file,
                            world: Box::new(world),
                        },
                    ))
                }
                other => bail!("{shown}: `platform` must be \"mavlink\" or \"sim\", got {other:?}"),
            }
        }
    }
}

/// `kestrel check-config`: the checks of `run` (with `--virtual-world`, of that file too), then
/// a short summary of what it would start.
pub fn check(config_path: &Path, virtual_world: Option<PathBuf>) -> Result<()> {
    let s = prepare(
        Some(config_path),
        &Overrides {
            virtual_world,
            ..Overrides::default()
        },
    )?;
    let shown = |p: &Path| {
        if p.as_os_str().is_empty() {
            ".".to_string()
        } else {
            p.display().to_string()
        }
    };
    println!("OK: {}", config_path.display());
    match s.vehicles.as_slice() {
        [one] if s.config.vehicles.is_empty() => {
            let (platform, link) = match &one.platform {
                PlatformPlan::Sim { file, .. } => {
                    (file.name.clone(), "none (simulator)".to_string())
                }
                PlatformPlan::Mavlink(p) => (p.name.clone(), one.connection.clone()),
            };
            println!("  drone id   {}", one.id);
            println!("  platform   {platform} ({})", one.platform_origin);
            println!("  mavlink    {link}");
        }
        fleet => {
            println!("  vehicles   {}", fleet.len());
            for v in fleet {
                println!("  {}", vehicle_summary(v));
            }
        }
    }
    if let Some(listen) = s.listen {
        println!("  api        {listen}");
    }
    println!(
        "  token      {}",
        if s.token.is_some() { "yes" } else { "no" }
    );
    println!("  log dir    {}", shown(&s.log_dir));
    println!("  state dir  {}", shown(&s.state_dir));
    if let Some(line) = crate::cli::fleet_key::summary(&s.config) {
        println!("  fleet      {line}");
    }
    for w in &s.warnings {
        println!("  warning    {w}");
    }
    if let Some(v) = &s.virtual_world {
        println!(
            "  virtual world  {} ({} obstacles)",
            v.path.display(),
            v.world.shapes().len()
        );
        for vehicle in &s.vehicles {
            println!(
                "  {}: sensor {}",
                vehicle.id,
                sensor_summary(&v.sensor(vehicle, &s.config))
            );
        }
    }
    Ok(())
}

/// A sensor in a few words: kind, range, rate.
fn sensor_summary(sensor: &SensorConfig) -> String {
    match *sensor {
        SensorConfig::Multiranger {
            range_max_m,
            rate_hz,
            ..
        } => format!("multiranger, {range_max_m} m, {rate_hz} Hz"),
        SensorConfig::Lidar360 {
            range_max_m,
            rate_hz,
            beams,
            ..
        } => format!("lidar360, {beams} beams, {range_max_m} m, {rate_hz} Hz"),
        SensorConfig::None => "none".into(),
    }
}

/// One line of `check-config` for a vehicle of the list: id, platform, link, system id, frame.
fn vehicle_summary(v: &VehiclePlan) -> String {
    let name = match &v.platform {
        PlatformPlan::Sim { file, .. } => file.name.as_str(),
        PlatformPlan::Mavlink(p) => p.name.as_str(),
    };
    let system = v
        .target_system
        .map_or_else(|| "first heard".to_string(), |s| s.to_string());
    let [x, y, z] = v.origin_enu_m;
    let mut line = format!(
        "{}: {name} ({}) over {}, system id {system}, origin [{x}, {y}, {z}] m",
        v.id, v.platform_origin, v.connection
    );
    if !v.forward.is_empty() {
        line.push_str(&format!(", forward {}", v.forward.join(" ")));
    }
    line
}
