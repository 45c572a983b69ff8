//! Range data sent over the API (there is no ROS): planar scans, four-beam multi-ranger
//! readings, depth-image rows and point clouds, each projected to one [`RangeScan`] at the
//! sensor's height, or the binary `KSC1` scan (`mapping::scan` documents its layout).
//!
//! In: a `POST /api/scans` body: JSON `{"drone": "drone_0", "scans": [ScanInput, ..]}` or
//! `KSC1` bytes. Out: the drone (body field or `?drone=`) and its scans, or every problem as a
//! JSON pointer and a message.

use super::error::ApiError;
use crate::mapping::scan::{self, CloudProjection, PinholeRow, RangeScan};
use crate::mission::ValidationError;
use nalgebra::Vector3;
use serde::Deserialize;
use std::f64::consts::PI;

/// Most scans in one request.
pub const MAX_SCANS_PER_REQUEST: usize = 16;

/// One sensor reading, in the world frame of the drone (`earth`, ENU) at the sensor's pose.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum ScanInput {
    /// A planar lidar scan (ROS `LaserScan` fields): `ranges_m[i]` at `angle_min_rad + i *
    /// angle_increment_rad` (FLU, CCW from the sensor's x axis); null = no return.
    Planar {
        #[schema(value_type = Vec<f64>)]
        origin_enu_m: [f64; 3],
        yaw_rad: f64,
        angle_min_rad: f64,
        angle_increment_rad: f64,
        ranges_m: Vec<Option<f64>>,
        range_min_m: f64,
        range_max_m: f64,
    },
    /// A four-beam multi-ranger: front, left, back, right (m); null = no return.
    Multiranger {
        #[schema(value_type = Vec<f64>)]
        origin_enu_m: [f64; 3],
        yaw_rad: f64,
        #[schema(value_type = Vec<Option<f64>>)]
        front_left_back_right_m: [Option<f64>; 4],
        range_min_m: f64,
        range_max_m: f64,
    },
    /// One row of a depth image (z-depth, m; 0 = no data), pinhole `fx_px`, `cx_px`.
    DepthRow {
        #[schema(value_type = Vec<f64>)]
        origin_enu_m: [f64; 3],
        yaw_rad: f64,
        depths_m: Vec<f32>,
        fx_px: f64,
        cx_px: f64,
        range_min_m: f64,
        range_max_m: f64,
    },
    /// A point cloud in the sensor's FLU frame; points with z in `[z_min_m, z_max_m]` are
    /// flattened into `beam_count` bins over 360 degrees (nearest point per bin).
    PointCloud {
        #[schema(value_type = Vec<f64>)]
        origin_enu_m: [f64; 3],
        yaw_rad: f64,
        #[schema(value_type = Vec<Vec<f64>>)]
        points_flu_m: Vec<[f64; 3]>,
        z_min_m: f64,
        z_max_m: f64,
        range_min_m: f64,
        range_max_m: f64,
        #[serde(default = "default_beams")]
        beam_count: usize,
    },
}

fn default_beams() -> usize {
    360
}

/// The JSON body of `POST /api/scans`.
#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct ScanBatch {
    /// The drone that sensed them; `?drone=` works too.
    #[serde(default)]
    pub drone: Option<String>,
    pub scans: Vec<ScanInput>,
}

impl ScanInput {
    /// The reading as a scan.
    pub fn to_scan(&self) -> RangeScan {
        let v = |o: &[f64; 3]| Vector3::new(o[0], o[1], o[2]);
        match self {
            ScanInput::Planar {
                origin_enu_m,
                yaw_rad,
                angle_min_rad,
                angle_increment_rad,
                ranges_m,
                range_min_m,
                range_max_m,
            } => {
                let ranges: Vec<f64> = ranges_m
                    .iter()
                    .map(|r| r.unwrap_or(f64::INFINITY))
                    .collect();
                scan::from_planar_lidar(
                    v(origin_enu_m),
                    *yaw_rad,
                    *angle_min_rad,
                    *angle_increment_rad,
                    &ranges,
                    *range_min_m,
                    *range_max_m,
                )
            }
            ScanInput::Multiranger {
                origin_enu_m,
                yaw_rad,
                front_left_back_right_m,
                range_min_m,
                range_max_m,
            } => scan::from_multiranger(
                v(origin_enu_m),
                *yaw_rad,
                *front_left_back_right_m,
                *range_min_m,
                *range_max_m,
            ),
            ScanInput::DepthRow {
                origin_enu_m,
                yaw_rad,
                depths_m,
                fx_px,
                cx_px,
                range_min_m,
                range_max_m,
            } => scan::from_depth_row(
                v(origin_enu_m),
                *yaw_rad,
                depths_m,
                PinholeRow {
                    fx_px: *fx_px,
                    cx_px: *cx_px,
                },
                *range_min_m,
                *range_max_m,
            ),
            ScanInput::PointCloud {
                origin_enu_m,
                yaw_rad,
                points_flu_m,
                z_min_m,
                z_max_m,
                range_min_m,
                range_max_m,
                beam_count,
            } => {
                let points: Vec<Vector3<f64>> = points_flu_m.iter().map(v).collect();
                let projection = CloudProjection {
                    z_min_m: *z_min_m,
                    z_max_m: *z_max_m,
                    angle_min_rad: -PI,
                    angle_max_rad: PI,
                    beam_count: *beam_count,
                    range_min_m: *range_min_m,
                    range_max_m: *range_max_m,
                };
                scan::from_point_cloud(v(origin_enu_m), *yaw_rad, &points, &projection)
            }
        }
    }

