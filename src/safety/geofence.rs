//! The geofence in flight: ceiling and floor relative to home, a radius around home and an
//! optional polygon in `earth`, with the nearest point inside for what lies outside.
//!
//! In: the `[geofence]` section (the same limits missions are validated against; the config
//! embeds and validates it) and home. Out: whether a point is inside, and the point clamped a
//! margin inside.

use crate::types::Vec3;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

/// Where missions may send the vehicle. Altitudes are relative to home (the arming point, or
/// the vehicle's position before the first arming).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct GeofenceSection {
    /// Ceiling above home (m).
    pub max_altitude_m: f64,
    /// Floor relative to home (m); negative allows goals below the home altitude.
    pub min_altitude_m: f64,
    /// Largest horizontal distance from home (m); absent = no radius limit.
    pub radius_m: Option<f64>,
    /// Polygon [[x, y], ..] (m, ENU `earth`) the vehicle must stay inside; absent = none.
    pub polygon_enu_m: Option<Vec<[f64; 2]>>,
}

impl Default for GeofenceSection {
    fn default() -> Self {
        Self {
            max_altitude_m: 120.0,
            min_altitude_m: 0.0,
            radius_m: Some(1000.0),
            polygon_enu_m: None,
        }
    }
}

/// The fence around one home.
#[derive(Debug, Clone, PartialEq)]
pub struct Fence<'a> {
    pub section: &'a GeofenceSection,
    pub home_enu_m: Vec3,
    /// How far inside the fence a clamped point is put (m).
    pub margin_m: f64,
}

impl Fence<'_> {
    /// Above the ceiling, outside the radius or the polygon (the floor is for targets only).
    pub fn breached_by(&self, p: &Vec3) -> Option<&'static str> {
        let s = self.section;
        if p.z - self.home_enu_m.z > s.max_altitude_m {
            return Some("ceiling");
        }
        if s.radius_m
            .is_some_and(|r| (p.xy() - self.home_enu_m.xy()).norm() > r)
        {
            return Some("radius");
        }
        if s.polygon_enu_m
            .as_ref()
            .is_some_and(|poly| !inside(poly, Vector2::new(p.x, p.y)))
        {
            return Some("polygon");
        }
        None
    }

    /// A target below the floor (beyond a landing's reach of home).
    pub fn below_floor(&self, p: &Vec3) -> bool {
        p.z - self.home_enu_m.z < self.section.min_altitude_m - FLOOR_TOLERANCE_M
    }

    /// The nearest point `margin_m` inside the fence (and above the floor).
    pub fn clamp(&self, p: &Vec3) -> Vec3 {
        let s = self.section;
        let home = self.home_enu_m;
        let mut out = *p;
        let top = home.z + (s.max_altitude_m - self.margin_m).max(0.0);
        let bottom = home.z + s.min_altitude_m;
        out.z = out.z.min(top).max(bottom.min(top));
        if let Some(r) = s.radius_m {
            let d = out.xy() - home.xy();
            let limit = (r - self.margin_m).max(0.0);
            if d.norm() > limit {
                let inside = home.xy() + d.normalize() * limit;
                out.x = inside.x;
                out.y = inside.y;
            }
        }
        if let Some(poly) = &s.polygon_enu_m {
            let q = Vector2::new(out.x, out.y);
            if !inside(poly, q) {
                let edge = nearest_on_boundary(poly, q);
                let centre = centroid(poly);
                let inward = (centre - edge).try_normalize(1e-9).unwrap_or_default();
                let moved = edge + inward * self.margin_m;
                out.x = moved.x;
                out.y = moved.y;
            }
        }
        out
    }
}

/// Targets this far below the floor still count as on it (a landing aims at the ground).
const FLOOR_TOLERANCE_M: f64 = 0.5;

/// Even-odd rule.
fn inside(poly: &[[f64; 2]], p: Vector2<f64>) -> bool {
    let mut inside = false;
    let n = poly.len();
    for i in 0..n {
        let ([xi, yi], [xj, yj]) = (poly[i], poly[(i + n - 1) % n]);
        if (yi > p.y) != (yj > p.y) && p.x < (xj - xi) * (p.y - yi) / (yj - yi) + xi {
            inside = !inside;
        }
    }
    inside
}

fn nearest_on_boundary(poly: &[[f64; 2]], p: Vector2<f64>) -> Vector2<f64> {
    let n = poly.len();
    (0..n)
        .map(|i| {
            let a = Vector2::new(poly[i][0], poly[i][1]);
            let b = Vector2::new(poly[(i + 1) % n][0], poly[(i + 1) % n][1]);
            let ab = b - a;
            let t = ((p - a).dot(&ab) / ab.norm_squared().max(1e-12)).clamp(0.0, 1.0);
            a + ab * t
        })
        .min_by(|x, y| (x - p).norm().total_cmp(&(y - p).norm()))
        .unwrap_or(p)
}

fn centroid(poly: &[[f64; 2]]) -> Vector2<f64> {
    let sum = poly
        .iter()
        .fold(Vector2::zeros(), |s, [x, y]| s + Vector2::new(*x, *y));
    sum / poly.len().max(1) as f64
}

#[cfg(test)]
mod tests {
    use super::*;

    fn section() -> GeofenceSection {
        GeofenceSection {
            max_altitude_m: 120.0,
            min_altitude_m: 0.0,
            radius_m: Some(100.0),
            polygon_enu_m: None,
        }
    }

    #[test]
    fn points_outside_are_found_and_clamped_a_margin_inside() {
        let s = section();
        let fence = Fence {
            section: &s,
            home_enu_m: Vec3::new(10.0, 0.0, 5.0),
            margin_m: 0.5,
        };
        let high = Vec3::new(10.0, 0.0, 500.0);
        assert_eq!(fence.breached_by(&high), Some("ceiling"));
        assert_eq!(fence.clamp(&high), Vec3::new(10.0, 0.0, 124.5));
        let far = Vec3::new(210.0, 0.0, 10.0);
        assert_eq!(fence.breached_by(&far), Some("radius"));
        let c = fence.clamp(&far);
        assert!(
            (c.x - 109.5).abs() < 1e-9 && fence.breached_by(&c).is_none(),
            "{c}"
        );
        assert!(fence.below_floor(&Vec3::new(0.0, 0.0, 3.0)));
        assert!(!fence.below_floor(&Vec3::new(0.0, 0.0, 4.8)), "landing");
    }

    #[test]
    fn a_point_outside_the_polygon_comes_back_inside() {
        let mut s = section();
        s.polygon_enu_m = Some(vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]]);
        let fence = Fence {
            section: &s,
            home_enu_m: Vec3::new(5.0, 5.0, 0.0),
            margin_m: 0.5,
        };
        let out = Vec3::new(15.0, 5.0, 2.0);
        assert_eq!(fence.breached_by(&out), Some("polygon"));
        let c = fence.clamp(&out);
        assert!(
            fence.breached_by(&c).is_none() && (c.x - 9.5).abs() < 1e-9,
            "{c}"
        );
    }
}
