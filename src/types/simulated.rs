//! What the config chooses for a simulated vehicle (and for a real one flown through
//! `--virtual-world`): which range sensor it carries, and its collision radius when nothing
//! says. The simulator casts the sensor (`sim::sensors`); the config, world files and
//! `--sensor` only name it.

use serde::{Deserialize, Serialize};

/// Collision radius of a vehicle when nothing sets one (m): `[sim] vehicle_radius_m`'s default
/// and the simulator's multirotor's.
pub const DEFAULT_VEHICLE_RADIUS_M: f64 = 0.15;

/// What a real drone has that a perfect simulation would not: a position estimate that drifts
/// away from the truth and range readings that go missing (`[sim] position_drift_mps`,
/// `[sim] range_dropout`; the range noise is the sensor's `noise_std_m`). Both off by default.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Imperfections {
    /// Speed at which the position estimate walks away from the truth (m/s, horizontal; 0 = none).
    pub position_drift_mps: f64,
    /// Fraction of beam readings that return nothing (0 to 1).
    pub range_dropout: f64,
}

/// Bounds of a sensor's settings: most lidar beams, longest range (m), fastest rate (Hz).
const MAX_BEAMS: u32 = 3600;
const MAX_RANGE_M: f64 = 1000.0;
const MAX_RATE_HZ: f64 = 1000.0;

/// A simulated sensor's setting out of its range: the field, its bounds and unit, the value.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SensorError {
    #[error("sensor.beams must be 1 to {MAX_BEAMS}, got {0}")]
    Beams(u32),
    #[error("sensor.range_max_m must be above 0 and at most {MAX_RANGE_M} m, got {0}")]
    Range(f64),
    #[error("sensor.rate_hz must be above 0 and at most {MAX_RATE_HZ} Hz, got {0}")]
    Rate(f64),
    #[error("sensor.noise_std_m must be 0 or more and at most {MAX_RANGE_M} m, got {0}")]
    Noise(f64),
}

/// Which range sensor the simulated drones carry. Absent fields take the defaults of the
/// kind, so `{"kind": "lidar360"}` is a complete sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind", deny_unknown_fields)]
pub enum SensorConfig {
    /// Crazyflie multi-ranger deck: four beams front/left/back/right (defaults 4 m, 20 Hz,
    /// 1 cm noise).
    Multiranger {
        #[serde(default = "multiranger_range")]
        range_max_m: f64,
        #[serde(default = "multiranger_rate")]
        rate_hz: f64,
        #[serde(default = "default_noise")]
        noise_std_m: f64,
    },
    /// Planar lidar, beams evenly over 360 deg (defaults 360 beams, 10 m, 10 Hz, 1 cm noise).
    Lidar360 {
        #[serde(default = "lidar_range")]
        range_max_m: f64,
        #[serde(default = "lidar_rate")]
        rate_hz: f64,
        #[serde(default = "default_noise")]
        noise_std_m: f64,
        #[serde(default = "lidar_beams")]
        beams: u32,
    },
    None,
}

fn multiranger_range() -> f64 {
    4.0
}
fn multiranger_rate() -> f64 {
    20.0
}
fn lidar_range() -> f64 {
    10.0
}
fn lidar_rate() -> f64 {
    10.0
}
fn lidar_beams() -> u32 {
    360
}
fn default_noise() -> f64 {
    0.01
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self::multiranger()
    }
}

impl SensorConfig {
    pub fn multiranger() -> Self {
        Self::Multiranger {
            range_max_m: multiranger_range(),
            rate_hz: multiranger_rate(),
            noise_std_m: default_noise(),
        }
    }

    pub fn lidar() -> Self {
        Self::Lidar360 {
            range_max_m: lidar_range(),
            rate_hz: lidar_rate(),
            noise_std_m: default_noise(),
            beams: lidar_beams(),
        }
    }

    /// By name, as on the command line: `multiranger`, `lidar` (or `lidar360`), `none`.
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "multiranger" => Some(Self::multiranger()),
            "lidar" | "lidar360" => Some(Self::lidar()),
            "none" => Some(Self::None),
            _ => None,
        }
    }

    /// Checks ranges, rates and the beam count (each bounded: a sensor is cast every time it is
    /// due, on the control loop); the message names the field and unit.
    pub fn validate(&self) -> Result<(), SensorError> {
        let (range, rate, noise) = match *self {
            Self::Multiranger {
                range_max_m,
                rate_hz,
                noise_std_m,
            } => (range_max_m, rate_hz, noise_std_m),
            Self::Lidar360 {
                range_max_m,
                rate_hz,
                noise_std_m,
                beams,
            } => {
                if !(1..=MAX_BEAMS).contains(&beams) {
                    return Err(SensorError::Beams(beams));
                }
                (range_max_m, rate_hz, noise_std_m)
            }
            Self::None => return Ok(()),
        };
        if !(range > 0.0 && range <= MAX_RANGE_M) {
            return Err(SensorError::Range(range));
        }
        if !(rate > 0.0 && rate <= MAX_RATE_HZ) {
            return Err(SensorError::Rate(rate));
        }
        if !(0.0..=MAX_RANGE_M).contains(&noise) {
            return Err(SensorError::Noise(noise));
        }
        Ok(())
    }
}
