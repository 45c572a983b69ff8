//! The `[map]` config section: which mapping plugin, the grid's geometry, how scans update it,
//! and the known map and graph files to start from.
//!
//! In: a [`MapSection`] (raw TOML), the config file's folder for [`MapSection::load_files`],
//! and optionally the simulator world's bounds. Out: a validated [`MapConfig`] shared by every
//! drone's [`super::server::MapServer`] and the host's merged map; `None` when mapping is off.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Duration;

use nalgebra::Vector2;
use serde::{Deserialize, Serialize};

use super::graph::TopoGraph;
use super::grid::DEFAULT_OCCUPIED_THRESHOLD;
use super::grid::{GridSpec, InsertParams, OccupancyGrid};
use super::layers::FuseRule;
use super::MapError;

/// Bounds of `[map] update_rate_hz` (Hz).
const MIN_UPDATE_RATE_HZ: f64 = 0.01;
const MAX_UPDATE_RATE_HZ: f64 = 100.0;

/// Which mapping plugin builds the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum MapPlugin {
    /// Ray-casts every range scan into a 2D occupancy grid (Aerostack2's `scan2occ_grid`).
    #[default]
    Scan2occGrid,
    /// No mapping: scans are ignored and `navigate_to` is unavailable.
    None,
}

/// The `[map]` config section as written.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MapSection {
    pub plugin: MapPlugin,
    /// Cell edge (m, > 0).
    pub resolution_m: f64,
    /// Extent [east, north] (m); absent = the simulator world's bounds plus 2 m, else 40 x 40.
    pub size_m: Option<[f64; 2]>,
    /// ENU position of the grid's south-west corner (m); absent = the extent centred on the
    /// world (simulator) or on the `earth` origin.
    pub origin_enu_m: Option<[f64; 2]>,
    /// Added to a cell at a beam's end (0..=100).
    pub hit_confidence: u8,
    /// Subtracted from a cell a beam crosses (0..=100).
    pub miss_confidence: u8,
    /// Readings are clipped to this range (m); absent = each sensor's own maximum.
    pub max_range_m: Option<f64>,
    /// Cells above this value stay occupied for ever (Aerostack2: 80); absent = never.
    pub lock_above: Option<u8>,
    /// Cells at or above this occupancy (0..=100) are obstacles for planning.
    pub occupied_threshold: i8,
    /// A beam without a return clears occupied cells too, and what is behind them (false: it
    /// stops before them, since a dropped reading looks like an open view).
    pub no_return_clears_occupied: bool,
    /// A known map in the ROS `map_server` format (the YAML file; its `image` is read beside
    /// it), relative to the config file. It sets the grid's geometry (`size_m` and
    /// `origin_enu_m` must then be absent) and its cells are where every drone starts from.
    pub known_map: Option<PathBuf>,
    /// A topological graph (JSON, `TopoGraph`) for the `graph_a_star` planner.
    pub graph: Option<PathBuf>,
    /// How drones' layers fuse into the merged map.
    pub fuse: FuseRule,
    /// Most `map_update` WebSocket messages per second (Hz, 0.01..=100).
    pub update_rate_hz: f64,
    /// Files named above, loaded by [`MapSection::load_files`].
    #[serde(skip)]
    pub loaded: LoadedFiles,
}

/// The known map and graph a [`MapSection`] names, once read.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct LoadedFiles {
    pub known_map: Option<Arc<OccupancyGrid>>,
    pub graph: Option<Arc<TopoGraph>>,
}

/// Extent used when neither the config nor a world gives one (m).
const DEFAULT_SIZE_M: f64 = 40.0;
/// Margin added around a simulator world's bounds (m).
const WORLD_MARGIN_M: f64 = 2.0;

