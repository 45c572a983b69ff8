//! Configuration: raw TOML → validated [`Config`]. Unknown keys are refused; every field's unit
//! is in its name. Sections: `[drone]`, `[estimator]`, `[controller]`, `[behaviors]`, `[sim]`,
//! `[mavlink]`.

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
        Self::parse(&text, &p)
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
