//! World files: bounds, obstacles, start poses and sensors for the simulators.
//!
//! The base layout is the thesis's exploration worlds, read unchanged (`bounds_m`,
//! `pole_radius_m`, `poles_xy_m`, `starts_xy_yaw` keyed by drone count). Optional extensions in
//! the same JSON object: `cylinders`, `boxes`, `sensor`, `geodetic_origin`, `pole_height_m`.
//! The Python fake autopilot in `sitl/` reads the same files, and `kestrel run --virtual-world`
//! casts real vehicles' range sensors against them (`sim::virtual_world`), so a file is bounded
//! ([`MAX_WORLD_BYTES`], [`MAX_SHAPES`]) and every number checked, the error naming the field.

pub use super::shape::Shape;
use crate::types::{GeoPoint, SensorConfig, SensorError};
use crate::types::{Vec2, Vec3};
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::io::Read;
use std::path::Path;

/// Largest world file read (bytes); the thesis's densest world is 19 kB.
pub const MAX_WORLD_BYTES: u64 = 16 << 20;
/// Most obstacles (poles, cylinders and boxes together) in one world.
pub const MAX_SHAPES: usize = 100_000;
/// Largest extent of a world along x or y, and largest obstacle size (m).
const MAX_EXTENT_M: f64 = 100_000.0;

#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Bounds {
    /// [min, max] east (m).
    pub x: [f64; 2],
    /// [min, max] north (m).
    pub y: [f64; 2],
}

impl Bounds {
    /// The (min, max) corners (ENU, m).
    pub fn corners(&self) -> (Vec2, Vec2) {
        (
            Vec2::new(self.x[0], self.y[0]),
            Vec2::new(self.x[1], self.y[1]),
        )
    }
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
    #[error("world file {path} is {size} bytes, more than the {max} read")]
    TooLarge { path: String, size: u64, max: u64 },
    #[error("world file {path} is not valid: {source}")]
    Parse {
        path: String,
        source: serde_json::Error,
    },
    #[error("world file {path}: {rule}")]
    Invalid { path: String, rule: WorldRule },
}