impl Default for MapSection {
    fn default() -> Self {
        let p = InsertParams::default();
        MapSection {
            plugin: MapPlugin::default(),
            resolution_m: 0.1,
            size_m: None,
            origin_enu_m: None,
            hit_confidence: p.hit_confidence,
            miss_confidence: p.miss_confidence,
            max_range_m: None,
            lock_above: None,
            occupied_threshold: DEFAULT_OCCUPIED_THRESHOLD,
            no_return_clears_occupied: false,
            known_map: None,
            graph: None,
            fuse: FuseRule::default(),
            update_rate_hz: 2.0,
            loaded: LoadedFiles::default(),
        }
    }
}

impl MapSection {
    /// Checks numbers; the error names the field (`map.<field>`) and the problem.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let field = |f: &str, m: String| (format!("map.{f}"), m);
        if !(self.resolution_m.is_finite() && self.resolution_m > 0.0) {
            return Err(field("resolution_m", "must be > 0 (m)".into()));
        }
        if let Some([w, h]) = self.size_m {
            if !(w.is_finite() && h.is_finite() && w > 0.0 && h > 0.0) {
                return Err(field("size_m", "must be two positive lengths (m)".into()));
            }
        }
        if self
            .origin_enu_m
            .is_some_and(|o| o.iter().any(|v| !v.is_finite()))
        {
            return Err(field("origin_enu_m", "must be finite (m)".into()));
        }
        if self.hit_confidence > 100 || self.miss_confidence > 100 {
            return Err(field("hit_confidence", "confidences are 0..=100".into()));
        }
        if self.lock_above.is_some_and(|l| l > 100) {
            return Err(field("lock_above", "must be 0..=100".into()));
        }
        if self
            .max_range_m
            .is_some_and(|r| !(r.is_finite() && r > 0.0))
        {
            return Err(field("max_range_m", "must be > 0 (m)".into()));
        }
        if !(0..=100).contains(&self.occupied_threshold) {
            return Err(field("occupied_threshold", "must be 0..=100".into()));
        }
        if self.known_map.is_some() && (self.size_m.is_some() || self.origin_enu_m.is_some()) {
            return Err(field(
                "known_map",
                "sets the grid geometry: remove size_m and origin_enu_m".into(),
            ));
        }
        // Bounded below too: its period becomes a `Duration`, which 1 / 1e-300 s overflows.
        if !(MIN_UPDATE_RATE_HZ..=MAX_UPDATE_RATE_HZ).contains(&self.update_rate_hz) {
            return Err(field(
                "update_rate_hz",
                format!(
                    "must be within {MIN_UPDATE_RATE_HZ}..={MAX_UPDATE_RATE_HZ} (Hz), got {}",
                    self.update_rate_hz
                ),
            ));
        }
        Ok(())
    }

    /// Reads the known map and graph files, relative to `base_dir` (the config file's folder).
    pub fn load_files(&mut self, base_dir: &Path) -> Result<(), MapError> {
        if let Some(yaml_path) = &self.known_map {
            let grid = load_ros_map(&base_dir.join(yaml_path))?;
            self.loaded.known_map = Some(Arc::new(grid));
        }
        if let Some(graph_path) = &self.graph {
            let path = base_dir.join(graph_path);
            let text = std::fs::read_to_string(&path)
                .map_err(|e| MapError::Graph(format!("{}: {e}", path.display())))?;
            self.loaded.graph = Some(Arc::new(TopoGraph::from_json(&text)?));
        }
        Ok(())
    }

    /// The validated map configuration, `None` when mapping is off. `world_bounds` (min and max
    /// corners, ENU m) frame the grid when the section gives no extent.
    pub fn config(
        &self,
        world_bounds: Option<(Vector2<f64>, Vector2<f64>)>,
    ) -> Result<Option<MapConfig>, MapError> {
        if self.plugin == MapPlugin::None {
            return Ok(None);
        }
        let params = InsertParams {
            hit_confidence: self.hit_confidence,
            miss_confidence: self.miss_confidence,
            max_range_m: self.max_range_m,
            lock_above: self.lock_above,
            no_return_stops_at: (!self.no_return_clears_occupied)
                .then_some(self.occupied_threshold.max(0) as u8),
        };
        let initial = match &self.loaded.known_map {
            Some(known) => known.clone(),
            None => Arc::new(OccupancyGrid::new(self.spec(world_bounds))?),
        };
        Ok(Some(MapConfig {
            initial,
            params,
            occupied_threshold: self.occupied_threshold,
            graph: self.loaded.graph.clone(),
            fuse: self.fuse,
            update_period: Duration::from_secs_f64(1.0 / self.update_rate_hz),
        }))
    }

    fn spec(&self, world_bounds: Option<(Vector2<f64>, Vector2<f64>)>) -> GridSpec {
        let (size, centre) = match (self.size_m, world_bounds) {
            (Some([w, h]), bounds) => (
                Vector2::new(w, h),
                bounds.map_or(Vector2::zeros(), |(lo, hi)| (lo + hi) / 2.0),
            ),
            (None, Some((lo, hi))) => (
                hi - lo + Vector2::repeat(2.0 * WORLD_MARGIN_M),
                (lo + hi) / 2.0,
            ),
            (None, None) => (Vector2::repeat(DEFAULT_SIZE_M), Vector2::zeros()),
        };
        let origin = self
            .origin_enu_m
            .map_or(centre - size / 2.0, |[x, y]| Vector2::new(x, y));
        let cells = |m: f64| (m / self.resolution_m).ceil().max(1.0) as u32;
        GridSpec {
            resolution_m: self.resolution_m,
            width_cells: cells(size.x),
            height_cells: cells(size.y),
            origin_enu_m: origin,
        }
    }
}

