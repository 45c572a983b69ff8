//! WGS84 geodetic origin and conversion to and from the local ENU `earth` frame.
//!
//! In: latitude/longitude in degrees, altitude in metres above the WGS84 ellipsoid (AMSL is
//! accepted as an approximation where the autopilot gives AMSL). Out: ENU metres from the origin.

use crate::types::Vec3;
use map_3d::Ellipsoid;
use serde::{Deserialize, Serialize};

pub use crate::types::{GeoError, GeoPoint};

/// The geographic position of the `earth` frame's origin.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct GeodeticOrigin(pub GeoPoint);

impl Default for GeodeticOrigin {
    /// Madrid, as Aerostack2's simulator world; real vehicles set it from config or GPS home.
    fn default() -> Self {
        Self(GeoPoint {
            lat_deg: 40.4405,
            lon_deg: -3.68982,
            alt_m: 100.0,
        })
    }
}

impl GeodeticOrigin {
    pub fn to_enu(&self, p: &GeoPoint) -> Result<Vec3, GeoError> {
        p.validate()?;
        let o = self.0;
        let (e, n, u) = map_3d::geodetic2enu(
            p.lat_deg.to_radians(),
            p.lon_deg.to_radians(),
            p.alt_m,
            o.lat_deg.to_radians(),
            o.lon_deg.to_radians(),
            o.alt_m,
            Ellipsoid::WGS84,
        );
        Ok(Vec3::new(e, n, u))
    }

    pub fn to_geo(&self, enu_m: &Vec3) -> GeoPoint {
        let o = self.0;
        let (lat, lon, alt) = map_3d::enu2geodetic(
            enu_m.x,
            enu_m.y,
            enu_m.z,
            o.lat_deg.to_radians(),
            o.lon_deg.to_radians(),
            o.alt_m,
            Ellipsoid::WGS84,
        );
        GeoPoint {
            lat_deg: lat.to_degrees(),
            lon_deg: lon.to_degrees(),
            alt_m: alt,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn one_arc_second_north_is_about_31_metres() {
        let origin = GeodeticOrigin(GeoPoint {
            lat_deg: 47.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        });
        let p = GeoPoint {
            lat_deg: 47.0 + 1.0 / 3600.0,
            lon_deg: 8.0,
            alt_m: 400.0,
        };
        let enu = origin.to_enu(&p).unwrap();
        assert!(enu.x.abs() < 1e-3);
        assert!((enu.y - 30.87).abs() < 0.05, "{enu}");
        assert!(enu.z.abs() < 0.01);
    }

    #[test]
    fn enu_geo_round_trip_is_millimetre_exact() {
        let origin = GeodeticOrigin::default();
        let enu = Vec3::new(123.4, -56.7, 8.9);
        let back = origin.to_enu(&origin.to_geo(&enu)).unwrap();
        assert!((back - enu).norm() < 1e-3);
    }

    #[test]
    fn out_of_range_latitude_is_refused() {
        let origin = GeodeticOrigin::default();
        let bad = GeoPoint {
            lat_deg: 91.0,
            lon_deg: 0.0,
            alt_m: 0.0,
        };
        assert_eq!(origin.to_enu(&bad), Err(GeoError::Latitude(91.0)));
    }
}
