//! Configuration: raw TOML → validated [`Config`]. Unknown keys are refused; every field's unit
//! is in its name. Sections: `[drone]`, `[estimator]`, `[controller]`, `[behaviors]`, `[sim]`,
//! `[mavlink]`, `[api]`, `[geofence]`, `[mission]`, `[map]`, `[safety]`, `[exploration]`,
//! `[fleet]`, `[ros2]`, and the `[[vehicle]]` list (several autopilots on one host; without it, `[drone]`
//! over `[mavlink]` is the one).

pub mod bounds;
pub mod ros2;
pub mod sim;
pub mod vehicles;

use crate::behavior::BehaviorConfig;
use crate::control::ControllerConfig;
use crate::estimator::geodetic::GeoPoint;
use crate::estimator::EstimatorPlugin;
use crate::exploration::online::settings::ExplorationSettings;
use crate::mission::executor::{ExecutorConfig, InFlightFailure, LinkRegained};
use crate::mission::Limits;
use crate::safety::{GeofenceSection, SafetyConfig};
use serde::{Deserialize, Serialize};
pub use sim::SimSection;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Config {
    pub drone: DroneSection,
    pub estimator: EstimatorSection,
    pub controller: ControllerConfig,
    pub behaviors: BehaviorConfig,
    pub sim: SimSection,
    pub mavlink: crate::platform::mavlink::config::MavlinkSection,
    pub api: ApiSection,
    pub geofence: GeofenceSection,
    pub mission: MissionSection,
    pub map: crate::mapping::config::MapSection,
    pub safety: SafetySection,
    /// `[exploration]`: the allocator's weights and which small unknown regions are worth a
    /// trip (every `explore` goal's defaults).
    pub exploration: ExplorationSettings,
    /// `[fleet]`: the bus to other Kestrels (off by default).
    pub fleet: crate::fleet_bus::config::FleetSection,
    /// `[ros2]`: the drones as ROS 2 topics over rmw_zenoh (off by default).
    pub ros2: ros2::Ros2Section,
    /// `[[vehicle]]` entries: several autopilots flown by `kestrel run`; empty = one vehicle,
    /// `[drone] id` over `[mavlink]`.
    #[serde(rename = "vehicle", skip_serializing_if = "Vec::is_empty")]
    pub vehicles: Vec<vehicles::VehicleSection>,
}

/// The safety stage every setpoint passes (the geofence itself is `[geofence]`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SafetySection {
    /// Least distance kept between two flying drones of the fleet (m, centre to centre).
    pub min_separation_m: f64,
    /// Drones brake to stop this much farther out than `min_separation_m` (m).
    pub separation_margin_m: f64,
    /// A target beyond the geofence is held this far inside it (m).
    pub geofence_margin_m: f64,
    /// How far the vehicle's height estimate may be off (m, 0..=20); absent: its platform
    /// profile's (PX4 and ArduPilot: a barometer's 1.5 m; the simulator's: none). Missions are
    /// refused below this plus [`crate::safety::GROUND_CLEARANCE_M`] above home. Set it low
    /// for a vehicle that holds its height on a downward rangefinder.
    pub height_error_m: Option<f64>,
}