/// Reads a ROS `map_server` YAML and the image it names (relative to the YAML's folder).
pub fn load_ros_map(yaml_path: &Path) -> Result<OccupancyGrid, MapError> {
    let bad = |what: String| MapError::RosMap(format!("{}: {what}", yaml_path.display()));
    let yaml = std::fs::read_to_string(yaml_path).map_err(|e| bad(e.to_string()))?;
    let image = yaml
        .lines()
        .filter_map(|l| l.split('#').next()?.trim().strip_prefix("image:"))
        .map(|v| v.trim().trim_matches(|c| c == '"' || c == '\''))
        .next()
        .ok_or_else(|| bad("no `image:` entry".into()))?;
    let image_path = yaml_path.parent().unwrap_or(Path::new(".")).join(image);
    let pgm = std::fs::read(&image_path)
        .map_err(|e| bad(format!("image {}: {e}", image_path.display())))?;
    OccupancyGrid::from_pgm_yaml(&pgm, &yaml)
}

/// Validated mapping settings shared by every drone of a host.
#[derive(Debug, Clone, PartialEq)]
pub struct MapConfig {
    /// The grid every drone starts from: the known map, or all unknown.
    pub initial: Arc<OccupancyGrid>,
    pub params: InsertParams,
    pub occupied_threshold: i8,
    pub graph: Option<Arc<TopoGraph>>,
    pub fuse: FuseRule,
    /// Shortest time between two map updates sent to clients.
    pub update_period: Duration,
}

