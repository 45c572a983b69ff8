//! REST handlers: health, status, behaviors, missions, MissionUpdate, frames, flight logs and
//! simulator faults. Each one asks the host (commands) or reads its latest published state.
//!
//! In: HTTP requests (JSON bodies, `?drone=` queries). Out: JSON answers as `docs/API.md`
//! lists them; errors through [`ApiError`].

use super::body::{parse, JsonBody};
use super::error::{ApiError, ErrorBody};
use super::saved::{changes_saved, Durability};
use super::ApiState;
use crate::flightlog::files::{self, LogEntry};
use crate::host::engine::{FrameRegistration, MissionView, Updated, Uploaded};
use crate::host::runtime::BehaviorInfo;
use crate::host::store::StoreHealth;
use crate::host::HostError;
use crate::host::{Command, DroneStatus, LoadOptions};
use crate::mission::{Mission, MissionUpdate};
use axum::extract::{Path, Query, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

#[derive(Debug, Deserialize, utoipa::IntoParams)]
pub struct DroneQuery {
    /// A drone id (`drone_0` ...); absent = every drone (or the only one).
    pub drone: Option<String>,
}

#[derive(Debug, Deserialize, utoipa::IntoParams)]
pub struct UploadQuery {
    /// Load under this id (replacing an idle mission with that id).
    pub mission_id: Option<u32>,
}

#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct Health {
    pub status: String,
    pub version: String,
    pub drones: Vec<String>,
    pub uptime_s: f64,
    pub simulated: bool,
    /// The state directory (absent without one): saves failing and retried, files quarantined
    /// at start.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub storage: Option<StoreHealth>,
}

#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct StatusAnswer {
    pub t: f64,
    pub drones: Vec<DroneStatus>,
    /// Drones other Kestrels of the fleet fly (heard over the fleet bus); absent without a bus.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub remote: Vec<crate::fleet_bus::remote::RemoteDroneStatus>,
    /// The fleet bus's traffic and latency; absent without a bus.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fleet_bus: Option<crate::host::status::BusReport>,
}

#[utoipa::path(get, path = "/api/health", tag = "system",
    responses((status = 200, body = Health)))]
pub async fn health(State(s): State<ApiState>) -> Json<Health> {
    Json(Health {
        status: "ok".into(),
        version: env!("CARGO_PKG_VERSION").into(),
        drones: s.host.info.drones.clone(),
        uptime_s: s.started.elapsed().as_secs_f64(),
        simulated: s.host.info.simulated,
        storage: s.store.as_ref().map(|st| st.health()),
    })
}

#[utoipa::path(get, path = "/api/status", tag = "vehicles", security(("bearer" = [])),
    responses((status = 200, body = StatusAnswer), (status = 401, body = ErrorBody)))]
pub async fn status(State(s): State<ApiState>) -> Json<StatusAnswer> {
    let snap = s.host.snapshot();
    Json(StatusAnswer {
        t: snap.t,
        drones: snap.drones.clone(),
        remote: snap.remote.clone(),
        fleet_bus: snap.fleet_bus.clone(),
    })
}

#[utoipa::path(get, path = "/api/behaviors", tag = "missions", security(("bearer" = [])),
    responses((status = 200, body = Vec<BehaviorInfo>)))]
pub async fn behaviors(State(s): State<ApiState>) -> Json<Vec<BehaviorInfo>> {
    Json(s.host.info.behaviors.clone())
}

#[utoipa::path(get, path = "/api/missions", tag = "missions", security(("bearer" = [])),
    params(DroneQuery), responses((status = 200, body = Vec<MissionView>)))]
pub async fn missions(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
) -> Result<Json<Vec<MissionView>>, ApiError> {
    let views = s
        .host
        .call(|reply| Command::Missions {
            drone: q.drone,
            reply,
        })
        .await?;
    Ok(Json(views))
}

#[utoipa::path(post, path = "/api/missions", tag = "missions", security(("bearer" = [])),
    params(UploadQuery), request_body = Mission,
    responses((status = 201, body = UploadAnswer,
        description = "loaded; `durable`: saved (file and directory synced) before this answer"),
        (status = 422, body = ErrorBody), (status = 413, body = ErrorBody)))]
