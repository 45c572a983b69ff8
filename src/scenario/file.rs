//! Scenario files: the frames a mission needs and the mission to fly, for `kestrel sim
//! --scenario` and `kestrel mission validate|run --scenario`.
//!
//! In: a JSON file `{"description", "frames": [FrameRegistration..], "mission": "file.json",
//! "drones": N, "coverage": {..}}` (the mission path is relative to the scenario file). Out:
//! [`Scenario`]. One drone flies `mission`; several split `coverage` among them
//! ([`super::coverage`]).

use crate::host::FrameRegistration;
use serde::Deserialize;
use std::path::{Path, PathBuf};

#[derive(Debug, Clone, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Scenario {
    #[serde(default)]
    pub description: String,
    #[serde(default)]
    pub frames: Vec<FrameRegistration>,
    /// Mission file, relative to the scenario file.
    #[serde(default)]
    pub mission: Option<PathBuf>,
    /// Drones the scenario needs (at least).
    #[serde(default)]
    pub drones: Option<usize>,
    /// An area to sweep: with several drones (or no `mission`) it is split among them.
    #[serde(default)]
    pub coverage: Option<super::coverage::CoverageSpec>,
}

impl Scenario {
    /// The coverage to split among `drones` drones, when this scenario flies that way: it has
    /// a `coverage` section and either several drones or no single-drone `mission`.
    pub fn split_coverage(&self, drones: usize) -> Option<&super::coverage::CoverageSpec> {
        self.coverage
            .as_ref()
            .filter(|_| drones > 1 || self.mission.is_none())
    }
}

#[derive(Debug, thiserror::Error)]
pub enum ScenarioError {
    #[error("cannot read scenario {path}: {source}")]
    Read {
        path: String,
        source: std::io::Error,
    },
    #[error("scenario {path}: {message}")]
    Parse { path: String, message: String },
}

impl Scenario {
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|source| ScenarioError::Read {
            path: path.display().to_string(),
            source,
        })?;
        let mut s: Scenario = serde_json::from_str(&text).map_err(|e| ScenarioError::Parse {
            path: path.display().to_string(),
            message: e.to_string(),
        })?;
        if let (Some(m), Some(dir)) = (&s.mission, path.parent()) {
            s.mission = Some(dir.join(m));
        }
        Ok(s)
    }
}