impl MapConfig {
    /// The default section's configuration: a 40 m x 40 m all-unknown grid at 0.1 m centred on
    /// the `earth` origin.
    pub fn open_field() -> Result<MapConfig, MapError> {
        MapSection::default()
            .config(None)?
            .ok_or_else(|| MapError::InvalidSpec("mapping is off by default".into()))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mapping::graph::{GraphEdge, GraphNode};
    use crate::mapping::Cell;
    use nalgebra::Vector3;

    #[test]
    fn update_rates_whose_period_overflows_a_duration_are_refused() {
        // Found writing the config fuzz target (fuzz/corpus/config/map_update_rate_tiny.toml):
        // validation passed, then `config` panicked in Duration::from_secs_f64(1e300).
        for rate in [1e-300, 0.001, 0.0, -1.0, f64::NAN, f64::INFINITY, 1e6] {
            let s = MapSection {
                update_rate_hz: rate,
                ..MapSection::default()
            };
            let (field, _) = s.validate().unwrap_err();
            assert_eq!(field, "map.update_rate_hz", "{rate}");
        }
        for rate in [0.01, 2.0, 100.0] {
            let s = MapSection {
                update_rate_hz: rate,
                ..MapSection::default()
            };
            s.validate().unwrap();
            assert!(s.config(None).unwrap().is_some());
        }
    }

    #[test]
    fn the_extent_follows_the_world_unless_the_section_gives_one() {
        let s = MapSection::default();
        let world = (Vector2::new(0.0, 0.0), Vector2::new(20.0, 10.0));
        let c = s.config(Some(world)).unwrap().unwrap();
        let spec = c.initial.spec();
        assert_eq!((spec.width_cells, spec.height_cells), (240, 140));
        assert_eq!(spec.origin_enu_m, Vector2::new(-2.0, -2.0));
        let open = MapConfig::open_field().unwrap();
        assert_eq!(open.initial.spec().origin_enu_m, Vector2::new(-20.0, -20.0));
        let off = MapSection {
            plugin: MapPlugin::None,
            ..MapSection::default()
        };
        assert_eq!(off.config(None).unwrap(), None);
    }

    #[test]
    fn bad_numbers_name_their_field() {
        let bad = MapSection {
            resolution_m: 0.0,
            ..MapSection::default()
        };
        assert_eq!(bad.validate().unwrap_err().0, "map.resolution_m");
        let both = MapSection {
            known_map: Some("m.yaml".into()),
            size_m: Some([10.0, 10.0]),
            ..MapSection::default()
        };
        assert_eq!(both.validate().unwrap_err().0, "map.known_map");
    }

    #[test]
    fn a_known_map_and_a_graph_are_loaded_beside_the_config() {
        let dir = tempfile::tempdir().unwrap();
        let mut grid = MapConfig::open_field().unwrap().initial.as_ref().clone();
        grid.set(Cell { x: 3, y: 4 }, 100).unwrap();
        grid.set(Cell { x: 5, y: 5 }, 0).unwrap();
        let (pgm, yaml) = grid.to_pgm_yaml("site.pgm");
        std::fs::write(dir.path().join("site.pgm"), pgm).unwrap();
        std::fs::write(dir.path().join("site.yaml"), yaml).unwrap();
        let node = |id: &str, x: f64| GraphNode {
            id: id.into(),
            position_enu_m: Vector3::new(x, 0.0, 1.0),
        };
        let graph = TopoGraph::new(
            vec![node("a", 0.0), node("b", 5.0)],
            vec![GraphEdge {
                from: "a".into(),
                to: "b".into(),
                weight: 5.0,
            }],
        )
        .unwrap();
        std::fs::write(dir.path().join("graph.json"), graph.to_json()).unwrap();
        let mut s = MapSection {
            known_map: Some("site.yaml".into()),
            graph: Some("graph.json".into()),
            ..MapSection::default()
        };
        s.load_files(dir.path()).unwrap();
        let c = s.config(None).unwrap().unwrap();
        assert_eq!(c.initial.get(Cell { x: 3, y: 4 }), Some(100));
        assert_eq!(c.initial.get(Cell { x: 5, y: 5 }), Some(0));
        assert_eq!(c.initial.get(Cell { x: 6, y: 6 }), Some(-1));
        assert_eq!(c.graph.as_deref(), Some(&graph));
        let missing = MapSection {
            known_map: Some("nope.yaml".into()),
            ..MapSection::default()
        };
        assert!(matches!(
            missing.clone().load_files(dir.path()),
            Err(MapError::RosMap(_))
        ));
    }
}
