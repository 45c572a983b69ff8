//! Scans for the map: the sensor adapters the API and cameras need on top of the platforms'
//! (`types::scan`): one depth-image row, a point cloud, and the binary wire message below.
//! Out: a [`RangeScan`] in the world ENU frame, ready for
//! [`crate::mapping::OccupancyGrid::insert_scan`].
//!
//! Conventions: beam angles are relative to the sensor x axis, counter-clockwise (FLU);
//! `range_m: None` means "no return within `range_max_m`" (the ray is cleared, no hit).
//! Invalid readings (below the minimum range, NaN, "unknown" codes) are dropped, not turned into
//! `None`, because a dropped beam says nothing while `None` clears free space.
//!
//! # Binary scan message (`KSC1`, little endian)
//! | offset | type | field |
//! |---|---|---|
//! | 0 | `[u8; 4]` | magic `b"KSC1"` |
//! | 4, 12, 20 | `f64` ×3 | sensor origin x, y, z (ENU, m) |
//! | 28 | `f64` | sensor yaw (ENU, rad, CCW from east) |
//! | 36 | `f32` | range_min (m, finite) |
//! | 40 | `f32` | range_max (m, finite) |
//! | 44 | `f32` | angle of the first beam (rad, FLU, finite) |
//! | 48 | `f32` | angle increment (rad, finite) |
//! | 52 | `u32` | beam count N (at most [`MAX_BEAMS`]) |
//! | 56 | `f32` ×N | ranges (m): NaN = invalid (dropped), +inf or > range_max = no return |

use std::f64::consts::{PI, TAU};

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::MapError;

/// Most beams in one scan from outside (a `KSC1` message, a planar scan or a depth row sent
/// over the API): more than any planar lidar has, far less than would stall the map.
pub const MAX_BEAMS: usize = 10_000;
use crate::types::scan::beam;
pub use crate::types::scan::{
    beam_from_distance_sensor, from_multiranger, from_obstacle_distance, from_planar_lidar, Beam,
    ObstacleSectors, RangeScan, ScanError, SectorFrame,
};

impl RangeScan {
    /// Decodes the binary `KSC1` message described in the module docs.
    pub fn decode_binary(bytes: &[u8]) -> Result<RangeScan, MapError> {
        let bad = |what: &str| MapError::InvalidScan(format!("binary scan: {what}"));
        if bytes.get(0..4) != Some(b"KSC1".as_slice()) {
            return Err(bad("missing KSC1 magic"));
        }
        let f64_at = |o: usize| -> Result<f64, MapError> {
            let b = bytes.get(o..o + 8).ok_or_else(|| bad("truncated header"))?;
            let mut a = [0u8; 8];
            a.copy_from_slice(b);
            Ok(f64::from_le_bytes(a))
        };
        let u32_at = |o: usize| -> Result<u32, MapError> {
            let b = bytes.get(o..o + 4).ok_or_else(|| bad("truncated"))?;
            let mut a = [0u8; 4];
            a.copy_from_slice(b);
            Ok(u32::from_le_bytes(a))
        };
        let f32_at = |o: usize| u32_at(o).map(|v| f64::from(f32::from_bits(v)));
        let origin = Vector3::new(f64_at(4)?, f64_at(12)?, f64_at(20)?);
        let yaw = f64_at(28)?;
        let range_min = f32_at(36)?;
        let range_max = f32_at(40)?;
        let angle_min = f32_at(44)?;
        let increment = f32_at(48)?;
        for (field, v) in [
            ("angle_min (offset 44, rad)", angle_min),
            ("angle_increment (offset 48, rad)", increment),
            ("range_min (offset 36, m)", range_min),
            ("range_max (offset 40, m)", range_max),
        ] {
            if !v.is_finite() {
                return Err(bad(&format!("{field} is {v}, not a finite number")));
            }
        }
        let n = u32_at(52)? as usize;
        if n > MAX_BEAMS {
            return Err(bad(&format!(
                "beam count (offset 52) is {n}, more than {MAX_BEAMS}"
            )));
        }
        let expected = n.checked_mul(4).and_then(|b| b.checked_add(56));
        if expected != Some(bytes.len()) {
            return Err(bad(&format!(
                "{} bytes, but a beam count of {n} (offset 52) needs {}",
                bytes.len(),
                56 + 4 * n
            )));
        }
        let mut ranges = Vec::with_capacity(n);
        for i in 0..n {
            ranges.push(f32_at(56 + 4 * i)?);
        }
        let scan = from_planar_lidar(
            origin, yaw, angle_min, increment, &ranges, range_min, range_max,
        );
        scan.validate()?;
        Ok(scan)
    }
}

