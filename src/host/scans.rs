//! Range data from outside (the API; there is no ROS): planar scans, four-beam multi-ranger
//! readings, depth-image rows and point clouds, each projected to one [`RangeScan`] at the
//! sensor's height, or the binary `KSC1` scan (`mapping::scan` documents its layout).
//!
//! In: a [`ScanBatch`] or `KSC1` bytes. Out: the scans, or every problem as a JSON pointer and a
//! message. Every size is checked before anything is built with it.

use crate::mapping::scan::{self, CloudProjection, PinholeRow, RangeScan};
/// The `KSC1` encoder and the most beams of a scan, for clients of the API (and its tests).
pub use crate::mapping::scan::{encode_binary, MAX_BEAMS};
use crate::mapping::MapError;
use crate::mission::ValidationError;
use nalgebra::Vector3;
use serde::Deserialize;
use std::f64::consts::PI;

/// Most scans in one request.
pub const MAX_SCANS_PER_REQUEST: usize = 16;
/// Most bins a point cloud is flattened into (a tenth of a degree each).
pub const MAX_CLOUD_BINS: usize = 3600;
/// Most points in one point cloud.
pub const MAX_CLOUD_POINTS: usize = 100_000;

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

    /// Problems a scan's own validation cannot see (numbers it does not keep) and every size,
    /// before anything is built with it: `Err((field, message))`.
    fn check(&self) -> Result<(), (&'static str, String)> {
        let finite = |field: &'static str, v: f64, unit: &str| {
            if v.is_finite() {
                Ok(())
            } else {
                Err((
                    field,
                    format!("{field} is {v}, not a finite number ({unit})"),
                ))
            }
        };
        let at_most = |field: &'static str, n: usize, max: usize, what: &str| {
            if n <= max {
                Ok(())
            } else {
                Err((field, format!("{field} has {n} {what}, at most {max}")))
            }
        };
        match self {
            ScanInput::Planar {
                angle_increment_rad,
                angle_min_rad,
                ranges_m,
                ..
            } => {
                finite("angle_min_rad", *angle_min_rad, "rad")?;
                finite("angle_increment_rad", *angle_increment_rad, "rad")?;
                at_most("ranges_m", ranges_m.len(), scan::MAX_BEAMS, "ranges")
            }
            ScanInput::DepthRow {
                fx_px,
                cx_px,
                depths_m,
                ..
            } => {
                if !(fx_px.is_finite() && *fx_px > 0.0) {
                    return Err(("fx_px", format!("fx_px is {fx_px}, must be > 0 (pixels)")));
                }
                finite("cx_px", *cx_px, "pixels")?;
                at_most("depths_m", depths_m.len(), scan::MAX_BEAMS, "columns")
            }
            ScanInput::PointCloud {
                beam_count,
                z_min_m,
                z_max_m,
                points_flu_m,
                ..
            } => {
                if !(1..=MAX_CLOUD_BINS).contains(beam_count) {
                    return Err((
                        "beam_count",
                        format!(
                            "beam_count is {beam_count}, must be 1..={MAX_CLOUD_BINS} (bins over 360 degrees)"
                        ),
                    ));
                }
                finite("z_min_m", *z_min_m, "m")?;
                finite("z_max_m", *z_max_m, "m")?;
                if z_min_m > z_max_m {
                    return Err((
                        "z_max_m",
                        format!("z_max_m ({z_max_m} m) is below z_min_m ({z_min_m} m)"),
                    ));
                }
                at_most(
                    "points_flu_m",
                    points_flu_m.len(),
                    MAX_CLOUD_POINTS,
                    "points",
                )
            }
            ScanInput::Multiranger { .. } => Ok(()),
        }
    }
}

/// The scans of a batch, each checked before it is built (a beam count or a size from outside
/// never allocates before it passed its bounds).
pub fn to_scans(batch: &ScanBatch) -> Result<Vec<RangeScan>, Vec<ValidationError>> {
    let mut errors = Vec::new();
    let mut scans = Vec::with_capacity(batch.scans.len().min(MAX_SCANS_PER_REQUEST));
    for (i, input) in batch.scans.iter().enumerate() {
        let built = input.check().and_then(|()| {
            let scan = input.to_scan();
            scan.validate().map_err(|e| ("", e.to_string()))?;
            Ok(scan)
        });
        match built {
            Ok(scan) => scans.push(scan),
            Err((field, message)) => errors.push(ValidationError {
                pointer: match field {
                    "" => format!("/scans/{i}"),
                    f => format!("/scans/{i}/{f}"),
                },
                message,
            }),
        }
    }
    if errors.is_empty() {
        Ok(scans)
    } else {
        Err(errors)
    }
}

/// A binary `KSC1` scan.
pub fn decode_binary(bytes: &[u8]) -> Result<RangeScan, MapError> {
    RangeScan::decode_binary(bytes)
}
