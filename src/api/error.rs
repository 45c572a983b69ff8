//! The one place where errors become HTTP answers: a status and a stable snake_case code.
//!
//! In: [`HostError`]s and request problems. Out: `{"error": {"code", "message", "details"}}`,
//! or, for MissionUpdate answers, `{"accepted": false, "reason", "code", "details"}`. What axum
//! and tower answer on their own under `/api` (a path or query that does not parse, a wrong
//! method, a timeout) gets the same body ([`json_errors`]).

use crate::behavior::ServerError;
use crate::host::HostError;
use crate::mission::{ActionError, ValidationError};
use axum::extract::Request;
use axum::http::{header, StatusCode};
use axum::middleware::Next;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde::Serialize;
use serde_json::json;

#[derive(Debug, thiserror::Error)]
pub enum ApiError {
    #[error(transparent)]
    Host(#[from] HostError),
    #[error("missing or wrong bearer token")]
    Unauthorized,
    #[error("request body is not valid JSON: {0}")]
    BadJson(String),
    #[error("request body is larger than the limit of {0} bytes")]
    TooLarge(usize),
    #[error("{0}")]
    BadRequest(String),
    #[error("{0}")]
    NotFound(String),
    #[error("too many WebSocket clients (limit {0})")]
    TooManyClients(usize),
    /// A request body that parsed but does not make sense, field by field (JSON pointers).
    #[error("request is invalid")]
    Invalid(Vec<ValidationError>),
    #[error("send the body as JSON with Content-Type: application/json (got {0})")]
    UnsupportedMediaType(String),
    /// Refused before a handler ran (axum's path, query and method checks) or timed out.
    #[error("{message}")]
    Refused { status: StatusCode, message: String },
    #[error("requests from the web page at {0} are refused: this Kestrel has no API token, so only its own pages and [api] cors_origins may call it")]
    ForeignOrigin(String),
    #[error("requests for the host `{0}` are refused: this Kestrel has no API token, so it answers only requests addressed to a loopback name or address (localhost, 127.0.0.1, [::1]); a web page that rebinds its own name to this machine cannot call it")]
    ForeignHost(String),
}

/// The JSON error body, for the OpenAPI spec.
#[derive(Debug, Serialize, utoipa::ToSchema)]
pub struct ErrorBody {
    pub code: String,
    pub message: String,
    pub details: Vec<ValidationError>,
}

impl ApiError {
    /// Status and stable code of every error.
    pub fn status_and_code(&self) -> (StatusCode, &'static str) {
        match self {
            ApiError::Host(h) => match h {
                HostError::UnknownDrone(..) => (StatusCode::NOT_FOUND, "unknown_drone"),
                HostError::DroneNeeded(_) => (StatusCode::BAD_REQUEST, "drone_id_required"),
                HostError::Invalid(_) | HostError::Action(ActionError::Invalid(_)) => {
                    (StatusCode::UNPROCESSABLE_ENTITY, "invalid_mission")
                }
                HostError::Action(ActionError::UnknownMission(_)) => {
                    (StatusCode::NOT_FOUND, "unknown_mission")
                }
                HostError::Action(ActionError::Refused(_)) => {
                    (StatusCode::CONFLICT, "action_refused")
                }
                HostError::Frame(_) => (StatusCode::UNPROCESSABLE_ENTITY, "invalid_frame"),
                HostError::NotSupported(_) => (StatusCode::BAD_REQUEST, "not_supported"),
                HostError::Unavailable(_) => (StatusCode::SERVICE_UNAVAILABLE, "unavailable"),
                HostError::AlreadyLanded(_) => (StatusCode::CONFLICT, "already_landed"),
                HostError::RemoteDrone { .. } => (StatusCode::CONFLICT, "remote_drone"),
                HostError::FleetNotJoined { .. } => (StatusCode::CONFLICT, "fleet_not_joined"),
                HostError::Behavior(b) => match b {
                    ServerError::UnknownBehavior(_) => (StatusCode::NOT_FOUND, "unknown_behavior"),
                    ServerError::Rejected { reason, .. } => {
                        (StatusCode::UNPROCESSABLE_ENTITY, reason.code.as_str())
                    }
                    ServerError::NotActive(_)
                    | ServerError::NotRunning(_)
                    | ServerError::NotPaused(_) => (StatusCode::CONFLICT, "behavior_state"),
                },
            },
            ApiError::Unauthorized => (StatusCode::UNAUTHORIZED, "unauthorized"),
            ApiError::BadJson(_) => (StatusCode::BAD_REQUEST, "bad_json"),
            ApiError::TooLarge(_) => (StatusCode::PAYLOAD_TOO_LARGE, "payload_too_large"),
            ApiError::BadRequest(_) => (StatusCode::UNPROCESSABLE_ENTITY, "invalid_request"),
            ApiError::NotFound(_) => (StatusCode::NOT_FOUND, "not_found"),
            ApiError::TooManyClients(_) => (StatusCode::SERVICE_UNAVAILABLE, "too_many_clients"),
            ApiError::Invalid(_) => (StatusCode::UNPROCESSABLE_ENTITY, "invalid_request"),
            ApiError::UnsupportedMediaType(_) => {
                (StatusCode::UNSUPPORTED_MEDIA_TYPE, "unsupported_media_type")
            }
            ApiError::ForeignOrigin(_) => (StatusCode::FORBIDDEN, "foreign_origin"),
            ApiError::ForeignHost(_) => (StatusCode::FORBIDDEN, "foreign_host"),
            ApiError::Refused { status, .. } => (*status, refused_code(*status)),
        }
    }

