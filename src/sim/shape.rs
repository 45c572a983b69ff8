//! Obstacle shapes: vertical prisms (cylinders, rotated boxes) from the ground up.
//!
//! In: a point or a horizontal ray. Out: the distance to the shape's surface, or where the ray
//! hits it. Collision checks and the simulated range sensors are built on these two.

use crate::types::{Vec2, Vec3};

/// An obstacle shape: vertical prism from the ground to `height_m`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Shape {
    Cylinder {
        center: Vec2,
        radius_m: f64,
        height_m: f64,
    },
    Box {
        center: Vec2,
        half_size: Vec2,
        yaw_rad: f64,
        height_m: f64,
    },
}

impl Shape {
    /// Horizontal distance from `p` to the shape's surface (negative inside), if `p.z` is
    /// within the shape's height; `None` above it.
    pub fn distance_m(&self, p: &Vec3) -> Option<f64> {
        match *self {
            Shape::Cylinder {
                center,
                radius_m,
                height_m,
            } => (p.z <= height_m).then(|| (p.xy() - center).norm() - radius_m),
            Shape::Box {
                center,
                half_size,
                yaw_rad,
                height_m,
            } => (p.z <= height_m).then(|| {
                let local = rotate(p.xy() - center, -yaw_rad);
                let d = Vec2::new(local.x.abs() - half_size.x, local.y.abs() - half_size.y);
                let outside = Vec2::new(d.x.max(0.0), d.y.max(0.0)).norm();
                outside + d.x.max(d.y).min(0.0)
            }),
        }
    }

    /// Distance along a horizontal ray from `origin` in unit direction `dir` to the shape, if hit.
    pub fn ray_hit_m(&self, origin: &Vec3, dir: &Vec2) -> Option<f64> {
        match *self {
            Shape::Cylinder {
                center,
                radius_m,
                height_m,
            } => {
                if origin.z > height_m {
                    return None;
                }
                let oc = origin.xy() - center;
                let b = oc.dot(dir);
                let c = oc.norm_squared() - radius_m * radius_m;
                let disc = b * b - c;
                if disc < 0.0 {
                    return None;
                }
                let t = -b - disc.sqrt();
                if t >= 0.0 {
                    Some(t)
                } else if c < 0.0 {
                    Some(0.0)
                } else {
                    None
                }
            }
            Shape::Box {
                center,
                half_size,
                yaw_rad,
                height_m,
            } => {
                if origin.z > height_m {
                    return None;
                }
                let o = rotate(origin.xy() - center, -yaw_rad);
                let d = rotate(*dir, -yaw_rad);
                let (mut t_min, mut t_max) = (f64::NEG_INFINITY, f64::INFINITY);
                for i in 0..2 {
                    if d[i].abs() < 1e-12 {
                        if o[i].abs() > half_size[i] {
                            return None;
                        }
                    } else {
                        let t1 = (-half_size[i] - o[i]) / d[i];
                        let t2 = (half_size[i] - o[i]) / d[i];
                        t_min = t_min.max(t1.min(t2));
                        t_max = t_max.min(t1.max(t2));
                    }
                }
                (t_max >= t_min.max(0.0)).then_some(t_min.max(0.0))
            }
        }
    }
}

fn rotate(v: Vec2, angle_rad: f64) -> Vec2 {
    let (s, c) = angle_rad.sin_cos();
    Vec2::new(c * v.x - s * v.y, s * v.x + c * v.y)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cylinder_ray_and_distance() {
        let s = Shape::Cylinder {
            center: Vec2::new(5.0, 0.0),
            radius_m: 1.0,
            height_m: 3.0,
        };
        let hit = s
            .ray_hit_m(&Vec3::new(0.0, 0.0, 1.0), &Vec2::new(1.0, 0.0))
            .unwrap();
        assert!((hit - 4.0).abs() < 1e-12);
        assert!(
            s.ray_hit_m(&Vec3::new(0.0, 0.0, 4.0), &Vec2::new(1.0, 0.0))
                .is_none(),
            "above the cylinder"
        );
        assert!(
            s.ray_hit_m(&Vec3::new(0.0, 0.0, 1.0), &Vec2::new(-1.0, 0.0))
                .is_none(),
            "behind the ray"
        );
        assert!((s.distance_m(&Vec3::new(5.0, 3.0, 0.0)).unwrap() - 2.0).abs() < 1e-12);
    }

    #[test]
    fn rotated_box_ray_and_distance() {
        let s = Shape::Box {
            center: Vec2::new(0.0, 5.0),
            half_size: Vec2::new(1.0, 1.0),
            yaw_rad: std::f64::consts::FRAC_PI_4,
            height_m: 3.0,
        };
        let hit = s
            .ray_hit_m(&Vec3::new(0.0, 0.0, 1.0), &Vec2::new(0.0, 1.0))
            .unwrap();
        assert!((hit - (5.0 - 2f64.sqrt())).abs() < 1e-9, "{hit}");
        assert!(
            s.distance_m(&Vec3::new(0.0, 5.0, 1.0)).unwrap() < 0.0,
            "inside"
        );
    }
}
