//! Map routes: the occupancy grid as JSON and PNG, its metadata, and scans sent by clients.
//!
//! In: `GET /api/map`, `/api/map.png`, `/api/map/info` (`?drone=`; absent = the merged map)
//! and `POST /api/scans` (JSON [`ScanInput`]s, or one binary `KSC1` scan as
//! `application/octet-stream`). Out: the grid `{spec, data, ..}`, a PNG, metadata, or the
//! number of scans queued for the drone's next tick. Grids are copied by the control loop and
//! encoded here, off the loop. Map changes reach WebSocket clients as `map_update` events.

use super::error::{ApiError, ErrorBody};
use super::routes::DroneQuery;
use super::scans::{body_scans, ScanInput};
use super::ApiState;
use crate::host::map_view::{GridSpec, MapView};
use crate::host::{Command, HostError};
use axum::body::Bytes;
use axum::extract::{Query, State};
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use serde_json::{json, Value};

/// Asks the host for a copy of a map; "mapping is off" is a 404.
async fn fetch(s: &ApiState, drone: Option<String>) -> Result<MapView, ApiError> {
    s.host
        .call(|reply| Command::Map { drone, reply })
        .await
        .map_err(|e| match e {
            HostError::NotSupported(m) => ApiError::NotFound(m),
            other => ApiError::Host(other),
        })
}

#[utoipa::path(get, path = "/api/map", tag = "map", security(("bearer" = [])),
    params(DroneQuery),
    responses((status = 200, description = "{spec: {resolution_m, width_cells, height_cells, origin_enu_m: [x, y]}, data: [row-major from the south-west cell, -1 unknown, else occupancy 0..100], drone, layers, revision, updated_at_s}"),
        (status = 404, body = ErrorBody, description = "unknown drone, or mapping is off")))]
pub async fn grid(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
) -> Result<Json<Value>, ApiError> {
    let view = fetch(&s, q.drone).await?;
    Ok(Json(json!({
        "spec": view.grid.spec(),
        "data": view.grid.data(),
        "drone": view.drone,
        "layers": view.layers,
        "revision": view.revision,
        "updated_at_s": view.updated_at_s,
    })))
}

#[utoipa::path(get, path = "/api/map.png", tag = "map", security(("bearer" = [])),
    params(DroneQuery),
    responses((status = 200, content_type = "image/png",
        description = "8-bit grey, north up: unknown grey, free white, occupied black"),
        (status = 404, body = ErrorBody)))]
pub async fn png(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
) -> Result<Response, ApiError> {
    let view = fetch(&s, q.drone).await?;
    let bytes = view
        .grid
        .to_png()
        .map_err(|e| ApiError::Host(HostError::Unavailable(e.to_string())))?;
    Ok(([(header::CONTENT_TYPE, "image/png")], bytes).into_response())
}

/// What `GET /api/map/info` answers.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct MapInfo {
    /// The drone whose map this is; null = the merged map.
    pub drone: Option<String>,
    #[schema(value_type = Object)]
    pub spec: GridSpec,
    /// `[x_min, y_min, x_max, y_max]` (ENU m).
    pub bbox_enu_m: [f64; 4],
    pub layers: Vec<String>,
    pub revision: Option<u64>,
    pub updated_at_s: Option<f64>,
    pub cells_unknown: usize,
    pub cells_free: usize,
    pub cells_occupied: usize,
    /// Cells at or above this value are obstacles for planning (drone maps).
    pub occupied_threshold: Option<i8>,
}

#[utoipa::path(get, path = "/api/map/info", tag = "map", security(("bearer" = [])),
    params(DroneQuery),
    responses((status = 200, body = MapInfo), (status = 404, body = ErrorBody)))]
pub async fn info(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
) -> Result<Json<MapInfo>, ApiError> {
    let view = fetch(&s, q.drone).await?;
    let spec = *view.grid.spec();
    let cells = view.cell_counts();
    let o = spec.origin_enu_m;
    Ok(Json(MapInfo {
        drone: view.drone,
        spec,
        bbox_enu_m: [
            o.x,
            o.y,
            o.x + f64::from(spec.width_cells) * spec.resolution_m,
            o.y + f64::from(spec.height_cells) * spec.resolution_m,
        ],
        layers: view.layers,
        revision: view.revision,
        updated_at_s: view.updated_at_s,
        cells_unknown: cells.unknown,
        cells_free: cells.free,
        cells_occupied: cells.occupied,
        occupied_threshold: view.occupied_threshold,
    }))
}

#[utoipa::path(post, path = "/api/scans", tag = "map", security(("bearer" = [])),
    params(DroneQuery), request_body = ScanInput,
    responses((status = 200, description = "{\"drone\": .., \"queued\": N}: inserted at the drone's next tick"),
        (status = 422, body = ErrorBody), (status = 404, body = ErrorBody)))]
pub async fn post_scans(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
    headers: HeaderMap,
    body: Bytes,
) -> Result<Json<Value>, ApiError> {
    let binary = headers
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|t| t.starts_with("application/octet-stream"));
    if !binary {
        super::body::require_json(&headers)?;
    }
    let (drone, scans) = body_scans(&body, binary, q.drone)?;
    let queued = s
        .host
        .call(|reply| Command::Scans {
            drone: drone.clone(),
            scans,
            reply,
        })
        .await
        .map_err(|e| match e {
            HostError::NotSupported(m) => ApiError::NotFound(m),
            other => ApiError::Host(other),
        })?;
    Ok(Json(json!({ "drone": drone, "queued": queued })))
}

#[utoipa::path(get, path = "/api/exploration", tag = "map", security(("bearer" = [])),
    responses((status = 200, body = crate::exploration::online::service::ExplorationView)))]
/// The exploration as the frontier allocator last saw it: frontiers, each exploring drone's
/// goal, the share of the merged map known, and the progress of the run started over the API
/// (`api::exploration`).
pub async fn exploration(
    State(s): State<ApiState>,
) -> Result<Json<crate::exploration::online::service::ExplorationView>, ApiError> {
    s.host
        .call(|reply| Command::Exploration { reply })
        .await
        .map(Json)
        .map_err(ApiError::Host)
}
