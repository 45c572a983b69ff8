//! Where and how fast a mission item may fly: its speeds against the vehicle's limit, its
//! heights against the ceiling, its frames known, its points inside the geofence.
//!
//! In: one item's goal (canonical arguments and the summary its behavior gives) and the
//! [`ValidationContext`]. Out: every problem found, each with its JSON pointer.

use super::{at, join, ValidationContext, ValidationError};
use crate::behavior::GoalSummary;
use crate::estimator::geodetic::GeoPoint;
use crate::mission::methods::Canonical;
use crate::safety::LowestHeight;
use crate::types::Vec3;
use serde_json::Value;

const SPEED_KEYS: [&str; 6] = [
    "speed",
    "land_speed",
    "speed_x",
    "speed_y",
    "speed_z",
    "max_speed",
];

/// Speeds, heights, frames and the geofence.
pub(super) fn check_limits(
    goal: &Value,
    summary: &GoalSummary,
    canonical: &Canonical,
    args_pointer: &str,
    ctx: &ValidationContext,
) -> Result<(), Vec<ValidationError>> {
    let mut errors = Vec::new();
    let pointer_of = |key: &str| join(args_pointer, &canonical.origin_of(key));
    let limits = ctx.limits;
    let mut speed_flagged = false;
    for key in SPEED_KEYS {
        if let Some(v) = goal.get(key).and_then(Value::as_f64) {
            if v > limits.max_speed_mps {
                speed_flagged = true;
                errors.push(at(
                    &pointer_of(key),
                    format!(
                        "{key} = {v} m/s is above the vehicle's limit of {} m/s",
                        limits.max_speed_mps
                    ),
                ));
            }
        }
    }
    if !speed_flagged {
        if let Some(v) = summary
            .speeds_mps
            .iter()
            .find(|v| **v > limits.max_speed_mps)
        {
            errors.push(at(
                args_pointer,
                format!(
                    "speed {v} m/s is above the vehicle's limit of {} m/s",
                    limits.max_speed_mps
                ),
            ));
        }
    }
    errors.extend(height_errors(goal, summary, &pointer_of, args_pointer, ctx));
    let path_len = goal.get("path").and_then(Value::as_array).map(Vec::len);
    if let Some(n) = path_len.filter(|n| *n > limits.max_waypoints) {
        errors.push(at(
            &pointer_of("path"),
            format!(
                "path has {n} waypoints, more than the limit of {}",
                limits.max_waypoints
            ),
        ));
        return Err(errors);
    }
    if let Some(frame) = goal.get("frame_id").and_then(Value::as_str) {
        let known =
            frame.is_empty() || frame == crate::behavior::WGS84 || ctx.frames.contains(frame);
        if !known {
            errors.push(unknown_frame(&pointer_of("frame_id"), frame, ctx));
            return Err(errors);
        }
    }
    for (k, target) in summary.targets.iter().enumerate() {
        let (horizontal, vertical) = match path_len {
            Some(n) if n == summary.targets.len() => {
                let p = format!("{}/{k}", pointer_of("path"));
                (p.clone(), p)
            }
            _ if goal.get("x").is_some() => (pointer_of("x"), pointer_of("z")),
            _ if goal.get("lat").is_some() => (pointer_of("lat"), pointer_of("alt")),
            _ => (args_pointer.to_string(), args_pointer.to_string()),
        };
        let earth = if target.frame_id == crate::behavior::WGS84 {
            let geo = GeoPoint {
                lat_deg: target.position_m.x,
                lon_deg: target.position_m.y,
                alt_m: target.position_m.z,
            };
            ctx.geo_origin.to_enu(&geo).map_err(|e| e.to_string())
        } else if !ctx.frames.contains(&target.frame_id) {
            errors.push(unknown_frame(
                &pointer_of("frame_id"),
                &target.frame_id,
                ctx,
            ));
            break;
        } else {
            ctx.frames
                .point_to_earth(&target.position_m, &target.frame_id, ctx.now)
                .map_err(|e| e.to_string())
        };
        match earth {
            Ok(p) => errors.extend(geofence_errors(&p, ctx, &horizontal, &vertical)),
            Err(e) => errors.push(at(&pointer_of("frame_id"), e)),
        }
    }
    if errors.is_empty() {
        Ok(())
    } else {
        Err(errors)
    }
}