/// Encodes an evenly spaced planar scan as the binary `KSC1` message (see the module docs).
pub fn encode_binary(
    origin_enu_m: Vector3<f64>,
    yaw_rad: f64,
    range_min_m: f32,
    range_max_m: f32,
    angle_min_rad: f32,
    angle_increment_rad: f32,
    ranges_m: &[f32],
) -> Vec<u8> {
    let mut out = Vec::with_capacity(56 + 4 * ranges_m.len());
    out.extend_from_slice(b"KSC1");
    for v in [origin_enu_m.x, origin_enu_m.y, origin_enu_m.z, yaw_rad] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [range_min_m, range_max_m, angle_min_rad, angle_increment_rad] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    out.extend_from_slice(&(ranges_m.len() as u32).to_le_bytes());
    for r in ranges_m {
        out.extend_from_slice(&r.to_le_bytes());
    }
    out
}

/// Pinhole intrinsics of a depth camera, horizontal part only (pixels).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct PinholeRow {
    pub fx_px: f64,
    pub cx_px: f64,
}

/// One row of a depth image (z-depth in metres, optical frame: x right, z forward) as a scan,
/// one beam per column. `depth <= 0` or NaN is dropped (no data); beyond `range_max_m` is no
/// return. To use a band of rows, pass the per-column minimum over the band.
pub fn from_depth_row(
    origin_enu_m: Vector3<f64>,
    yaw_rad: f64,
    depths_m: &[f32],
    camera: PinholeRow,
    range_min_m: f64,
    range_max_m: f64,
) -> RangeScan {
    let beams = depths_m
        .iter()
        .enumerate()
        .filter(|(_, &z)| z > 0.0)
        .filter_map(|(u, &z)| {
            let x_over_z = (u as f64 - camera.cx_px) / camera.fx_px;
            // Optical x (right) is FLU -y, so the angle is atan(-x/z).
            let angle = (-x_over_z).atan();
            let range = f64::from(z) * (1.0 + x_over_z * x_over_z).sqrt();
            beam(angle, range, range_min_m, range_max_m)
        })
        .collect();
    RangeScan {
        origin_enu_m,
        yaw_rad,
        range_min_m,
        range_max_m,
        beams,
    }
}

/// How a point cloud is flattened to a scan at the flight height.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct CloudProjection {
    /// Points with sensor-frame z in `[z_min_m, z_max_m]` are kept.
    pub z_min_m: f64,
    pub z_max_m: f64,
    /// Angular span of the scan (FLU), split into `beam_count` equal bins.
    pub angle_min_rad: f64,
    pub angle_max_rad: f64,
    pub beam_count: usize,
    pub range_min_m: f64,
    pub range_max_m: f64,
}

impl CloudProjection {
    /// A full 360-degree projection with one-degree bins.
    pub fn full_circle(z_min_m: f64, z_max_m: f64, range_min_m: f64, range_max_m: f64) -> Self {
        CloudProjection {
            z_min_m,
            z_max_m,
            angle_min_rad: -PI,
            angle_max_rad: PI,
            beam_count: 360,
            range_min_m,
            range_max_m,
        }
    }
}