pub async fn upload(
    State(s): State<ApiState>,
    Query(q): Query<UploadQuery>,
    JsonBody(mission): JsonBody<Value>,
) -> Result<(StatusCode, Json<UploadAnswer>), ApiError> {
    let options = LoadOptions {
        mission_id: q.mission_id,
        start: false,
    };
    let up = s.host.load_mission(mission, options).await?;
    let saved = changes_saved(&s).await;
    Ok((StatusCode::CREATED, Json(UploadAnswer { up, saved })))
}

/// An upload's answer: the mission's id and whether it is saved.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct UploadAnswer {
    #[serde(flatten)]
    pub up: Uploaded,
    #[serde(flatten)]
    pub saved: Durability,
}

#[utoipa::path(get, path = "/api/missions/{id}", tag = "missions", security(("bearer" = [])),
    params(("id" = u32, Path), DroneQuery),
    responses((status = 200, body = MissionView), (status = 404, body = ErrorBody)))]
pub async fn mission(
    State(s): State<ApiState>,
    Path(id): Path<u32>,
    Query(q): Query<DroneQuery>,
) -> Result<Json<MissionView>, ApiError> {
    let view = s
        .host
        .call(|reply| Command::Mission {
            drone: q.drone,
            mission_id: id,
            reply,
        })
        .await?;
    Ok(Json(view))
}

#[utoipa::path(delete, path = "/api/missions/{id}", tag = "missions", security(("bearer" = [])),
    params(("id" = u32, Path), DroneQuery),
    responses((status = 204), (status = 409, body = ErrorBody), (status = 404, body = ErrorBody)))]
pub async fn delete_mission(
    State(s): State<ApiState>,
    Path(id): Path<u32>,
    Query(q): Query<DroneQuery>,
) -> Result<StatusCode, ApiError> {
    s.host
        .call(|reply| Command::Delete {
            drone: q.drone,
            mission_id: id,
            reply,
        })
        .await?;
    // 204 has no body to say "not saved"; the health does (a failed save is retried).
    changes_saved(&s).await;
    Ok(StatusCode::NO_CONTENT)
}

/// A MissionUpdate's answer.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct UpdateAnswer {
    pub accepted: bool,
    #[serde(flatten)]
    pub updated: Updated,
    #[serde(flatten)]
    pub saved: Durability,
}

/// Applies a MissionUpdate (the JSON form of Aerostack2's message, accepted as is) and waits
/// for what it changed to be saved.
pub async fn apply_update(s: &ApiState, bytes: &[u8]) -> Result<(Updated, Durability), ApiError> {
    let update: MissionUpdate = parse(bytes)?;
    let updated = s
        .host
        .call(|reply| Command::Update { update, reply })
        .await?;
    Ok((updated, changes_saved(s).await))
}

#[utoipa::path(post, path = "/api/mission_update", tag = "missions", security(("bearer" = [])),
    request_body = MissionUpdate,
    responses((status = 200, body = UpdateAnswer,
        description = "accepted; refusals answer 409 (or 422 for an invalid mission, 404 for an unknown one) with {accepted: false, reason, code, details}")))]
pub async fn mission_update(
    State(s): State<ApiState>,
    JsonBody(body): JsonBody<Value>,
) -> Response {
    let bytes = body.to_string();
    match apply_update(&s, bytes.as_bytes()).await {
        Ok((updated, saved)) => Json(UpdateAnswer {
            accepted: true,
            updated,
            saved,
        })
        .into_response(),
        Err(e) => e.as_rejection(),
    }
}

#[utoipa::path(post, path = "/api/frames", tag = "frames", security(("bearer" = [])),
    request_body = FrameRegistration,
    responses((status = 200, description = "{\"frame_id\": .., \"durable\": ..}"), (status = 422, body = ErrorBody)))]
pub async fn set_frame(
    State(s): State<ApiState>,
    JsonBody(frame): JsonBody<FrameRegistration>,
) -> Result<Json<Value>, ApiError> {
    let id = frame.frame_id.clone();
    s.host
        .call(|reply| Command::SetFrame { frame, reply })
        .await?;
    let saved = changes_saved(&s).await;
    Ok(Json(
        json!({ "frame_id": id, "durable": saved.durable, "not_durable": saved.not_durable }),
    ))
}

