//! World files: bounds, obstacles, start poses and sensors for the simulators.
//!
//! The base layout is the thesis's exploration worlds, read unchanged (`bounds_m`,
//! `pole_radius_m`, `poles_xy_m`, `starts_xy_yaw` keyed by drone count). Optional extensions in
//! the same JSON object: `cylinders`, `boxes`, `sensor`, `geodetic_origin`, `pole_height_m`.
//! The Python fake autopilot in `sitl/` reads the same files.

use crate::estimator::geodetic::GeoPoint;
use crate::types::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// [min, max] east (m).
    pub x: [f64; 2],
    /// [min, max] north (m).
    pub y: [f64; 2],
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Cylinder {
    pub xy_m: [f64; 2],
    pub radius_m: f64,
    #[serde(default = "default_height")]
    pub height_m: f64,
}

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxObstacle {
    pub center_xy_m: [f64; 2],
    /// Full size along the box's own x and y (m).
    pub size_xy_m: [f64; 2],
    #[serde(default)]
    pub yaw_rad: f64,
    #[serde(default = "default_height")]
    pub height_m: f64,
}

fn default_height() -> f64 {
    10.0
}

/// Which range sensor the simulated drones carry. Absent fields take the defaults of the
/// kind, so `{"kind": "lidar360"}` is a complete sensor.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case", tag = "kind", deny_unknown_fields)]
pub enum SensorConfig {
    /// Crazyflie multi-ranger deck: four beams front/left/back/right (defaults 4 m, 20 Hz,
    /// 1 cm noise).
    Multiranger {
        #[serde(default = "multiranger_range")]
        range_max_m: f64,
        #[serde(default = "multiranger_rate")]
        rate_hz: f64,
        #[serde(default = "default_noise")]
        noise_std_m: f64,
    },
    /// Planar lidar, beams evenly over 360 deg (defaults 360 beams, 10 m, 10 Hz, 1 cm noise).
    Lidar360 {
        #[serde(default = "lidar_range")]
        range_max_m: f64,
        #[serde(default = "lidar_rate")]
        rate_hz: f64,
        #[serde(default = "default_noise")]
        noise_std_m: f64,
        #[serde(default = "lidar_beams")]
        beams: u32,
    },
    None,
}

fn multiranger_range() -> f64 {
    4.0
}
fn multiranger_rate() -> f64 {
    20.0
}
fn lidar_range() -> f64 {
    10.0
}
fn lidar_rate() -> f64 {
    10.0
}
fn lidar_beams() -> u32 {
    360
}
fn default_noise() -> f64 {
    0.01
}

impl Default for SensorConfig {
    fn default() -> Self {
        Self::multiranger()
    }
}

impl SensorConfig {
    pub fn multiranger() -> Self {
        Self::Multiranger {
            range_max_m: multiranger_range(),
            rate_hz: multiranger_rate(),
            noise_std_m: default_noise(),
        }
    }

    pub fn lidar() -> Self {
        Self::Lidar360 {
            range_max_m: lidar_range(),
            rate_hz: lidar_rate(),
            noise_std_m: default_noise(),
            beams: lidar_beams(),
        }
    }

    /// By name, as on the command line: `multiranger`, `lidar` (or `lidar360`), `none`.
    pub fn by_name(name: &str) -> Option<Self> {
        match name {
            "multiranger" => Some(Self::multiranger()),
            "lidar" | "lidar360" => Some(Self::lidar()),
            "none" => Some(Self::None),
            _ => None,
        }
    }

    fn validate(&self) -> Result<(), String> {
        let (range, rate, noise) = match *self {
            Self::Multiranger {
                range_max_m,
                rate_hz,
                noise_std_m,
            } => (range_max_m, rate_hz, noise_std_m),
            Self::Lidar360 {
                range_max_m,
                rate_hz,
                noise_std_m,
                beams,
            } => {
                if beams == 0 {
                    return Err("sensor.beams must be at least 1".into());
                }
                (range_max_m, rate_hz, noise_std_m)
            }
            Self::None => return Ok(()),
        };
        if !(range > 0.0 && rate > 0.0 && noise >= 0.0) {
            return Err(
                "sensor needs range_max_m > 0 (m), rate_hz > 0 (Hz), noise_std_m >= 0 (m)".into(),
            );
        }
        Ok(())
    }
}

/// A world file as written on disk.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct World {
    #[serde(default)]
    pub name: String,
    pub bounds_m: Bounds,
    #[serde(default)]
    pub pole_radius_m: f64,
    #[serde(default = "default_height")]
    pub pole_height_m: f64,
    #[serde(default)]
    pub poles_xy_m: Vec<[f64; 2]>,
    /// Start poses [x, y, yaw] keyed by the number of drones.
    #[serde(default)]
    pub starts_xy_yaw: BTreeMap<String, Vec<[f64; 3]>>,
    #[serde(default)]
    pub cylinders: Vec<Cylinder>,
    #[serde(default)]
    pub boxes: Vec<BoxObstacle>,
    #[serde(default)]
    pub sensor: SensorConfig,
    #[serde(default)]
    pub geodetic_origin: Option<GeoPoint>,
}

