//! Grid import and export: PNG, and the ROS `map_server` format (PGM image + YAML metadata).
//!
//! In: an [`OccupancyGrid`], or PGM bytes plus YAML text. Out: PNG bytes, PGM bytes plus YAML
//! text, or an [`OccupancyGrid`]. No file I/O: callers read and write the bytes.
//!
//! Image rows run north to south (row 0 is the grid's top, `y = height - 1`), as in ROS.
//! Export uses `map_saver`'s trinary encoding: free (`<= 25`) = 254, occupied (`>= 65`) = 0,
//! anything else including unknown = 205, with `occupied_thresh 0.65` and `free_thresh 0.196` in
//! the YAML (as ROS 1 `map_saver` writes: 205 reads back as occupancy 0.196, i.e. unknown).

use std::fmt::Write as _;

use nalgebra::Vector2;

use super::grid::{GridSpec, OccupancyGrid};
use super::MapError;

/// Occupancy (percent) at or above which a cell is exported as occupied.
pub const OCCUPIED_PERCENT: i8 = 65;
/// Occupancy (percent) at or below which a cell is exported as free.
pub const FREE_PERCENT: i8 = 25;

/// Pixels row-major, north row first.
fn pixels(grid: &OccupancyGrid, shade: impl Fn(i8) -> u8) -> Vec<u8> {
    let w = grid.spec().width_cells as usize;
    grid.data()
        .chunks(w.max(1))
        .rev()
        .flat_map(|row| row.iter().map(|&v| shade(v)))
        .collect()
}

impl OccupancyGrid {
    /// 8-bit greyscale PNG: free white, occupied black, occupancy in between as grey,
    /// unknown 205.
    pub fn to_png(&self) -> Result<Vec<u8>, MapError> {
        let data = pixels(self, |v| {
            if v < 0 {
                205
            } else {
                (255 - (i32::from(v) * 255 + 50) / 100) as u8
            }
        });
        let spec = self.spec();
        let mut out = Vec::new();
        let mut encoder = png::Encoder::new(&mut out, spec.width_cells, spec.height_cells);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        let mut writer = encoder
            .write_header()
            .map_err(|e| MapError::Image(e.to_string()))?;
        writer
            .write_image_data(&data)
            .map_err(|e| MapError::Image(e.to_string()))?;
        writer
            .finish()
            .map_err(|e| MapError::Image(e.to_string()))?;
        Ok(out)
    }

    /// The ROS `map_server` pair: binary PGM (P5) bytes and the YAML text naming `image_file`.
    pub fn to_pgm_yaml(&self, image_file: &str) -> (Vec<u8>, String) {
        let spec = self.spec();
        let mut pgm = format!(
            "P5\n# CREATOR: kestrel {:.3} m/pix\n{} {}\n255\n",
            spec.resolution_m, spec.width_cells, spec.height_cells
        )
        .into_bytes();
        pgm.extend(pixels(self, |v| {
            if v >= OCCUPIED_PERCENT {
                0
            } else if (0..=FREE_PERCENT).contains(&v) {
                254
            } else {
                205
            }
        }));
        let mut yaml = String::new();
        let _ = writeln!(yaml, "image: {image_file}");
        let _ = writeln!(yaml, "mode: trinary");
        let _ = writeln!(yaml, "resolution: {}", spec.resolution_m);
        let _ = writeln!(
            yaml,
            "origin: [{}, {}, 0.0]",
            spec.origin_enu_m.x, spec.origin_enu_m.y
        );
        let _ = writeln!(yaml, "negate: 0");
        let _ = writeln!(
            yaml,
            "occupied_thresh: {}",
            f64::from(OCCUPIED_PERCENT) / 100.0
        );
        let _ = writeln!(yaml, "free_thresh: 0.196");
        (pgm, yaml)
    }

