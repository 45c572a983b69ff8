//! `GET /api/geofence`: the `[geofence]` config section missions are checked against, for
//! ground stations to draw.
//!
//! In: nothing (the host's limits, fixed at start). Out: `{max_altitude_m, min_altitude_m,
//! radius_m, polygon_enu_m}` (metres; altitudes relative to home, polygon ENU `earth`).

use super::ApiState;
use crate::safety::GeofenceSection;
use axum::extract::State;
use axum::Json;

#[utoipa::path(get, path = "/api/geofence", tag = "map", security(("bearer" = [])),
    responses((status = 200, description = "{max_altitude_m, min_altitude_m, radius_m, polygon_enu_m}")))]
pub async fn geofence(State(s): State<ApiState>) -> Json<GeofenceSection> {
    Json(s.host.info.geofence.clone())
}