/// Point cloud in the sensor's FLU frame to a scan: for each angular bin, the nearest point
/// inside the height band. Empty bins are "no return".
pub fn from_point_cloud(
    origin_enu_m: Vector3<f64>,
    yaw_rad: f64,
    points_flu_m: &[Vector3<f64>],
    p: &CloudProjection,
) -> RangeScan {
    let n = p.beam_count;
    let span = p.angle_max_rad - p.angle_min_rad;
    let mut nearest: Vec<Option<f64>> = vec![None; n];
    if n > 0 && span > 0.0 && span <= TAU + 1e-9 {
        for q in points_flu_m {
            if !(q.z >= p.z_min_m && q.z <= p.z_max_m) {
                continue;
            }
            let r = q.x.hypot(q.y);
            if !(r >= p.range_min_m && r < p.range_max_m) {
                continue;
            }
            let a = q.y.atan2(q.x);
            let bin = ((a - p.angle_min_rad) / span * n as f64).floor();
            if bin < 0.0 || bin >= n as f64 {
                continue;
            }
            if let Some(slot) = nearest.get_mut(bin as usize) {
                if slot.is_none_or(|old| r < old) {
                    *slot = Some(r);
                }
            }
        }
    }
    let step = if n > 0 { span / n as f64 } else { 0.0 };
    let beams = nearest
        .into_iter()
        .enumerate()
        .map(|(i, range_m)| Beam {
            angle_rad: p.angle_min_rad + step * (i as f64 + 0.5),
            range_m,
        })
        .collect();
    RangeScan {
        origin_enu_m,
        yaw_rad,
        range_min_m: p.range_min_m,
        range_max_m: p.range_max_m,
        beams,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::FRAC_PI_4;

    const EPS: f64 = 1e-9;

    #[test]
    fn multiranger_maps_four_directions_and_no_return() {
        let s = from_multiranger(
            Vector3::new(1.0, 2.0, 0.5),
            0.3,
            [Some(1.5), None, Some(5.0), Some(0.01)],
            0.02,
            4.0,
        );
        // Right reading below range_min is dropped; back beyond max is "no return".
        assert_eq!(s.beams.len(), 3);
        assert_eq!(s.beams[0].range_m, Some(1.5));
        assert!((s.beams[1].angle_rad - PI / 2.0).abs() < EPS);
        assert_eq!(s.beams[1].range_m, None);
        assert!((s.beams[2].angle_rad - PI).abs() < EPS);
        assert_eq!(s.beams[2].range_m, None);
    }

    #[test]
    fn distance_sensor_orientation_is_clockwise_frd() {
        let right = beam_from_distance_sensor(2, 150, 4, 400);
        assert!(right.is_some_and(|b| (b.angle_rad + PI / 2.0).abs() < EPS));
        assert_eq!(right.and_then(|b| b.range_m), Some(1.5));
        assert_eq!(
            beam_from_distance_sensor(0, 400, 4, 400).map(|b| b.range_m),
            Some(None)
        );
        assert_eq!(beam_from_distance_sensor(24, 100, 4, 400), None);
    }

    #[test]
    fn obstacle_distance_body_frd_converts_to_flu() {
        let mut d = [u16::MAX; 72];
        d[0] = 250; // forward
        d[18] = 100; // 90 deg clockwise = right
        d[36] = 1001; // behind, beyond max: no obstacle
        let s = from_obstacle_distance(
            Vector3::zeros(),
            1.0,
            &ObstacleSectors {
                distances_cm: &d,
                increment_deg: 5.0,
                angle_offset_deg: 0.0,
                min_distance_cm: 20,
                max_distance_cm: 1000,
                frame: SectorFrame::BodyFrd,
            },
        );
        assert_eq!(s.yaw_rad, 1.0);
        assert_eq!(s.beams.len(), 3);
        assert!((s.beams[0].angle_rad).abs() < EPS);
        assert_eq!(s.beams[0].range_m, Some(2.5));
        assert!((s.beams[1].angle_rad + PI / 2.0).abs() < EPS);
        assert_eq!(s.beams[1].range_m, Some(1.0));
        assert_eq!(s.beams[2].range_m, None);
    }

    #[test]
    fn obstacle_distance_ned_sector_points_north_in_enu() {
        let d = [300u16];
        let s = from_obstacle_distance(
            Vector3::zeros(),
            2.0,
            &ObstacleSectors {
                distances_cm: &d,
                increment_deg: 5.0,
                angle_offset_deg: 90.0, // east
                min_distance_cm: 20,
                max_distance_cm: 1000,
                frame: SectorFrame::LocalNed,
            },
        );
        let dir = s.beam_direction_enu(&s.beams[0]);
        assert!((dir.x - 1.0).abs() < EPS && dir.y.abs() < EPS);
    }

    #[test]
    fn depth_row_uses_ray_length_and_flu_angles() {
        // Column 0 is left of the centre column 2: FLU angle positive (left).
        let s = from_depth_row(
            Vector3::zeros(),
            0.0,
            &[2.0, 0.0, 2.0, f32::NAN, 20.0],
            PinholeRow {
                fx_px: 2.0,
                cx_px: 2.0,
            },
            0.1,
            10.0,
        );
        assert_eq!(s.beams.len(), 3);
        assert!((s.beams[0].angle_rad - FRAC_PI_4).abs() < EPS);
        assert!((s.beams[0].range_m.unwrap_or(0.0) - 2.0 * 2f64.sqrt()).abs() < 1e-6);
        assert_eq!(s.beams[1].range_m, Some(2.0));
        assert_eq!(s.beams[2].range_m, None);
    }

    #[test]
    fn point_cloud_keeps_nearest_point_in_band() {
        let pts = [
            Vector3::new(3.0, 0.0, 0.0),
            Vector3::new(2.0, 0.0, 0.05),
            Vector3::new(1.0, 0.0, 1.0), // above the band
            Vector3::new(0.0, 1.5, 0.0),
        ];
        let p = CloudProjection {
            z_min_m: -0.1,
            z_max_m: 0.1,
            angle_min_rad: -PI,
            angle_max_rad: PI,
            beam_count: 4,
            range_min_m: 0.1,
            range_max_m: 10.0,
        };
        let s = from_point_cloud(Vector3::zeros(), 0.0, &pts, &p);
        // Bins: [-pi,-pi/2), [-pi/2,0), [0,pi/2), [pi/2,pi]; 1.5 m at +pi/2 falls in bin 3.
        let r: Vec<Option<f64>> = s.beams.iter().map(|b| b.range_m).collect();
        assert_eq!(r, vec![None, None, Some(2.0), Some(1.5)]);
    }

    #[test]
    fn binary_message_round_trips() {
        let bytes = encode_binary(
            Vector3::new(1.0, -2.0, 0.5),
            0.25,
            0.1,
            8.0,
            -1.0,
            0.5,
            &[1.0, f32::INFINITY, f32::NAN, 9.0, 2.5],
        );
        let s = RangeScan::decode_binary(&bytes).unwrap();
        assert_eq!(s.origin_enu_m, Vector3::new(1.0, -2.0, 0.5));
        assert_eq!(s.beams.len(), 4);
        assert_eq!(s.beams[0].range_m, Some(1.0));
        assert_eq!(s.beams[1].range_m, None);
        assert_eq!(s.beams[2].range_m, None);
        assert!((s.beams[3].angle_rad - 1.0).abs() < 1e-6);
        assert!(RangeScan::decode_binary(&bytes[..bytes.len() - 1]).is_err());
        assert!(RangeScan::decode_binary(b"XXXX").is_err());
    }

    #[test]
    fn binary_headers_with_non_finite_angles_or_huge_counts_are_refused() {
        let origin = Vector3::new(1.0, 2.0, 1.0);
        // No beam would carry the bad angle: the header itself is checked.
        for (angle, increment, ranges) in [
            (f32::NAN, 0.5, vec![f32::NAN; 3]),
            (0.0, f32::INFINITY, vec![]),
            (f32::NEG_INFINITY, 0.5, vec![f32::NAN]),
        ] {
            let bytes = encode_binary(origin, 0.0, 0.1, 8.0, angle, increment, &ranges);
            let e = RangeScan::decode_binary(&bytes).unwrap_err().to_string();
            assert!(e.contains("angle"), "{e}");
        }
        let mut huge = encode_binary(origin, 0.0, 0.1, 8.0, 0.0, 0.1, &[]);
        huge.splice(52..56, u32::MAX.to_le_bytes());
        let e = RangeScan::decode_binary(&huge).unwrap_err().to_string();
        assert!(e.contains("offset 52") && e.contains("10000"), "{e}");
    }
}