    /// Loads a map in the ROS `map_server` format (PGM P5 or P2, 8-bit; YAML as written by
    /// `map_saver`). Modes `trinary` (default), `scale` and `raw` are supported; a non-zero
    /// origin yaw is refused.
    pub fn from_pgm_yaml(pgm: &[u8], yaml: &str) -> Result<OccupancyGrid, MapError> {
        let meta = RosMapMeta::parse(yaml)?;
        let (w, h, maxval, values) = parse_pgm(pgm)?;
        let spec = GridSpec {
            resolution_m: meta.resolution_m,
            width_cells: w,
            height_cells: h,
            origin_enu_m: meta.origin_m,
        };
        spec.validate()?;
        let w = w as usize;
        let mut data = Vec::with_capacity(values.len());
        // Image rows are north first; grid rows are south first.
        for row in values.chunks(w).rev() {
            for &v in row {
                data.push(meta.occupancy(v, maxval));
            }
        }
        OccupancyGrid::from_data(spec, data)
    }
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum RosMode {
    Trinary,
    Scale,
    Raw,
}

#[derive(Debug, Clone, Copy)]
struct RosMapMeta {
    resolution_m: f64,
    origin_m: Vector2<f64>,
    negate: bool,
    occupied_thresh: f64,
    free_thresh: f64,
    mode: RosMode,
}

impl RosMapMeta {
    fn parse(yaml: &str) -> Result<Self, MapError> {
        let bad = |what: String| MapError::RosMap(what);
        let mut resolution = None;
        let mut origin = None;
        let mut meta = RosMapMeta {
            resolution_m: 0.0,
            origin_m: Vector2::zeros(),
            negate: false,
            occupied_thresh: 0.65,
            free_thresh: 0.196,
            mode: RosMode::Trinary,
        };
        for line in yaml.lines() {
            let line = line.split('#').next().unwrap_or("").trim();
            let Some((key, value)) = line.split_once(':') else {
                continue;
            };
            let value = value.trim().trim_matches(|c| c == '"' || c == '\'');
            let num = |v: &str| {
                v.trim()
                    .parse::<f64>()
                    .map_err(|_| bad(format!("{key}: not a number: {v}")))
            };
            match key.trim() {
                "resolution" => resolution = Some(num(value)?),
                "origin" => {
                    let inner = value.trim_start_matches('[').trim_end_matches(']');
                    let parts = inner.split(',').map(num).collect::<Result<Vec<_>, _>>()?;
                    match parts.as_slice() {
                        [x, y] => origin = Some(Vector2::new(*x, *y)),
                        [x, y, yaw] if *yaw == 0.0 => origin = Some(Vector2::new(*x, *y)),
                        [_, _, yaw] => return Err(bad(format!("origin yaw {yaw} unsupported"))),
                        _ => return Err(bad(format!("origin: expected [x, y, yaw]: {value}"))),
                    }
                }
                "negate" => meta.negate = num(value)? != 0.0,
                "occupied_thresh" => meta.occupied_thresh = num(value)?,
                "free_thresh" => meta.free_thresh = num(value)?,
                "mode" => {
                    meta.mode = match value {
                        "trinary" => RosMode::Trinary,
                        "scale" => RosMode::Scale,
                        "raw" => RosMode::Raw,
                        other => return Err(bad(format!("unknown mode {other}"))),
                    }
                }
                _ => {}
            }
        }
        meta.resolution_m = resolution.ok_or_else(|| bad("missing resolution".into()))?;
        meta.origin_m = origin.ok_or_else(|| bad("missing origin".into()))?;
        if !(0.0..=1.0).contains(&meta.free_thresh)
            || !(0.0..=1.0).contains(&meta.occupied_thresh)
            || meta.free_thresh >= meta.occupied_thresh
        {
            return Err(bad("need 0 <= free_thresh < occupied_thresh <= 1".into()));
        }
        Ok(meta)
    }

