//! A geographic point (WGS84 degrees, metres); conversions are in `estimator::geodetic`.

use serde::{Deserialize, Serialize};

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeoPoint {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

#[derive(Debug, Clone, Copy, thiserror::Error, PartialEq)]
pub enum GeoError {
    #[error("latitude {0} deg is outside -90..90")]
    Latitude(f64),
    #[error("longitude {0} deg is outside -180..180")]
    Longitude(f64),
}

impl GeoPoint {
    pub fn validate(&self) -> Result<(), GeoError> {
        if !(-90.0..=90.0).contains(&self.lat_deg) {
            return Err(GeoError::Latitude(self.lat_deg));
        }
        if !(-180.0..=180.0).contains(&self.lon_deg) {
            return Err(GeoError::Longitude(self.lon_deg));
        }
        Ok(())
    }
}