    pub fn details(&self) -> Vec<ValidationError> {
        match self {
            ApiError::Host(HostError::Invalid(d))
            | ApiError::Host(HostError::Action(ActionError::Invalid(d)))
            | ApiError::Invalid(d) => d.clone(),
            _ => Vec::new(),
        }
    }

    /// The message, with the first validation errors spelled out.
    pub fn message(&self) -> String {
        match self {
            ApiError::Host(HostError::Invalid(d)) => {
                let first: Vec<String> = d.iter().take(3).map(ToString::to_string).collect();
                format!("mission is invalid: {}", first.join("; "))
            }
            ApiError::Invalid(d) => {
                let first: Vec<String> = d.iter().take(3).map(ToString::to_string).collect();
                format!("request is invalid: {}", first.join("; "))
            }
            other => other.to_string(),
        }
    }

    /// The answer to a refused MissionUpdate.
    pub fn as_rejection(&self) -> Response {
        let (status, code) = self.status_and_code();
        let body = json!({
            "accepted": false,
            "reason": self.message(),
            "code": code,
            "details": self.details(),
        });
        (status, Json(body)).into_response()
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let (status, code) = self.status_and_code();
        let body = json!({
            "error": {"code": code, "message": self.message(), "details": self.details()}
        });
        (status, Json(body)).into_response()
    }
}

/// The stable code of an answer axum or tower gave on their own.
fn refused_code(status: StatusCode) -> &'static str {
    match status {
        StatusCode::BAD_REQUEST => "bad_request",
        StatusCode::NOT_FOUND => "not_found",
        StatusCode::METHOD_NOT_ALLOWED => "method_not_allowed",
        StatusCode::REQUEST_TIMEOUT => "request_timeout",
        StatusCode::PAYLOAD_TOO_LARGE => "payload_too_large",
        StatusCode::UNSUPPORTED_MEDIA_TYPE => "unsupported_media_type",
        StatusCode::UNPROCESSABLE_ENTITY => "invalid_request",
        s if s.is_server_error() => "internal_error",
        _ => "refused",
    }
}

/// Longest plain-text rejection kept as the message (axum's are one line).
const MAX_REJECTION_TEXT: usize = 4096;

/// Middleware: an error answer under `/api` that is not JSON (axum's plain-text rejections such
/// as `Invalid URL: Cannot parse ...`, an empty 405 or 408) becomes the JSON error body, with
/// the same status and its `Allow` header kept.
pub async fn json_errors(request: Request, next: Next) -> Response {
    let api = request.uri().path().starts_with("/api");
    let response = next.run(request).await;
    let status = response.status();
    let is_json = response
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .is_some_and(|v| v.starts_with("application/json"));
    if !api || is_json || !(status.is_client_error() || status.is_server_error()) {
        return response;
    }
    let (parts, body) = response.into_parts();
    let text = axum::body::to_bytes(body, MAX_REJECTION_TEXT)
        .await
        .map(|b| String::from_utf8_lossy(&b).trim().to_string())
        .unwrap_or_default();
    let message = if text.is_empty() {
        status
            .canonical_reason()
            .unwrap_or("refused")
            .to_lowercase()
    } else {
        text
    };
    let mut answer = ApiError::Refused { status, message }.into_response();
    if let Some(allow) = parts.headers.get(header::ALLOW) {
        answer.headers_mut().insert(header::ALLOW, allow.clone());
    }
    answer
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refusals_are_conflicts_and_invalid_missions_unprocessable() {
        let e = ApiError::from(HostError::Action(ActionError::Refused("no".into())));
        assert_eq!(
            e.status_and_code(),
            (StatusCode::CONFLICT, "action_refused")
        );
        let e = ApiError::from(HostError::Invalid(vec![]));
        assert_eq!(e.status_and_code().0, StatusCode::UNPROCESSABLE_ENTITY);
    }
}