    /// One pixel to a cell value, as `map_server` does.
    fn occupancy(&self, v: u8, maxval: u8) -> i8 {
        if self.mode == RosMode::Raw {
            return if v <= 100 { v as i8 } else { -1 };
        }
        let shade = f64::from(v) / f64::from(maxval);
        let occ = if self.negate { shade } else { 1.0 - shade };
        if occ > self.occupied_thresh {
            100
        } else if occ < self.free_thresh {
            0
        } else if self.mode == RosMode::Scale {
            let s = (occ - self.free_thresh) / (self.occupied_thresh - self.free_thresh);
            (99.0 * s).round() as i8
        } else {
            -1
        }
    }
}

/// Parses an 8-bit PGM (P5 binary or P2 ASCII): width, height, maxval, pixels.
fn parse_pgm(bytes: &[u8]) -> Result<(u32, u32, u8, Vec<u8>), MapError> {
    let bad = |what: &str| MapError::RosMap(format!("PGM: {what}"));
    let mut pos = 0;
    // Header tokens, skipping whitespace and `#` comments.
    let next_token = |pos: &mut usize| -> Option<String> {
        loop {
            match bytes.get(*pos) {
                Some(b'#') => {
                    while bytes.get(*pos).is_some_and(|&b| b != b'\n') {
                        *pos += 1;
                    }
                }
                Some(b) if b.is_ascii_whitespace() => *pos += 1,
                Some(_) => break,
                None => return None,
            }
        }
        let start = *pos;
        while bytes.get(*pos).is_some_and(|b| !b.is_ascii_whitespace()) {
            *pos += 1;
        }
        std::str::from_utf8(bytes.get(start..*pos)?)
            .ok()
            .map(str::to_owned)
    };
    let magic = next_token(&mut pos).ok_or_else(|| bad("empty"))?;
    let num = |pos: &mut usize| -> Result<u32, MapError> {
        next_token(pos)
            .and_then(|t| t.parse().ok())
            .ok_or_else(|| bad("bad header number"))
    };
    let w = num(&mut pos)?;
    let h = num(&mut pos)?;
    let maxval = num(&mut pos)?;
    if maxval == 0 || maxval > 255 {
        return Err(bad("only 8-bit PGM is supported"));
    }
    // Bounded before anything is allocated with it (a header is a few bytes, the size is not).
    let cells = u64::from(w) * u64::from(h);
    if cells == 0 || cells > super::grid::MAX_CELLS {
        return Err(bad(&format!(
            "{w} x {h} pixels: a map has 1..={} cells",
            super::grid::MAX_CELLS
        )));
    }
    let n = usize::try_from(cells).map_err(|_| bad("size overflow"))?;
    let values = match magic.as_str() {
        "P5" => {
            // Exactly one whitespace byte separates maxval from the raster.
            let start = pos + 1;
            let raster = bytes
                .get(start..start.saturating_add(n))
                .ok_or_else(|| bad("truncated raster"))?;
            raster.to_vec()
        }
        "P2" => {
            // An ASCII pixel takes two bytes at least: the file bounds what is reserved.
            let mut v = Vec::with_capacity(n.min(bytes.len() / 2));
            for _ in 0..n {
                let x = num(&mut pos)?;
                v.push(u8::try_from(x).map_err(|_| bad("pixel above 255"))?);
            }
            v
        }
        _ => return Err(bad("not a P5 or P2 PGM")),
    };
    Ok((w, h, maxval as u8, values))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::grid::Cell;

    fn grid() -> OccupancyGrid {
        let spec = GridSpec {
            resolution_m: 0.05,
            width_cells: 3,
            height_cells: 2,
            origin_enu_m: Vector2::new(-1.5, 2.0),
        };
        // South row: free, occupied, unknown; north row: 10, 50, 90.
        OccupancyGrid::from_data(spec, vec![0, 100, -1, 10, 50, 90]).unwrap()
    }

    #[test]
    fn a_pgm_header_with_a_huge_size_is_refused_before_allocating() {
        for header in [
            "P2 4000000000 4000000000 255 0",
            "P5 100000 100000 255 ",
            "P2 0 5 255",
        ] {
            let e = parse_pgm(header.as_bytes()).unwrap_err().to_string();
            assert!(e.contains("cells"), "{header}: {e}");
        }
    }

    #[test]
    fn pgm_rows_are_north_first_with_trinary_values() {
        let (pgm, yaml) = grid().to_pgm_yaml("map.pgm");
        let header = b"P5\n# CREATOR: kestrel 0.050 m/pix\n3 2\n255\n";
        assert_eq!(&pgm[..header.len()], header);
        assert_eq!(&pgm[header.len()..], &[254, 205, 0, 254, 0, 205]);
        assert!(yaml.contains("image: map.pgm"));
        assert!(yaml.contains("origin: [-1.5, 2, 0.0]"));
    }

    #[test]
    fn ros_map_round_trip_keeps_free_occupied_unknown() {
        let (pgm, yaml) = grid().to_pgm_yaml("map.pgm");
        let back = OccupancyGrid::from_pgm_yaml(&pgm, &yaml).unwrap();
        assert_eq!(back.spec(), grid().spec());
        assert_eq!(back.data(), &[0, 100, -1, 0, -1, 100]);
    }

    #[test]
    fn loads_ascii_pgm_with_comments_and_scale_mode() {
        let pgm = b"P2\n# made by hand\n2 1\n255\n0 128\n";
        let yaml = "image: x.pgm\nresolution: 0.1\norigin: [0.0, 0.0, 0.0]\nnegate: 0\n\
                    occupied_thresh: 0.65\nfree_thresh: 0.196\nmode: scale\n";
        let g = OccupancyGrid::from_pgm_yaml(pgm, yaml).unwrap();
        // occ(128) = 1 - 128/255 = 0.498 -> 99 * (0.498 - 0.196) / (0.65 - 0.196) = 65.9 -> 66.
        assert_eq!(g.data(), &[100, 66]);
        assert_eq!(g.get(Cell { x: 1, y: 0 }), Some(66));
    }

    #[test]
    fn bad_ros_maps_are_typed_errors() {
        let yaml = "resolution: 0.1\norigin: [0.0, 0.0, 0.5]\n";
        assert!(matches!(
            OccupancyGrid::from_pgm_yaml(b"P5\n1 1\n255\n\0", yaml),
            Err(MapError::RosMap(_))
        ));
        let yaml = "resolution: 0.1\norigin: [0.0, 0.0, 0.0]\n";
        assert!(OccupancyGrid::from_pgm_yaml(b"P5\n2 2\n255\n\0", yaml).is_err());
        assert!(OccupancyGrid::from_pgm_yaml(b"P6\n1 1\n255\n\0\0\0", yaml).is_err());
    }

    #[test]
    fn png_has_signature_and_decodes_to_grid_shades() {
        let bytes = grid().to_png().unwrap();
        let decoder = png::Decoder::new(bytes.as_slice());
        let mut reader = decoder.read_info().unwrap();
        let mut buf = vec![0; reader.output_buffer_size()];
        let info = reader.next_frame(&mut buf).unwrap();
        assert_eq!((info.width, info.height), (3, 2));
        // North row (10, 50, 90) then south row (0, 100, unknown).
        assert_eq!(&buf[..6], &[229, 127, 25, 255, 0, 205]);
    }
}
