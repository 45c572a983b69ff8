//! Request bodies: size-limited JSON with errors that say where the JSON broke.
//!
//! In: a request. Out: the parsed body, or `415 unsupported_media_type` (a JSON body must say
//! `Content-Type: application/json`, so a web page cannot send one as a "simple" form post),
//! `413 payload_too_large`, `400 bad_json` (with line and column) or `422 invalid_request` (with
//! serde's message).

use super::error::ApiError;
use super::ApiState;
use axum::body::Bytes;
use axum::extract::{FromRequest, Request};
use axum::http::StatusCode;
use serde::de::DeserializeOwned;

pub struct JsonBody<T>(pub T);

impl<T: DeserializeOwned> FromRequest<ApiState> for JsonBody<T> {
    type Rejection = ApiError;

    async fn from_request(req: Request, state: &ApiState) -> Result<Self, ApiError> {
        require_json(req.headers())?;
        let bytes = Bytes::from_request(req, state).await.map_err(|r| {
            if r.status() == StatusCode::PAYLOAD_TOO_LARGE {
                ApiError::TooLarge(state.max_body_bytes)
            } else {
                ApiError::BadJson(r.body_text())
            }
        })?;
        parse(&bytes).map(JsonBody)
    }
}

/// Refuses a body whose `Content-Type` is not `application/json` (parameters such as
/// `charset` allowed).
pub fn require_json(headers: &axum::http::HeaderMap) -> Result<(), ApiError> {
    let given = headers
        .get(axum::http::header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("no Content-Type");
    let mime = given.split(';').next().unwrap_or_default().trim();
    if mime.eq_ignore_ascii_case("application/json") {
        Ok(())
    } else {
        Err(ApiError::UnsupportedMediaType(given.to_string()))
    }
}

/// Parses JSON text into `T`, telling syntax errors (400) from shape errors (422).
pub fn parse<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    // serde's message ends with the line and column.
    let value: serde_json::Value =
        serde_json::from_slice(bytes).map_err(|e| ApiError::BadJson(e.to_string()))?;
    serde_json::from_value(value).map_err(|e| ApiError::BadRequest(e.to_string()))
}

/// Middleware: a body announced larger than the limit is refused before it is read, so the
/// client gets its 413 without sending the body (bodies without a length are cut at the
/// limit by `DefaultBodyLimit`).
pub async fn refuse_large(
    axum::extract::State(state): axum::extract::State<ApiState>,
    request: Request,
    next: axum::middleware::Next,
) -> Result<axum::response::Response, ApiError> {
    let announced = request
        .headers()
        .get(axum::http::header::CONTENT_LENGTH)
        .and_then(|v| v.to_str().ok())
        .and_then(|v| v.parse::<usize>().ok());
    if announced.is_some_and(|n| n > state.max_body_bytes) {
        return Err(ApiError::TooLarge(state.max_body_bytes));
    }
    Ok(next.run(request).await)
}