/// A goal's `height` against the ceiling, and its heights (given or default) against the
/// vehicle's lowest flight height.
fn height_errors(
    goal: &Value,
    summary: &GoalSummary,
    pointer_of: &dyn Fn(&str) -> String,
    args_pointer: &str,
    ctx: &ValidationContext,
) -> Vec<ValidationError> {
    let mut errors = Vec::new();
    let given = goal.get("height").and_then(Value::as_f64);
    let ceiling = ctx.limits.geofence.max_altitude_m;
    if let Some(h) = given.filter(|h| *h > ceiling) {
        errors.push(at(
            &pointer_of("height"),
            format!("height = {h} m is above the {ceiling} m ceiling"),
        ));
    }
    if let Some(lowest) = ctx.lowest_height {
        for h in summary.heights_m.iter().filter(|h| **h < lowest.height_m) {
            let (pointer, what) = match given {
                Some(_) => (pointer_of("height"), format!("height = {h} m")),
                None => (
                    args_pointer.to_string(),
                    format!("height {h} m (the default)"),
                ),
            };
            errors.push(at(&pointer, too_low(&what, &lowest)));
        }
    }
    errors
}

/// Why `what` (a height, a point) is refused below the vehicle's lowest flight height.
fn too_low(what: &str, lowest: &LowestHeight) -> String {
    format!(
        "{what} is below this vehicle's lowest flight height of {:.1} m above home: its height \
         estimate may be off by {:.1} m (`height_error_m` of its platform profile, or `[safety] \
         height_error_m`; set it lower for a vehicle that holds its height on a downward \
         rangefinder)",
        lowest.height_m, lowest.error_m
    )
}

fn unknown_frame(pointer: &str, frame: &str, ctx: &ValidationContext) -> ValidationError {
    let known: Vec<&str> = ctx.frames.names().collect();
    at(
        pointer,
        format!(
            "unknown frame `{frame}`; known: {} (register frames with POST /api/frames)",
            known.join(", ")
        ),
    )
}

fn geofence_errors(
    p: &Vec3,
    ctx: &ValidationContext,
    horizontal: &str,
    vertical: &str,
) -> Vec<ValidationError> {
    let fence = &ctx.limits.geofence;
    let home = ctx.home_enu_m;
    let mut out = Vec::new();
    let where_ = format!("({:.1}, {:.1}, {:.1}) m in earth", p.x, p.y, p.z);
    let altitude = p.z - home.z;
    if altitude > fence.max_altitude_m {
        out.push(at(
            vertical,
            format!(
                "{where_} is {altitude:.1} m above home, over the {} m ceiling",
                fence.max_altitude_m
            ),
        ));
    }
    if let Some(lowest) = ctx.lowest_height.filter(|l| altitude < l.height_m) {
        out.push(at(
            vertical,
            too_low(&format!("{where_}, {altitude:.1} m above home,"), &lowest),
        ));
    }
    if altitude < fence.min_altitude_m {
        out.push(at(
            vertical,
            format!(
                "{where_} is {altitude:.1} m relative to home, below the {} m floor",
                fence.min_altitude_m
            ),
        ));
    }
    let distance = (p.xy() - home.xy()).norm();
    if let Some(r) = fence.radius_m.filter(|r| distance > *r) {
        out.push(at(
            horizontal,
            format!("{where_} is {distance:.0} m from home, outside the {r} m geofence"),
        ));
    }
    if let Some(poly) = &fence.polygon_enu_m {
        if !inside(poly, p.x, p.y) {
            out.push(at(
                horizontal,
                format!("{where_} is outside the geofence polygon"),
            ));
        }
    }
    out
}

/// Even-odd point-in-polygon test.
fn inside(poly: &[[f64; 2]], x: f64, y: f64) -> bool {
    let mut result = false;
    let n = poly.len();
    for i in 0..n {
        let [xi, yi] = poly[i];
        let [xj, yj] = poly[(i + n - 1) % n];
        if (yi > y) != (yj > y) && x < (xj - xi) * (y - yi) / (yj - yi) + xi {
            result = !result;
        }
    }
    result
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn polygon_inside_and_outside() {
        let square = [[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]];
        assert!(inside(&square, 5.0, 5.0));
        assert!(!inside(&square, 15.0, 5.0));
    }
}
