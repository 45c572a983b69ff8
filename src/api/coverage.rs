//! `POST /api/coverage`: a polygon swept by several drones, one boustrophedon piece each.
//!
//! In: `{"polygon_enu_m": [[x, y], ..], "street_spacing_m": 5, "angle_deg": null,
//! "drones": ["drone_0", ..], "height_m": 10}` (ENU `earth`, metres, degrees CCW from east;
//! null angle = across the polygon's narrowest direction). The drones' current positions decide
//! who flies which piece. Out: `{"angle_deg", "per_drone": {drone: [[x, y, z], ..]},
//! "lengths_m": {drone: m}, "transit_m": {drone: m}, "street_spacing_m"}`; problems as 422
//! with JSON pointers. Piece ends that meet are pulled apart (`host::coverage`).

use super::body::JsonBody;
use super::error::{ApiError, ErrorBody};
use super::ApiState;
use crate::host::coverage::{self, CoverageError};
use crate::mission::ValidationError;
use axum::extract::State;
use axum::Json;
use nalgebra::Vector2;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

#[derive(Debug, Clone, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct CoverageRequest {
    /// Polygon vertices [x, y] (m, ENU `earth`), at least 3.
    #[schema(value_type = Vec<Vec<f64>>)]
    pub polygon_enu_m: Vec<[f64; 2]>,
    /// Distance between sweep lines (m, > 0).
    pub street_spacing_m: f64,
    /// Sweep direction (deg, CCW from east); null = across the narrowest direction.
    #[serde(default)]
    pub angle_deg: Option<f64>,
    /// Drones sharing the area; each gets one piece of about equal length.
    pub drones: Vec<String>,
    /// Flight height of every point (m, ENU z).
    pub height_m: f64,
}

#[derive(Debug, Clone, Serialize, utoipa::ToSchema)]
pub struct CoverageAnswer {
    pub angle_deg: f64,
    #[schema(value_type = Object)]
    pub per_drone: BTreeMap<String, Vec<[f64; 3]>>,
    pub lengths_m: BTreeMap<String, f64>,
    /// Flight from each drone's position to its first point (m).
    pub transit_m: BTreeMap<String, f64>,
    /// Spacing actually used (streets spread evenly over the polygon), m.
    pub street_spacing_m: f64,
}

fn error(pointer: &str, message: impl Into<String>) -> ValidationError {
    ValidationError {
        pointer: pointer.into(),
        message: message.into(),
    }
}

/// Where a planner error points in the request.
fn pointer_of(e: &CoverageError) -> &'static str {
    match e {
        CoverageError::InvalidSpacing(_) | CoverageError::TooManyStreets(_) => "/street_spacing_m",
        CoverageError::NotFinite => "/height_m",
        CoverageError::NoDrones => "/drones",
        _ => "/polygon_enu_m",
    }
}

/// Sets its flag when dropped: with the handler's future, when the request times out.
struct CancelOnDrop(Arc<AtomicBool>);

impl Drop for CancelOnDrop {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

#[utoipa::path(post, path = "/api/coverage", tag = "map", security(("bearer" = [])),
    request_body = CoverageRequest,
    responses((status = 200, body = CoverageAnswer), (status = 422, body = ErrorBody)))]
pub async fn plan(
    State(s): State<ApiState>,
    JsonBody(req): JsonBody<CoverageRequest>,
) -> Result<Json<CoverageAnswer>, ApiError> {
    let snapshot = s.host.snapshot();
    let mut errors = Vec::new();
    if req.drones.is_empty() {
        errors.push(error("/drones", "name at least one drone"));
    }
    let mut starts = Vec::new();
    for (i, d) in req.drones.iter().enumerate() {
        if req.drones.iter().take(i).any(|other| other == d) {
            errors.push(error(
                &format!("/drones/{i}"),
                format!("{d} is listed twice"),
            ));
        }
        match snapshot.drones.iter().find(|s| &s.drone == d) {
            Some(status) => match status.position_enu_m {
                Some([x, y, _]) => starts.push(Vector2::new(x, y)),
                None => errors.push(error(
                    &format!("/drones/{i}"),
                    format!("{d} has no position yet: its autopilot has not given one"),
                )),
            },
            None => errors.push(error(
                &format!("/drones/{i}"),
                format!(
                    "unknown drone `{d}`; this Kestrel flies {}",
                    s.host.info.drones.join(", ")
                ),
            )),
        }
    }
    if req.angle_deg.is_some_and(|a| !a.is_finite()) {
        errors.push(error("/angle_deg", "must be a finite number of degrees"));
    }
    if !errors.is_empty() {
        return Err(ApiError::Invalid(errors));
    }
    let polygon: Vec<Vector2<f64>> = req
        .polygon_enu_m
        .iter()
        .map(|&[x, y]| Vector2::new(x, y))
        .collect();
    let angle = req.angle_deg.map(f64::to_radians);
    let (spacing, height) = (req.street_spacing_m, req.height_m);
    // Large polygons with fine spacing take a while: keep the API's threads free, and stop
    // when the request is dropped (its 408, or the client gone).
    let cancel = CancelOnDrop(Arc::new(AtomicBool::new(false)));
    let flag = cancel.0.clone();
    let plan = tokio::task::spawn_blocking(move || {
        coverage::plan(&polygon, spacing, angle, &starts, height, &flag)
    })
    .await
    .map_err(|e| ApiError::BadRequest(format!("coverage planner stopped: {e}")))?
    .map_err(|e| ApiError::Invalid(vec![error(pointer_of(&e), e.to_string())]))?;
    let mut answer = CoverageAnswer {
        angle_deg: plan.angle_rad.to_degrees(),
        per_drone: BTreeMap::new(),
        lengths_m: BTreeMap::new(),
        transit_m: BTreeMap::new(),
        street_spacing_m: plan.street_spacing_m,
    };
    for (i, drone) in req.drones.iter().enumerate() {
        let path = plan.pieces.get(i).map(Vec::as_slice).unwrap_or_default();
        let points = path.iter().map(|v| [v.x, v.y, v.z]).collect();
        answer.per_drone.insert(drone.clone(), points);
        let length = plan.lengths_m.get(i).copied().unwrap_or(0.0);
        answer.lengths_m.insert(drone.clone(), length);
        let transit = plan.transit_m.get(i).copied().unwrap_or(0.0);
        answer.transit_m.insert(drone.clone(), transit);
    }
    Ok(Json(answer))
}
