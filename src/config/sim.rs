//! The `[sim]` section: the built-in simulator's wind, turbulence, vehicle, sensor and
//! imperfections (a drifting position estimate, dropped range readings), checked with errors
//! that name the key and unit.

use super::bounds::Refusal;
use crate::types::{Imperfections, SensorConfig};
use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct SimSection {
    /// Steady wind (ENU, m/s).
    pub wind_enu_mps: [f64; 3],
    /// Random acceleration standard deviation per axis (m/s^2).
    pub turbulence_mps2: f64,
    /// Range sensor of every simulated drone (`kind` = `multiranger`, `lidar360` or `none`);
    /// replaces the world file's. Absent: the world file's, else the multi-ranger. Also the
    /// sensor `kestrel run --virtual-world` casts for vehicles that name none of their own.
    pub sensor: Option<SensorConfig>,
    /// Collision radius of a vehicle (m, 0.01 to 5): a drone whose centre comes closer than
    /// this to an obstacle of the simulator's world has crashed, of `--virtual-world`'s has a
    /// `virtual_collision`.
    pub vehicle_radius_m: f64,
    /// Speed at which each simulated drone's position estimate walks away from the truth while
    /// it flies, as an optical-flow deck's does (m/s, 0 to 1; 0 = off): its direction wanders
    /// (`sim::drift`), each drone's from the run's seed. The drone, its map and the flight
    /// log's `x`/`y` see the estimate; collisions and the log's `truth` are the truth.
    pub position_drift_mps: f64,
    /// Fraction of range readings that return nothing (0 to 1; 0 = off), drawn from the run's
    /// seed. The range noise is the sensor's `noise_std_m`.
    pub range_dropout: f64,
}

impl SimSection {
    /// Every number within its bounds; the refusal names the key (`sim.<field>`) and unit.
    pub fn validate(&self) -> Result<(), Refusal> {
        use super::bounds::{non_negative, within};
        for (axis, w) in ["x", "y", "z"].iter().zip(self.wind_enu_mps) {
            within(
                &format!("sim.wind_enu_mps.{axis}"),
                w,
                (-50.0, 50.0),
                false,
                "m/s",
            )?;
        }
        non_negative("sim.turbulence_mps2", self.turbulence_mps2, 20.0, "m/s^2")?;
        within(
            "sim.vehicle_radius_m",
            self.vehicle_radius_m,
            (0.01, 5.0),
            false,
            "m",
        )?;
        within(
            "sim.position_drift_mps",
            self.position_drift_mps,
            (0.0, 1.0),
            false,
            "m/s",
        )?;
        within(
            "sim.range_dropout",
            self.range_dropout,
            (0.0, 1.0),
            false,
            "(a fraction of the readings)",
        )?;
        if let Some(sensor) = &self.sensor {
            sensor
                .validate()
                .map_err(|e| ("sim.sensor".to_string(), e.to_string()))?;
        }
        Ok(())
    }

    /// The imperfections the simulator gives its vehicles.
    pub fn imperfections(&self) -> Imperfections {
        Imperfections {
            position_drift_mps: self.position_drift_mps,
            range_dropout: self.range_dropout,
        }
    }
}

impl Default for SimSection {
    fn default() -> Self {
        Self {
            wind_enu_mps: [0.0; 3],
            turbulence_mps2: 0.0,
            sensor: None,
            vehicle_radius_m: crate::types::DEFAULT_VEHICLE_RADIUS_M,
            position_drift_mps: 0.0,
            range_dropout: 0.0,
        }
    }
}