/// A number of a world file out of its range, or one obstacle too many; the words start with
/// the field (`cylinders[2].radius_m`).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum WorldRule {
    #[error("bounds_m must have min < max on x and y")]
    BoundsOrder,
    #[error("{0} obstacles (poles_xy_m, cylinders, boxes), at most {MAX_SHAPES}")]
    TooManyShapes(usize),
    #[error("{field} must be finite and within {MAX_EXTENT_M} m, got {values:?}")]
    Coordinates { field: String, values: Vec<f64> },
    #[error(
        "{field} must be {} and at most {MAX_EXTENT_M} m, got {value}",
        if *zero_ok { "0 or more" } else { "above 0" }
    )]
    Size {
        field: String,
        value: f64,
        zero_ok: bool,
    },
    #[error(transparent)]
    Sensor(#[from] SensorError),
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

    /// Reads, parses and checks a world file, refusing one over [`MAX_WORLD_BYTES`] before
    /// reading it; every error names the file (and the field, for a value out of range).
    pub fn load(path: &Path) -> Result<Self, WorldError> {
        let p = path.display().to_string();
        let read = |source| WorldError::Read {
            path: p.clone(),
            source,
        };
        let file = std::fs::File::open(path).map_err(read)?;
        let size = file.metadata().map_err(read)?.len();
        let too_large = |size| WorldError::TooLarge {
            path: p.clone(),
            size,
            max: MAX_WORLD_BYTES,
        };
        if size > MAX_WORLD_BYTES {
            return Err(too_large(size));
        }
        // The file may grow between the check and the read: never read past the limit.
        let mut text = String::new();
        file.take(MAX_WORLD_BYTES + 1)
            .read_to_string(&mut text)
            .map_err(read)?;
        if text.len() as u64 > MAX_WORLD_BYTES {
            return Err(too_large(text.len() as u64));
        }
        let world: World = serde_json::from_str(&text).map_err(|source| WorldError::Parse {
            path: p.clone(),
            source,
        })?;
        world
            .validate()
            .map_err(|rule| WorldError::Invalid { path: p, rule })?;
        Ok(world)
    }

    /// Every number finite and in range, at most [`MAX_SHAPES`] obstacles; the message starts
    /// with the field (`cylinders[2].radius_m`).
    fn validate(&self) -> Result<(), WorldRule> {
        let b = &self.bounds_m;
        if !(b.x[0] < b.x[1] && b.y[0] < b.y[1]) {
            return Err(WorldRule::BoundsOrder);
        }
        let shapes = self.poles_xy_m.len() + self.cylinders.len() + self.boxes.len();
        if shapes > MAX_SHAPES {
            return Err(WorldRule::TooManyShapes(shapes));
        }
        let coordinates = |field: &str, values: &[f64]| match values
            .iter()
            .all(|v| v.is_finite() && v.abs() <= MAX_EXTENT_M)
        {
            true => Ok(()),
            false => Err(WorldRule::Coordinates {
                field: field.to_string(),
                values: values.to_vec(),
            }),
        };
        let size = |field: &str, value: f64, zero_ok: bool| {
            let above = if zero_ok { value >= 0.0 } else { value > 0.0 };
            match above && value <= MAX_EXTENT_M {
                true => Ok(()),
                false => Err(WorldRule::Size {
                    field: field.to_string(),
                    value,
                    zero_ok,
                }),
            }
        };
        coordinates("bounds_m", &[b.x[0], b.x[1], b.y[0], b.y[1]])?;
        size("pole_radius_m", self.pole_radius_m, true)?;
        size("pole_height_m", self.pole_height_m, false)?;
        for (i, xy) in self.poles_xy_m.iter().enumerate() {
            coordinates(&format!("poles_xy_m[{i}]"), xy)?;
        }
        for (i, c) in self.cylinders.iter().enumerate() {
            coordinates(&format!("cylinders[{i}].xy_m"), &c.xy_m)?;
            size(&format!("cylinders[{i}].radius_m"), c.radius_m, false)?;
            size(&format!("cylinders[{i}].height_m"), c.height_m, false)?;
        }
        for (i, x) in self.boxes.iter().enumerate() {
            coordinates(&format!("boxes[{i}].center_xy_m"), &x.center_xy_m)?;
            coordinates(&format!("boxes[{i}].yaw_rad"), &[x.yaw_rad])?;
            for s in x.size_xy_m {
                size(&format!("boxes[{i}].size_xy_m"), s, false)?;
            }
            size(&format!("boxes[{i}].height_m"), x.height_m, false)?;
        }
        for (n, list) in &self.starts_xy_yaw {
            for (i, s) in list.iter().enumerate() {
                coordinates(&format!("starts_xy_yaw.{n}[{i}]"), s)?;
            }
        }
        Ok(self.sensor.validate()?)
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
    fn bad_values_are_refused_naming_the_field_and_the_file() {
        let refusal = |extra: &str| {
            let text = format!(r#"{{"bounds_m": {{"x": [-5, 5], "y": [-5, 5]}}, {extra}}}"#);
            serde_json::from_str::<World>(&text)
                .unwrap()
                .validate()
                .unwrap_err()
                .to_string()
        };
        let m = refusal(
            r#""cylinders": [{"xy_m": [1, 1], "radius_m": 1}, {"xy_m": [2, 2], "radius_m": -1}]"#,
        );
        assert!(m.starts_with("cylinders[1].radius_m"), "{m}");
        let m = refusal(r#""poles_xy_m": [[0, 0], [1e300, 0]]"#);
        assert!(m.starts_with("poles_xy_m[1]"), "{m}");
        let m = refusal(r#""boxes": [{"center_xy_m": [0, 0], "size_xy_m": [0, 1]}]"#);
        assert!(m.starts_with("boxes[0].size_xy_m"), "{m}");
        let m = refusal(r#""sensor": {"kind": "lidar360", "beams": 100000}"#);
        assert!(m.starts_with("sensor.beams"), "{m}");

        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("w.json");
        std::fs::write(
            &path,
            r#"{"bounds_m": {"x": [0, 1], "y": [0, 1]}, "pole_radius_m": -1}"#,
        )
        .unwrap();
        let e = World::load(&path).unwrap_err().to_string();
        assert!(e.contains(&path.display().to_string()), "{e}");
        assert!(e.contains("pole_radius_m"), "{e}");
        let f = std::fs::File::create(&path).unwrap();
        f.set_len(MAX_WORLD_BYTES + 1).unwrap();
        let e = World::load(&path).unwrap_err();
        assert!(matches!(e, WorldError::TooLarge { .. }), "{e}");
        let e = World::load(&dir.path().join("missing.json"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.json"), "{e}");
    }
}
