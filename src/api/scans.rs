//! `POST /api/scans`: the body (JSON `{"drone": "drone_0", "scans": [ScanInput, ..]}` or
//! `KSC1` bytes) parsed into the drone (body field or `?drone=`) and its scans; the host turns
//! sensor readings into scans (`host::scans`).

use super::error::ApiError;
use crate::host::scans::{self, MAX_SCANS_PER_REQUEST};
pub use crate::host::scans::{ScanBatch, ScanInput};
use crate::mission::ValidationError;
use crate::types::RangeScan;

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
        let scan = scans::decode_binary(body).map_err(|e| invalid(String::new(), e.to_string()))?;
        return Ok((query_drone, vec![scan]));
    }
    let batch: ScanBatch = super::body::parse(body)?;
    if batch.scans.len() > MAX_SCANS_PER_REQUEST {
        return Err(invalid(
            "/scans".into(),
            format!("at most {MAX_SCANS_PER_REQUEST} scans per request"),
        ));
    }
    let scans = scans::to_scans(&batch).map_err(ApiError::Invalid)?;
    Ok((batch.drone.or(query_drone), scans))
}

#[cfg(test)]
mod tests {
    use super::*;
    use nalgebra::Vector3;
    use serde_json::{json, Value};

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
    fn huge_beam_counts_are_refused_before_anything_is_allocated() {
        for count in [1_000_000_000_000u64, 1 << 60, 100_000_000] {
            let body = json!({ "drone": "drone_0", "scans": [
                { "kind": "point_cloud", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
                  "points_flu_m": [[2, 0, 0]], "z_min_m": -0.2, "z_max_m": 0.2,
                  "range_min_m": 0.1, "range_max_m": 10, "beam_count": count }
            ]});
            match body_scans(body.to_string().as_bytes(), false, None) {
                Err(ApiError::Invalid(errors)) => {
                    assert_eq!(errors[0].pointer, "/scans/0/beam_count");
                    assert!(
                        errors[0].message.contains("1..=3600"),
                        "{}",
                        errors[0].message
                    );
                }
                other => panic!("{count}: {other:?}"),
            }
        }
    }

    #[test]
    fn sizes_and_numbers_are_refused_with_the_field_and_unit() {
        let planar = |angle: Value, ranges: usize| {
            json!({ "kind": "planar", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
                "angle_min_rad": angle, "angle_increment_rad": 0.01,
                "ranges_m": vec![1.0; ranges], "range_min_m": 0.1, "range_max_m": 5 })
        };
        let cloud = json!({ "kind": "point_cloud", "origin_enu_m": [0, 0, 1], "yaw_rad": 0,
            "points_flu_m": [[2, 0, 0]], "z_min_m": 0.5, "z_max_m": 0.2,
            "range_min_m": 0.1, "range_max_m": 10 });
        let body = json!({ "scans": [
            planar(json!(0.0), 3), planar(json!(0.0), scans::MAX_BEAMS + 1), cloud,
            planar(json!(1e308), 1)
        ]});
        match body_scans(body.to_string().as_bytes(), false, None) {
            Err(ApiError::Invalid(errors)) => {
                let got: Vec<(&str, &str)> = errors
                    .iter()
                    .map(|e| (e.pointer.as_str(), e.message.as_str()))
                    .collect();
                assert_eq!(got.len(), 2, "{got:?}");
                assert_eq!(got[0].0, "/scans/1/ranges_m");
                assert!(got[0].1.contains("at most 10000"), "{got:?}");
                assert_eq!(got[1].0, "/scans/2/z_max_m");
                assert!(got[1].1.contains(" m)"), "{got:?}");
            }
            other => panic!("{other:?}"),
        }
    }

    #[test]
    fn a_binary_scan_with_a_non_finite_angle_is_refused() {
        let bytes = scans::encode_binary(
            Vector3::new(1.0, 2.0, 1.0),
            0.5,
            0.1,
            8.0,
            f32::NAN,
            0.5,
            &[1.0, 2.0],
        );
        assert!(body_scans(&bytes, true, None).is_err());
    }

    #[test]
    fn a_binary_scan_is_decoded() {
        let bytes = scans::encode_binary(
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
