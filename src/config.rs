//! Configuration: raw TOML → validated [`Config`]. Unknown keys are refused; every field's unit
//! is in its name. Sections: `[drone]`, `[estimator]`, `[controller]`, `[behaviors]`, `[sim]`,
//! `[mavlink]`, `[api]`, `[geofence]`, `[mission]`, `[map]`.

use crate::behavior::BehaviorConfig;
use crate::control::ControllerConfig;
use crate::estimator::geodetic::GeoPoint;
use crate::estimator::EstimatorPlugin;
use crate::sim::world::SensorConfig;
use serde::{Deserialize, Serialize};
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
    /// Where the flight logs go.
    pub log_dir: Option<PathBuf>,
}

impl Default for DroneSection {
    fn default() -> Self {
        Self {
            id: "drone_0".into(),
            control_rate_hz: 100.0,
            geodetic_origin: None,
            log_dir: None,
        }
    }
}

#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct EstimatorSection {
    pub plugin: Option<EstimatorPlugin>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSection {
    /// Steady wind (ENU, m/s).
    pub wind_enu_mps: [f64; 3],
    /// Random acceleration standard deviation per axis (m/s^2).
    pub turbulence_mps2: f64,
    /// Range sensor of every simulated drone (`kind` = `multiranger`, `lidar360` or `none`);
    /// replaces the world file's. Absent: the world file's, else the multi-ranger.
    pub sensor: Option<SensorConfig>,
}

impl Default for SimSection {
    fn default() -> Self {
        Self {
            wind_enu_mps: [0.0; 3],
            turbulence_mps2: 0.0,
            sensor: None,
        }
    }
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
        }
    }
}

/// Where missions may send the vehicle. Altitudes are relative to home (the arming point, or
/// the vehicle's position before the first arming).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeofenceSection {
    /// Ceiling above home (m).
    pub max_altitude_m: f64,
    /// Floor relative to home (m); negative allows goals below the home altitude.
    pub min_altitude_m: f64,
    /// Largest horizontal distance from home (m); absent = no radius limit.
    pub radius_m: Option<f64>,
    /// Polygon [[x, y], ..] (m, ENU `earth`) the vehicle must stay inside; absent = none.
    pub polygon_enu_m: Option<Vec<[f64; 2]>>,
}

impl Default for GeofenceSection {
    fn default() -> Self {
        Self {
            max_altitude_m: 120.0,
            min_altitude_m: 0.0,
            radius_m: Some(1000.0),
            polygon_enu_m: None,
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
}

impl Default for MissionSection {
    fn default() -> Self {
        Self {
            switch_hold_s: 1.0,
            state_dir: None,
        }
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
        config
            .validate()
            .map_err(|(field, message)| ConfigError::Invalid {
                path: origin.to_string(),
                field,
                message,
            })?;
        Ok(config)
    }

    fn validate(&self) -> Result<(), (String, String)> {
        let positive = |field: &str, v: f64| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err((field.to_string(), format!("must be > 0, got {v}")))
            }
        };
        positive("drone.control_rate_hz", self.drone.control_rate_hz)?;
        let c = &self.controller;
        positive(
            "controller.max_horizontal_speed_mps",
            c.max_horizontal_speed_mps,
        )?;
        positive("controller.max_up_speed_mps", c.max_up_speed_mps)?;
        positive("controller.max_down_speed_mps", c.max_down_speed_mps)?;
        positive("controller.max_yaw_rate_radps", c.max_yaw_rate_radps)?;
        let b = &self.behaviors;
        positive("behaviors.goal_threshold_m", b.goal_threshold_m)?;
        positive("behaviors.max_acceleration_mps2", b.max_acceleration_mps2)?;
        if let Some(o) = &self.drone.geodetic_origin {
            o.validate()
                .map_err(|e| ("drone.geodetic_origin".to_string(), e.to_string()))?;
        }
        self.mavlink.validate()?;
        if self.drone.id.is_empty() {
            return Err(("drone.id".into(), "must not be empty".into()));
        }
        let g = &self.geofence;
        positive("geofence.max_altitude_m", g.max_altitude_m)?;
        if !(g.min_altitude_m.is_finite() && g.min_altitude_m < g.max_altitude_m) {
            return Err((
                "geofence.min_altitude_m".into(),
                format!("must be below max_altitude_m, got {}", g.min_altitude_m),
            ));
        }
        if let Some(r) = g.radius_m {
            positive("geofence.radius_m", r)?;
        }
        if let Some(p) = &g.polygon_enu_m {
            if p.len() < 3 || p.iter().flatten().any(|v| !v.is_finite()) {
                return Err((
                    "geofence.polygon_enu_m".into(),
                    "needs at least 3 finite [x, y] vertices".into(),
                ));
            }
        }
        if !(self.mission.switch_hold_s.is_finite() && self.mission.switch_hold_s >= 0.0) {
            return Err(("mission.switch_hold_s".into(), "must be >= 0".into()));
        }
        if self.api.listen.parse::<std::net::SocketAddr>().is_err() {
            return Err((
                "api.listen".into(),
                format!("must be ADDR:PORT, got `{}`", self.api.listen),
            ));
        }
        self.map.validate()?;
        if self.api.max_body_bytes < 1024 {
            return Err(("api.max_body_bytes".into(), "must be >= 1024".into()));
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
        let c = Config::parse("[sim.sensor]\nkind = \"lidar360\"\n", "test").unwrap();
        assert_eq!(c.sim.sensor, Some(SensorConfig::lidar()));
    }

    #[test]
    fn unknown_keys_and_bad_values_are_refused() {
        let e = Config::parse("[drone]\nid = \"d\"\nspeed = 3\n", "test").unwrap_err();
        assert!(e.to_string().contains("speed"), "{e}");
        let e = Config::parse("[controller]\nmax_up_speed_mps = -1.0\n", "test").unwrap_err();
        assert!(e.to_string().contains("controller.max_up_speed_mps"), "{e}");
    }
}