#[derive(Debug, thiserror::Error)]
pub enum WorldError {
    #[error("cannot read world file {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("world file {path} is not valid: {source}")]
    Parse {
        path: String,
        source: serde_json::Error,
    },
    #[error("world file {path}: {message}")]
    Invalid { path: String, message: String },
}

impl World {
    /// An open 200 m x 200 m field with no obstacles.
    pub fn empty() -> Self {
        Self {
            name: "empty".into(),
            bounds_m: Bounds {
                x: [-100.0, 100.0],
                y: [-100.0, 100.0],
            },
            pole_radius_m: 0.0,
            pole_height_m: default_height(),
            poles_xy_m: Vec::new(),
            starts_xy_yaw: BTreeMap::new(),
            cylinders: Vec::new(),
            boxes: Vec::new(),
            sensor: SensorConfig::default(),
            geodetic_origin: None,
        }
    }

    pub fn load(path: &Path) -> Result<Self, WorldError> {
        let p = path.display().to_string();
        let text = std::fs::read_to_string(path).map_err(|source| WorldError::Read {
            path: p.clone(),
            source,
        })?;
        let world: World = serde_json::from_str(&text).map_err(|source| WorldError::Parse {
            path: p.clone(),
            source,
        })?;
        world
            .validate()
            .map_err(|message| WorldError::Invalid { path: p, message })?;
        Ok(world)
    }

    fn validate(&self) -> Result<(), String> {
        let b = &self.bounds_m;
        if !(b.x[0] < b.x[1] && b.y[0] < b.y[1]) {
            return Err("bounds_m must have min < max on x and y".into());
        }
        if self.pole_radius_m < 0.0 || self.cylinders.iter().any(|c| c.radius_m <= 0.0) {
            return Err("obstacle radii must be positive (m)".into());
        }
        self.sensor.validate()
    }

    /// Start poses for `n` drones: the world's own list for that count, else spots on a 2 m
    /// grid, heading east, filled row by row from the centre of the bounds (x = +0, +2, +4 ...
    /// then -2, -4 ...; rows y = +0, +2, -2, +4 ...), skipping spots within 1 m of an obstacle.
    pub fn starts(&self, n: usize) -> Vec<(Vec2, f64)> {
        if let Some(list) = self.starts_xy_yaw.get(&n.to_string()) {
            if list.len() == n {
                return list
                    .iter()
                    .map(|[x, y, yaw]| (Vec2::new(*x, *y), *yaw))
                    .collect();
            }
        }
        let shapes = self.shapes();
        let b = &self.bounds_m;
        let (cx, cy) = ((b.x[0] + b.x[1]) / 2.0, (b.y[0] + b.y[1]) / 2.0);
        let steps = |lo: f64, hi: f64| {
            let up = (0..)
                .map(move |k| cx + 2.0 * f64::from(k))
                .take_while(move |v| *v < hi);
            let down = (1..)
                .map(move |k| cx - 2.0 * f64::from(k))
                .take_while(move |v| *v > lo);
            up.chain(down)
        };
        let rows = {
            let up = (1..)
                .map(|k| cy + 2.0 * f64::from(k))
                .take_while(|v| *v < b.y[1]);
            let down = (1..)
                .map(|k| cy - 2.0 * f64::from(k))
                .take_while(|v| *v > b.y[0]);
            std::iter::once(cy).chain(interleave(up, down))
        };
        let clear = |p: &Vec2| {
            let at = Vec3::new(p.x, p.y, 0.0);
            shapes
                .iter()
                .all(|s| s.distance_m(&at).is_none_or(|d| d >= 1.0))
        };
        let mut starts: Vec<(Vec2, f64)> = rows
            .flat_map(|y| steps(b.x[0], b.x[1]).map(move |x| Vec2::new(x, y)))
            .filter(clear)
            .take(n)
            .map(|p| (p, 0.0))
            .collect();
        // A world too crowded for its drones: keep counting along x rather than drop drones.
        while starts.len() < n {
            starts.push((Vec2::new(cx + 2.0 * starts.len() as f64, cy), 0.0));
        }
        starts
    }

    /// Every obstacle as one shape list (poles become cylinders).
    pub fn shapes(&self) -> Vec<Shape> {
        let poles = self.poles_xy_m.iter().map(|&[x, y]| Shape::Cylinder {
            center: Vec2::new(x, y),
            radius_m: self.pole_radius_m,
            height_m: self.pole_height_m,
        });
        let cylinders = self.cylinders.iter().map(|c| Shape::Cylinder {
            center: Vec2::new(c.xy_m[0], c.xy_m[1]),
            radius_m: c.radius_m,
            height_m: c.height_m,
        });
        let boxes = self.boxes.iter().map(|b| Shape::Box {
            center: Vec2::new(b.center_xy_m[0], b.center_xy_m[1]),
            half_size: Vec2::new(b.size_xy_m[0] / 2.0, b.size_xy_m[1] / 2.0),
            yaw_rad: b.yaw_rad,
            height_m: b.height_m,
        });
        poles.chain(cylinders).chain(boxes).collect()
    }
}