impl Default for SafetySection {
    fn default() -> Self {
        Self {
            min_separation_m: 1.0,
            separation_margin_m: 0.2,
            geofence_margin_m: 0.5,
            height_error_m: None,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct DroneSection {
    /// Id used in missions (`target`), the API and logs.
    pub id: String,
    /// Control loop rate (Hz).
    pub control_rate_hz: f64,
    /// Geographic origin of the `earth` frame; absent = the autopilot's home (or a default in sim).
    pub geodetic_origin: Option<GeoPoint>,
    /// Where the flight logs go (default: the current directory). Each run writes a new log
    /// named by its start time.
    pub log_dir: Option<PathBuf>,
    /// Logs of one kind (`kestrel-run`, `kestrel-sim`, ...) kept in `log_dir`: at each start the
    /// oldest beyond this many are deleted (never the current one). 1 to 100000.
    pub log_keep: usize,
    /// Format of the flight logs: `jsonl` (JSON lines) or `mcap` (MCAP with Foxglove's
    /// channels); `--log-format` overrides it.
    pub log_format: crate::flightlog::LogFormat,
}

impl Default for DroneSection {
    fn default() -> Self {
        Self {
            id: "drone_0".into(),
            control_rate_hz: 100.0,
            geodetic_origin: None,
            log_dir: None,
            log_keep: crate::flightlog::files::DEFAULT_KEEP,
            log_format: crate::flightlog::LogFormat::Jsonl,
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorSection {
    pub plugin: Option<EstimatorPlugin>,
    /// `[estimator.map_correction]`: the estimate corrected against the map.
    pub map_correction: crate::estimator::map_correction::MapCorrectionSettings,
}

/// The HTTP/WebSocket ground-station API.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ApiSection {
    /// Address and port to serve on; `--listen` overrides it.
    pub listen: String,
    /// Bearer token for every command; `KESTREL_API_TOKEN` overrides it.
    pub token: Option<String>,
    /// File holding the token (created at install); used when `token` is absent.
    pub token_file: Option<PathBuf>,
    /// Browser origins allowed to call the API (CORS), e.g. `http://localhost:5173`.
    pub cors_origins: Vec<String>,
    /// Largest accepted request body (bytes).
    pub max_body_bytes: usize,
    /// Most WebSocket clients served at once.
    pub max_ws_clients: usize,
    /// Most TCP connections open at once, WebSockets included (1..=65 536). Further clients
    /// wait in the listen backlog until one closes, so the descriptors the state directory
    /// needs are never taken (systemd's `LimitNOFILE` is 8192).
    pub max_connections: usize,
    /// A request's head must arrive within this long (s, 0.1..=300) of the connection opening
    /// or of the previous answer: closes idle and slowly-typing (slowloris) connections.
    pub header_read_timeout_s: f64,
    /// A connection with nothing read or written for this long is closed (s, 1..=3600), whatever
    /// it waits for: a stalled body, an answer not read, a silent WebSocket. Keep it above
    /// `request_timeout_s`.
    pub idle_timeout_s: f64,
    /// A request not answered within this long gets `408 request_timeout` (s, 1..=600); work it
    /// started (a coverage plan) stops.
    pub request_timeout_s: f64,
}

impl Default for ApiSection {
    fn default() -> Self {
        Self {
            listen: "127.0.0.1:8080".into(),
            token: None,
            token_file: None,
            cors_origins: Vec::new(),
            max_body_bytes: 1 << 20,
            max_ws_clients: 256,
            max_connections: 512,
            header_read_timeout_s: 10.0,
            idle_timeout_s: 120.0,
            request_timeout_s: 30.0,
        }
    }
}

/// The mission executor.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MissionSection {
    /// When START switches from a running mission to another, hold this long before the new
    /// plan starts (s).
    pub switch_hold_s: f64,
    /// Loaded missions and their progress are kept here; `--state-dir` and
    /// `$STATE_DIRECTORY` override it. Absent = `./kestrel-state`.
    pub state_dir: Option<PathBuf>,
    /// When the link to the autopilot comes back after it was lost during an item: `land`
    /// (end the mission and land), `hold` (pause the mission and hover) or `resume` (start the
    /// interrupted item again). Meanwhile the autopilot's own failsafe flies the vehicle.
    pub on_link_regained: LinkRegained,
    /// How long a mission waits for a lost link before it fails (s).
    pub link_wait_s: f64,
    /// When a mission fails with the vehicle in the air: `hold` (hover where it is), `land`
    /// (land where it is) or `rtl` (return to the arming point and land). Not applied when a
    /// pilot took the vehicle (`pilot_takeover`: the mission pauses and Kestrel commands nothing).
    pub on_failure: InFlightFailure,
    /// `on_failure = "rtl"`: height above home to fly back at; a vehicle higher stays at its
    /// height (m, 0.5 to 120).
    pub rtl_height_m: f64,
    /// `on_failure = "rtl"`: speed to fly back at (m/s, above 0, at most 20).
    pub rtl_speed_mps: f64,
}

impl Default for MissionSection {
    fn default() -> Self {
        Self {
            switch_hold_s: 1.0,
            state_dir: None,
            on_link_regained: LinkRegained::default(),
            link_wait_s: 30.0,
            on_failure: InFlightFailure::default(),
            rtl_height_m: 3.0,
            rtl_speed_mps: 1.0,
        }
    }
}

/// The limits of the default config.
impl Default for Limits {
    fn default() -> Self {
        Config::default().mission_limits()
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ConfigError {
    #[error("cannot read config {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("config {path}: {message}")]
    Parse { path: String, message: String },
    #[error("config {path}: {field}: {message}")]
    Invalid {
        path: String,
        field: String,
        message: String,
    },
}

impl Config {
    /// The ids of the drones this config flies: the `[[vehicle]]` list's, or `[drone] id`.
    pub fn drone_ids(&self) -> Vec<String> {
        if self.vehicles.is_empty() {
            vec![self.drone.id.clone()]
        } else {
            self.vehicles.iter().map(|v| v.id.clone()).collect()
        }
    }

    /// What the safety stage enforces in flight.
    pub fn safety_config(&self) -> SafetyConfig {
        SafetyConfig {
            geofence: self.geofence.clone(),
            geofence_margin_m: self.safety.geofence_margin_m,
            min_separation_m: self.safety.min_separation_m,
            separation_margin_m: self.safety.separation_margin_m,
            limits: self.controller,
            braking_mps2: self.behaviors.max_acceleration_mps2,
            obstacle_keep_m: crate::safety::OBSTACLE_KEEP_M,
            height_error_m: self.safety.height_error_m,
        }
    }

    /// The mission executor's settings.
    pub fn executor_config(&self) -> ExecutorConfig {
        ExecutorConfig {
            switch_hold: std::time::Duration::from_secs_f64(self.mission.switch_hold_s),
            on_link_regained: self.mission.on_link_regained,
            link_wait: std::time::Duration::from_secs_f64(self.mission.link_wait_s),
            on_failure: self.mission.on_failure,
            rtl_height_m: self.mission.rtl_height_m,
            rtl_speed_mps: self.mission.rtl_speed_mps,
        }
    }

    /// What missions are validated against: the vehicle's speed limit and the geofence.
    pub fn mission_limits(&self) -> Limits {
        Limits {
            max_speed_mps: self.controller.max_horizontal_speed_mps,
            geofence: self.geofence.clone(),
            max_items: 1000,
            max_waypoints: 10_000,
        }
    }

    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: p.clone(),
            source,
        })?;
        let mut config = Self::parse(&text, &p)?;
        let dir = path.parent().unwrap_or(Path::new("."));
        config
            .map
            .load_files(dir)
            .map_err(|e| ConfigError::Invalid {
                path: p,
                field: "map".into(),
                message: e.to_string(),
            })?;
        Ok(config)
    }

    pub fn parse(text: &str, origin: &str) -> Result<Self, ConfigError> {
        let config: Config = toml::from_str(text).map_err(|e| ConfigError::Parse {
            path: origin.to_string(),
            message: e.to_string(),
        })?;
        config.check(origin)?;
        Ok(config)
    }

    /// The checks of [`Config::parse`], for a config changed after it was read (command-line
    /// settings); `origin` says where the values came from.
    pub fn check(&self, origin: &str) -> Result<(), ConfigError> {
        self.validate()
            .map_err(|(field, message)| ConfigError::Invalid {
                path: origin.to_string(),
                field,
                message,
            })
    }

    /// Every number within its bounds, every name and address well formed.
    fn validate(&self) -> Result<(), (String, String)> {
        use bounds::{count, within};
        if self.drone.id.is_empty() {
            return Err(("drone.id".into(), "must not be empty".into()));
        }
        within(
            "drone.control_rate_hz",
            self.drone.control_rate_hz,
            (1.0, 1000.0),
            false,
            "Hz",
        )?;
        count("drone.log_keep", self.drone.log_keep, (1, 100_000))?;
        if let Some(o) = &self.drone.geodetic_origin {
            o.validate()
                .map_err(|e| ("drone.geodetic_origin".to_string(), e.to_string()))?;
        }
        self.estimator
            .map_correction
            .check()
            .map_err(|(field, e)| (format!("estimator.map_correction.{field}"), e))?;
        self.validate_controller()?;
        vehicles::validate(&self.vehicles, &self.mavlink)?;
        self.fleet.validate(&self.drone_ids())?;
        self.ros2.validate(&self.drone_ids())?;
        self.validate_behaviors()?;
        self.sim.validate()?;
        self.mavlink.validate()?;
        self.validate_geofence()?;
        self.validate_mission()?;
        self.validate_api()?;
        self.map.validate()?;
        self.validate_safety()?;
        self.exploration
            .validate()
            .map_err(|e| (format!("exploration.{}", e.field), e.to_string()))?;
        Ok(())
    }

    /// `[behaviors]`: thresholds, limits and timeouts.
    fn validate_behaviors(&self) -> Result<(), (String, String)> {
        use bounds::positive;
        let b = &self.behaviors;
        positive("behaviors.goal_threshold_m", b.goal_threshold_m, 10.0, "m")?;
        positive(
            "behaviors.waypoint_threshold_m",
            b.waypoint_threshold_m,
            10.0,
            "m",
        )?;
        positive(
            "behaviors.takeoff_threshold_m",
            b.takeoff_threshold_m,
            5.0,
            "m",
        )?;
        positive(
            "behaviors.max_acceleration_mps2",
            b.max_acceleration_mps2,
            20.0,
            "m/s^2",
        )?;
        positive(
            "behaviors.no_progress_timeout_s",
            b.no_progress_timeout_s,
            3600.0,
            "s",
        )?;
        positive("behaviors.arm_timeout_s", b.arm_timeout_s, 600.0, "s")?;
        positive("behaviors.ready_timeout_s", b.ready_timeout_s, 3600.0, "s")?;
        positive("behaviors.hold_speed_mps", b.hold_speed_mps, 20.0, "m/s")?;
        Ok(())
    }

    /// `[mission]`: the hold between plans and the return home.
    fn validate_mission(&self) -> Result<(), (String, String)> {
        use bounds::{non_negative, positive, within};
        non_negative(
            "mission.switch_hold_s",
            self.mission.switch_hold_s,
            60.0,
            "s",
        )?;
        within(
            "mission.rtl_height_m",
            self.mission.rtl_height_m,
            (0.5, 120.0),
            false,
            "m",
        )?;
        positive(
            "mission.rtl_speed_mps",
            self.mission.rtl_speed_mps,
            20.0,
            "m/s",
        )?;
        Ok(())
    }

    /// `[api]`: the address and the bounds of what clients may send and hold.
    fn validate_api(&self) -> Result<(), (String, String)> {
        use bounds::{count, within};
        if self.api.listen.parse::<std::net::SocketAddr>().is_err() {
            return Err((
                "api.listen".into(),
                format!("must be ADDR:PORT, got `{}`", self.api.listen),
            ));
        }
        count(
            "api.max_body_bytes",
            self.api.max_body_bytes,
            (1024, 64 << 20),
        )?;
        count("api.max_ws_clients", self.api.max_ws_clients, (1, 10_000))?;
        count("api.max_connections", self.api.max_connections, (1, 65_536))?;
        within(
            "api.header_read_timeout_s",
            self.api.header_read_timeout_s,
            (0.1, 300.0),
            false,
            "s",
        )?;
        within(
            "api.idle_timeout_s",
            self.api.idle_timeout_s,
            (1.0, 3600.0),
            false,
            "s",
        )?;
        within(
            "api.request_timeout_s",
            self.api.request_timeout_s,
            (1.0, 600.0),
            false,
            "s",
        )?;
        Ok(())
    }

    /// `[safety]`: separation and geofence margins.
    fn validate_safety(&self) -> Result<(), (String, String)> {
        use bounds::non_negative;
        non_negative(
            "safety.min_separation_m",
            self.safety.min_separation_m,
            100.0,
            "m",
        )?;
        non_negative(
            "safety.separation_margin_m",
            self.safety.separation_margin_m,
            100.0,
            "m",
        )?;
        non_negative(
            "safety.geofence_margin_m",
            self.safety.geofence_margin_m,
            100.0,
            "m",
        )?;
        if let Some(e) = self.safety.height_error_m {
            non_negative("safety.height_error_m", e, 20.0, "m")?;
        }
        Ok(())
    }

    fn validate_controller(&self) -> Result<(), (String, String)> {
        use bounds::{non_negative, non_negative3, positive};
        let c = &self.controller;
        positive(
            "controller.max_horizontal_speed_mps",
            c.max_horizontal_speed_mps,
            50.0,
            "m/s",
        )?;
        positive(
            "controller.max_up_speed_mps",
            c.max_up_speed_mps,
            20.0,
            "m/s",
        )?;
        positive(
            "controller.max_down_speed_mps",
            c.max_down_speed_mps,
            20.0,
            "m/s",
        )?;
        positive(
            "controller.max_yaw_rate_radps",
            c.max_yaw_rate_radps,
            10.0,
            "rad/s",
        )?;
        if let Some(lag) = c.velocity_lag_s {
            non_negative("controller.velocity_lag_s", lag, 5.0, "s")?;
        }
        if let Some(share) = c.velocity_overshoot {
            non_negative("controller.velocity_overshoot", share, 1.0, "")?;
        }
        if let Some(share) = c.yaw_rate_overshoot {
            non_negative("controller.yaw_rate_overshoot", share, 1.0, "")?;
        }
        for (name, g) in [
            ("position", &c.position),
            ("trajectory", &c.trajectory),
            ("yaw", &c.yaw),
        ] {
            let key = |f: &str| format!("controller.{name}.{f}");
            non_negative3(&key("kp"), &g.kp.into(), 1000.0, "")?;
            non_negative3(&key("ki"), &g.ki.into(), 1000.0, "")?;
            non_negative3(&key("kd"), &g.kd.into(), 1000.0, "")?;
            non_negative3(&key("integral_limit"), &g.integral_limit.into(), 1e6, "")?;
            non_negative3(&key("integral_zone"), &g.integral_zone.into(), 1e6, "")?;
            non_negative(&key("derivative_alpha"), g.derivative_alpha, 1.0, "")?;
        }
        Ok(())
    }

    fn validate_geofence(&self) -> Result<(), (String, String)> {
        use bounds::{count, positive, within};
        let g = &self.geofence;
        positive("geofence.max_altitude_m", g.max_altitude_m, 10_000.0, "m")?;
        within(
            "geofence.min_altitude_m",
            g.min_altitude_m,
            (-10_000.0, g.max_altitude_m),
            false,
            "m",
        )?;
        if g.min_altitude_m >= g.max_altitude_m {
            return Err((
                "geofence.min_altitude_m".into(),
                format!("must be below max_altitude_m, got {}", g.min_altitude_m),
            ));
        }
        if let Some(r) = g.radius_m {
            positive("geofence.radius_m", r, 1e6, "m")?;
        }
        if let Some(p) = &g.polygon_enu_m {
            count("geofence.polygon_enu_m (vertices)", p.len(), (3, 1000))?;
            for v in p.iter().flatten() {
                within("geofence.polygon_enu_m", *v, (-1e7, 1e7), false, "m")?;
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn empty_config_gives_defaults() {
        let c = Config::parse("", "test").unwrap();
        assert_eq!(c.drone.id, "drone_0");
    }

    #[test]
    fn sim_sensor_is_chosen_by_kind() {
        use crate::types::SensorConfig;
        let c = Config::parse("[sim.sensor]\nkind = \"lidar360\"\n", "test").unwrap();
        assert_eq!(c.sim.sensor, Some(SensorConfig::lidar()));
    }

    #[test]
    fn sim_imperfections_are_off_unless_set() {
        use crate::types::Imperfections;
        assert_eq!(
            Config::default().sim.imperfections(),
            Imperfections::default()
        );
        let c = Config::parse(
            "[sim]\nposition_drift_mps = 0.02\nrange_dropout = 0.05\n",
            "test",
        )
        .unwrap();
        let i = c.sim.imperfections();
        assert_eq!((i.position_drift_mps, i.range_dropout), (0.02, 0.05));
        let mut c = Config::default();
        c.sim.range_dropout = -0.01;
        let e = c.check("the command line").unwrap_err().to_string();
        assert!(
            e.contains("the command line") && e.contains("sim.range_dropout"),
            "{e}"
        );
    }

    #[test]
    fn nan_negative_and_absurd_numbers_are_refused_with_the_key() {
        for (text, key) in [
            (
                "[behaviors]\narm_timeout_s = -1.0\n",
                "behaviors.arm_timeout_s",
            ),
            (
                "[behaviors]\nready_timeout_s = nan\n",
                "behaviors.ready_timeout_s",
            ),
            (
                "[behaviors]\nhold_speed_mps = -2.0\n",
                "behaviors.hold_speed_mps",
            ),
            (
                "[controller]\nmax_horizontal_speed_mps = inf\n",
                "controller.max_horizontal_speed_mps",
            ),
            (
                "[controller.position]\nkp = [1.0, -1.0, 1.0]\nki = [0.0, 0.0, 0.0]\n\
                 kd = [0.0, 0.0, 0.0]\nintegral_limit = [0.0, 0.0, 0.0]\nderivative_alpha = 1.0\n",
                "controller.position.kp",
            ),
            ("[drone]\ncontrol_rate_hz = 1e9\n", "drone.control_rate_hz"),
            ("[sim]\nturbulence_mps2 = -0.5\n", "sim.turbulence_mps2"),
            (
                "[sim]\nposition_drift_mps = 2.0\n",
                "sim.position_drift_mps",
            ),
            (
                "[sim]\nposition_drift_mps = nan\n",
                "sim.position_drift_mps",
            ),
            ("[sim]\nrange_dropout = 1.5\n", "sim.range_dropout"),
            (
                "[sim]\nwind_enu_mps = [0.0, 1e6, 0.0]\n",
                "sim.wind_enu_mps.y",
            ),
            ("[mission]\nswitch_hold_s = nan\n", "mission.switch_hold_s"),
            ("[mission]\nrtl_height_m = 0.0\n", "mission.rtl_height_m"),
            ("[mission]\nrtl_speed_mps = -1.0\n", "mission.rtl_speed_mps"),
            ("[geofence]\nradius_m = -5.0\n", "geofence.radius_m"),
            ("[api]\nmax_ws_clients = 0\n", "api.max_ws_clients"),
            ("[api]\nmax_connections = 0\n", "api.max_connections"),
            (
                "[api]\nheader_read_timeout_s = 0.0\n",
                "api.header_read_timeout_s",
            ),
            ("[api]\nidle_timeout_s = inf\n", "api.idle_timeout_s"),
            (
                "[exploration]\nedge_radius_m = 0.0\n",
                "exploration.edge_radius_m",
            ),
        ] {
            let e = Config::parse(text, "test").unwrap_err().to_string();
            assert!(e.contains(key), "{text}: {e}");
        }
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused() {
        let e = Config::parse("[drone]\nid = \"d\"\nspeed = 3\n", "test").unwrap_err();
        assert!(e.to_string().contains("speed"), "{e}");
        let e = Config::parse("[controller]\nmax_up_speed_mps = -1.0\n", "test").unwrap_err();
        assert!(e.to_string().contains("controller.max_up_speed_mps"), "{e}");
    }

    #[test]
    fn the_exploration_section_sets_the_weights_and_refuses_unknown_ones() {
        let c = Config::parse("[exploration]\nedge_bonus_m = 0.0\n", "test").unwrap();
        assert_eq!(c.exploration.edge_bonus_m, 0.0);
        assert_eq!(c.exploration.others_penalty_m, 12.0);
        let e = Config::parse("[exploration]\nedge_bonus = 0.0\n", "test").unwrap_err();
        assert!(e.to_string().contains("edge_bonus"), "{e}");
        let e = Config::parse("[exploration]\nkeep_bonus_m = 99.0\n", "test").unwrap_err();
        assert!(e.to_string().contains("0..=50 m"), "the unit: {e}");
    }

    #[test]
    fn on_failure_is_one_of_hold_land_rtl() {
        let c = Config::parse("[mission]\non_failure = \"rtl\"\n", "test").unwrap();
        assert_eq!(c.executor_config().on_failure, InFlightFailure::Rtl);
        assert_eq!(
            Config::default().executor_config().on_failure,
            InFlightFailure::Hold
        );
        let e = Config::parse("[mission]\non_failure = \"crash\"\n", "test").unwrap_err();
        assert!(e.to_string().contains("on_failure"), "{e}");
    }
}