    /// Problems a scan's own validation cannot see (numbers it does not keep).
    fn check(&self) -> Result<(), String> {
        match self {
            ScanInput::Planar {
                angle_increment_rad,
                angle_min_rad,
                ..
            } if !(angle_increment_rad.is_finite() && angle_min_rad.is_finite()) => {
                Err("angles must be finite".into())
            }
            ScanInput::DepthRow { fx_px, cx_px, .. }
                if !(fx_px.is_finite() && *fx_px > 0.0 && cx_px.is_finite()) =>
            {
                Err("fx_px must be > 0 and cx_px finite (pixels)".into())
            }
            ScanInput::PointCloud {
                beam_count,
                z_min_m,
                z_max_m,
                ..
            } if !((1..=3600).contains(beam_count)
                && z_min_m.is_finite()
                && z_max_m.is_finite())
                || z_min_m > z_max_m =>
            {
                Err("beam_count must be 1..=3600 and z_min_m <= z_max_m".into())
            }
            _ => Ok(()),
        }
    }
}

/// Parses a `POST /api/scans` body into the drone and its scans.
pub fn body_scans(
    body: &[u8],
    binary: bool,
    query_drone: Option<String>,
) -> Result<(Option<String>, Vec<RangeScan>), ApiError> {
    let invalid = |pointer: String, message: String| {
        ApiError::Invalid(vec![ValidationError { pointer, message }])
    };
    if binary {
        let scan =
            RangeScan::decode_binary(body).map_err(|e| invalid(String::new(), e.to_string()))?;
        return Ok((query_drone, vec![scan]));
    }
    let batch: ScanBatch = super::body::parse(body)?;
    if batch.scans.len() > MAX_SCANS_PER_REQUEST {
        return Err(invalid(
            "/scans".into(),
            format!("at most {MAX_SCANS_PER_REQUEST} scans per request"),
        ));
    }
    let mut errors = Vec::new();
    let mut scans = Vec::with_capacity(batch.scans.len());
    for (i, input) in batch.scans.iter().enumerate() {
        let scan = input.to_scan();
        match input
            .check()
            .and_then(|()| scan.validate().map_err(|e| e.to_string()))
        {
            Ok(()) => scans.push(scan),
            Err(message) => errors.push(ValidationError {
                pointer: format!("/scans/{i}"),
                message,
            }),
        }
    }
    if !errors.is_empty() {
        return Err(ApiError::Invalid(errors));
    }
    Ok((batch.drone.or(query_drone), scans))
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    #[test]
    fn every_kind_becomes_a_scan_and_bad_ones_are_pointed_at() {
        let body = json!({ "drone": "drone_0", "scans": [
            { "kind": "planar", "origin_enu_m": [0, 0, 1], "yaw_rad": 0, "angle_min_rad": -1,
              "angle_increment_rad": 1, "ranges_m": [1.0, null, 2.0], "range_min_m": 0.1,
              "range_max_m": 5 },
            { "kind": "multiranger", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
              "front_left_back_right_m": [1.0, null, 3.0, 0.5], "range_min_m": 0.04,
              "range_max_m": 4 },
            { "kind": "depth_row", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
              "depths_m": [2.0, 0.0, 2.0], "fx_px": 2, "cx_px": 1, "range_min_m": 0.1,
              "range_max_m": 8 },
            { "kind": "point_cloud", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
              "points_flu_m": [[2, 0, 0], [0, 3, 5]], "z_min_m": -0.2, "z_max_m": 0.2,
              "range_min_m": 0.1, "range_max_m": 10, "beam_count": 4 }
        ]});
        let (drone, scans) = body_scans(body.to_string().as_bytes(), false, None).unwrap();
        assert_eq!(drone.as_deref(), Some("drone_0"));
        let beams: Vec<usize> = scans.iter().map(|s| s.beams.len()).collect();
        assert_eq!(beams, [3, 4, 2, 4]);
        let hits = |s: &RangeScan| s.beams.iter().filter(|b| b.range_m.is_some()).count();
        assert_eq!(hits(&scans[3]), 1, "the point above the band is left out");

        let bad = json!({ "scans": [
            { "kind": "planar", "origin_enu_m": [0, 0, 1], "yaw_rad": 0, "angle_min_rad": 0,
              "angle_increment_rad": 1, "ranges_m": [1.0], "range_min_m": 5, "range_max_m": 1 }
        ]});
        match body_scans(bad.to_string().as_bytes(), false, None) {
            Err(ApiError::Invalid(errors)) => assert_eq!(errors[0].pointer, "/scans/0"),
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_binary_scan_is_decoded() {
        let bytes = scan::encode_binary(
            Vector3::new(1.0, 2.0, 1.0),
            0.5,
            0.1,
            8.0,
            -1.0,
            0.5,
            &[1.0, 2.0, 3.0],
        );
        let (drone, scans) = body_scans(&bytes, true, Some("drone_1".into())).unwrap();
        assert_eq!(drone.as_deref(), Some("drone_1"));
        assert_eq!(scans[0].beams.len(), 3);
        assert!(body_scans(b"nope", true, None).is_err());
    }
}