#[utoipa::path(get, path = "/api/frames", tag = "frames", security(("bearer" = [])),
    responses((status = 200, body = Vec<FrameRegistration>)))]
pub async fn frames(State(s): State<ApiState>) -> Result<Json<Vec<FrameRegistration>>, ApiError> {
    Ok(Json(s.host.call(|reply| Command::Frames { reply }).await?))
}

#[utoipa::path(get, path = "/api/log", tag = "system", security(("bearer" = [])),
    params(DroneQuery),
    responses((status = 200, content_type = "application/x-ndjson",
        description = "the flight log of the current or last flight, one JSON record per line")))]
pub async fn log(
    State(s): State<ApiState>,
    Query(q): Query<DroneQuery>,
) -> Result<Response, ApiError> {
    let file = s
        .log
        .clone()
        .ok_or_else(|| ApiError::NotFound("no flight log is being written".into()))?;
    if let Some(d) = q
        .drone
        .as_deref()
        .filter(|d| !s.host.info.drones.iter().any(|x| x == d))
    {
        return Err(ApiError::Host(HostError::UnknownDrone(
            d.to_string(),
            s.host.info.drones.join(", "),
        )));
    }
    s.host.call(|reply| Command::FlushLog { reply }).await?;
    // The writer thread flushes when idle, at most 100 ms after the hand-over.
    tokio::time::sleep(std::time::Duration::from_millis(150)).await;
    let text = tokio::fs::read_to_string(&file.path)
        .await
        .map_err(|e| ApiError::NotFound(format!("flight log {}: {e}", file.path.display())))?;
    let body = match &q.drone {
        None => text,
        Some(d) => {
            let needle = format!("\"drone\":\"{d}\"");
            text.lines()
                .filter(|l| l.contains(&needle))
                .fold(String::new(), |mut acc, l| {
                    acc.push_str(l);
                    acc.push('\n');
                    acc
                })
        }
    };
    Ok(([(header::CONTENT_TYPE, "application/x-ndjson")], body).into_response())
}

#[utoipa::path(get, path = "/api/logs", tag = "system", security(("bearer" = [])),
    responses((status = 200, body = Vec<LogEntry>,
        description = "the flight logs beside the current one (one per run, named by its UTC \
            start time), newest first")))]
pub async fn logs(State(s): State<ApiState>) -> Result<Json<Vec<LogEntry>>, ApiError> {
    let file = s
        .log
        .clone()
        .ok_or_else(|| ApiError::NotFound("no flight log is being written".into()))?;
    let dir = file
        .path
        .parent()
        .map(std::path::Path::to_path_buf)
        .unwrap_or_default();
    let listed = tokio::task::spawn_blocking(move || files::list(&dir, Some(&file.path)))
        .await
        .map_err(|e| ApiError::NotFound(format!("listing flight logs: {e}")))?
        .map_err(|e| ApiError::NotFound(format!("listing flight logs: {e}")))?;
    Ok(Json(listed))
}

#[derive(Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct Fault {
    pub drone_id: String,
    /// `link_lost` or `link_restored`.
    pub fault: String,
}

#[utoipa::path(post, path = "/api/sim/fault", tag = "system", security(("bearer" = [])),
    request_body = Fault,
    responses((status = 200), (status = 400, body = ErrorBody)))]
pub async fn sim_fault(
    State(s): State<ApiState>,
    JsonBody(fault): JsonBody<Fault>,
) -> Result<Json<Value>, ApiError> {
    let link_lost = match fault.fault.as_str() {
        "link_lost" => true,
        "link_restored" => false,
        other => {
            return Err(ApiError::BadRequest(format!(
                "unknown fault `{other}`: use link_lost or link_restored"
            )))
        }
    };
    s.host
        .call(|reply| Command::Fault {
            drone_id: fault.drone_id.clone(),
            link_lost,
            reply,
        })
        .await?;
    Ok(Json(
        json!({ "drone_id": fault.drone_id, "fault": fault.fault }),
    ))
}