/// Alternates two sequences (a0, b0, a1, b1 ...), then finishes whichever is longer.
fn interleave<T>(
    a: impl Iterator<Item = T>,
    b: impl Iterator<Item = T>,
) -> impl Iterator<Item = T> {
    let (mut a, mut b) = (a.fuse(), b.fuse());
    let mut take_a = true;
    std::iter::from_fn(move || {
        let next = if take_a {
            a.next().or_else(|| b.next())
        } else {
            b.next().or_else(|| a.next())
        };
        take_a = !take_a;
        next
    })
}

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
    fn thesis_worlds_load_unchanged() {
        for name in ["low", "medium", "high"] {
            let path = Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("sitl/worlds")
                .join(format!("{name}.json"));
            let world = World::load(&path).unwrap();
            assert!(!world.poles_xy_m.is_empty(), "{name} has poles");
            assert_eq!(world.starts(7).len(), 7);
        }
        let low = World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/low.json"))
            .unwrap();
        let (p, yaw) = low.starts(2)[1];
        assert_eq!((p.x, p.y, yaw), (-19.78, 7.5, 3.47));
    }

    #[test]
    fn default_starts_fill_a_grid_clear_of_obstacles() {
        let empty = World::empty();
        let row: Vec<(f64, f64)> = empty.starts(3).iter().map(|(p, _)| (p.x, p.y)).collect();
        assert_eq!(row, [(0.0, 0.0), (2.0, 0.0), (4.0, 0.0)]);
        let mut small = World::empty();
        small.bounds_m = Bounds {
            x: [-3.0, 3.0],
            y: [-3.0, 3.0],
        };
        small.cylinders.push(Cylinder {
            xy_m: [2.0, 0.0],
            radius_m: 0.5,
            height_m: 5.0,
        });
        let spots: Vec<(f64, f64)> = small.starts(4).iter().map(|(p, _)| (p.x, p.y)).collect();
        assert_eq!(spots, [(0.0, 0.0), (-2.0, 0.0), (0.0, 2.0), (2.0, 2.0)]);
        let low = World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/low.json"))
            .unwrap();
        let shapes = low.shapes();
        for (p, _) in low.starts(10) {
            let at = Vec3::new(p.x, p.y, 0.0);
            assert!(shapes.iter().all(|s| s.distance_m(&at).unwrap() >= 1.0));
        }
    }

    #[test]
    fn extensions_add_boxes_cylinders_and_a_geodetic_origin() {
        let w: World = serde_json::from_str(
            r#"{"bounds_m": {"x": [-10, 10], "y": [-10, 10]}, "pole_radius_m": 0.2,
                "poles_xy_m": [[1, 1]],
                "cylinders": [{"xy_m": [5, 5], "radius_m": 1.0, "height_m": 20}],
                "boxes": [{"center_xy_m": [-5, 0], "size_xy_m": [2, 4], "yaw_rad": 0.5}],
                "geodetic_origin": {"lat_deg": 47.0, "lon_deg": 8.0, "alt_m": 400}}"#,
        )
        .unwrap();
        w.validate().unwrap();
        let shapes = w.shapes();
        assert_eq!(shapes.len(), 3, "pole, cylinder, box");
        assert!(matches!(shapes[2], Shape::Box { height_m, .. } if height_m == 10.0));
        assert_eq!(w.geodetic_origin.unwrap().alt_m, 400.0);
        let bad: World =
            serde_json::from_str(r#"{"bounds_m": {"x": [1, -1], "y": [0, 1]}}"#).unwrap();
        assert!(bad.validate().is_err());
    }

    #[test]
    fn a_sensor_kind_alone_takes_its_defaults() {
        let w: World = serde_json::from_str(
            r#"{"bounds_m": {"x": [0, 1], "y": [0, 1]}, "sensor": {"kind": "lidar360", "beams": 90}}"#,
        )
        .unwrap();
        assert_eq!(
            w.sensor,
            SensorConfig::Lidar360 {
                range_max_m: 10.0,
                rate_hz: 10.0,
                noise_std_m: 0.01,
                beams: 90
            }
        );
        assert_eq!(SensorConfig::by_name("lidar"), Some(SensorConfig::lidar()));
        assert!(SensorConfig::Lidar360 {
            range_max_m: 10.0,
            rate_hz: 0.0,
            noise_std_m: 0.0,
            beams: 1
        }
        .validate()
        .is_err());
    }

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
