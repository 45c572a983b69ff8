//! Coverage planning (placeholder while the module is written).
use nalgebra::{Vector2, Vector3};

/// Per-drone sweep paths.
#[derive(Debug, Clone, PartialEq)]
pub struct CoveragePlan {
    pub per_drone: Vec<Vec<Vector3<f64>>>,
    pub angle_rad: f64,
    pub lengths_m: Vec<f64>,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CoverageError {
    #[error("invalid polygon")]
    InvalidPolygon,
}

pub fn plan_coverage(
    _polygon_enu: &[Vector2<f64>],
    _street_spacing_m: f64,
    _angle: Option<f64>,
    _drone_starts: &[Vector2<f64>],
    _height_m: f64,
) -> Result<CoveragePlan, CoverageError> {
    Err(CoverageError::InvalidPolygon)
}
