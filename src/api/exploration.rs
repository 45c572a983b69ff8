//! Exploration routes: start and stop an exploration for chosen drones, and its report.
//!
//! In: `POST /api/exploration/start` ([`StartRequest`]), `POST /api/exploration/stop`
//! ([`StopRequest`]), `GET /api/exploration/report`. Out: the missions started, the drones
//! stopped, or the report as a JSON attachment: what the host measured live, plus, in the
//! simulator, the evaluator's metrics of the sampled poses against the true world (computed here
//! on a blocking thread, off the control loop). `GET /api/exploration` (progress included) is in
//! `api::map`.

use super::body::JsonBody;
use super::error::{ApiError, ErrorBody};
use super::ApiState;
use crate::exploration::offline::evaluate::{evaluate, EvalParams, PoseSample};
use crate::host::engine::{ExplorationStarted, ReportInput};
use crate::host::{Command, HostError};
use axum::extract::State;
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};

/// Which drones explore, and the `explore` goal's arguments (`GET /api/behaviors`).
#[derive(Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct StartRequest {
    pub drones: Vec<String>,
    /// Arguments of the `explore` behavior; absent = every default.
    #[serde(default = "empty_object")]
    #[schema(value_type = Object)]
    pub args: Value,
}

fn empty_object() -> Value {
    json!({})
}

#[derive(Debug, Deserialize, utoipa::ToSchema)]
#[serde(deny_unknown_fields)]
pub struct StopRequest {
    pub drones: Vec<String>,
}

/// Host errors of a request body: its validation errors are the request's (`invalid_request`).
fn request_error(e: HostError) -> ApiError {
    match e {
        HostError::Invalid(details) => ApiError::Invalid(details),
        other => ApiError::Host(other),
    }
}

#[utoipa::path(post, path = "/api/exploration/start", tag = "map", security(("bearer" = [])),
    request_body = StartRequest,
    responses((status = 200, body = ExplorationStarted),
        (status = 404, body = ErrorBody, description = "unknown drone; nothing started"),
        (status = 409, body = ErrorBody, description = "a drone explores already; nothing started"),
        (status = 422, body = ErrorBody, description = "bad drones list or goal, with JSON pointers (`/drones/1`, `/args/speed`); nothing started")))]
/// Starts the `explore` behavior on every drone named, each in a mission of its own, loaded and
/// started as `POST /api/missions` and a START MissionUpdate would; all or none.
pub async fn start(
    State(s): State<ApiState>,
    JsonBody(req): JsonBody<StartRequest>,
) -> Result<Json<ExplorationStarted>, ApiError> {
    s.host
        .call(|reply| Command::ExplorationStart {
            drones: req.drones,
            args: req.args,
            reply,
        })
        .await
        .map(Json)
        .map_err(request_error)
}

#[utoipa::path(post, path = "/api/exploration/stop", tag = "map", security(("bearer" = [])),
    request_body = StopRequest,
    responses((status = 200, description = "{\"stopped\": [drone, ..]}: their missions stopped, the vehicles hold"),
        (status = 404, body = ErrorBody), (status = 409, body = ErrorBody, description = "a drone is not exploring; nothing stopped"),
        (status = 422, body = ErrorBody)))]
/// Stops the exploration missions of the drones named (STOP: the vehicles hold); all or none.
pub async fn stop(
    State(s): State<ApiState>,
    JsonBody(req): JsonBody<StopRequest>,
) -> Result<Json<Value>, ApiError> {
    let stopped = s
        .host
        .call(|reply| Command::ExplorationStop {
            drones: req.drones,
            reply,
        })
        .await
        .map_err(request_error)?;
    Ok(Json(json!({ "stopped": stopped })))
}

/// The report: the live measurements, and the evaluator's metrics against the true world when
/// it is known and some drone flew.
fn report_json(input: ReportInput) -> Value {
    let (evaluation, evaluation_error) = match &input.world {
        None => (
            Value::Null,
            Some("no true world: not a simulation".to_string()),
        ),
        Some(world) => {
            let samples: Vec<PoseSample> = input
                .samples
                .iter()
                .flat_map(|c| c.iter().cloned())
                .collect();
            match evaluate(world, &samples, &EvalParams::default()) {
                Ok(m) => (serde_json::to_value(m).unwrap_or(Value::Null), None),
                Err(e) => (Value::Null, Some(e.to_string())),
            }
        }
    };
    let mut report = serde_json::to_value(&input.live).unwrap_or_else(|_| json!({}));
    if let Some(fields) = report.as_object_mut() {
        fields.insert("evaluation".into(), evaluation);
        fields.insert("evaluation_error".into(), json!(evaluation_error));
    }
    report
}

#[utoipa::path(get, path = "/api/exploration/report", tag = "map", security(("bearer" = [])),
    responses((status = 200, content_type = "application/json",
        description = "attachment: {started_at_s, elapsed_s, finished, remaining_s, area_rate_pct_per_min, drones: [{drone, mission_id, phase, goal_enu_m, path_m}], known_pct, frontiers_left, area_curve: [{t_s, area_pct}], path_m, min_separation_m, pose_samples, pose_samples_dropped, evaluation: evaluator metrics against the simulator's true world (or kestrel run's --virtual-world) or null, evaluation_error}"),
        (status = 404, body = ErrorBody, description = "no exploration was started")))]
/// The exploration report as a downloadable JSON file.
pub async fn report(State(s): State<ApiState>) -> Result<Response, ApiError> {
    let input = s
        .host
        .call(|reply| Command::ExplorationReport { reply })
        .await
        .map_err(|e| match e {
            HostError::NotSupported(m) => ApiError::NotFound(m),
            other => ApiError::Host(other),
        })?;
    let t = input.live.progress.started_at_s;
    let report = tokio::task::spawn_blocking(move || report_json(input))
        .await
        .map_err(|e| ApiError::Host(HostError::Unavailable(e.to_string())))?;
    let disposition = format!("attachment; filename=\"kestrel-exploration-{t:.0}.json\"");
    Ok(([(header::CONTENT_DISPOSITION, disposition)], Json(report)).into_response())
}
