//! Request bodies: size-limited JSON with errors that say where the JSON broke.
//!
//! In: a request. Out: the parsed body, or `415 unsupported_media_type` (a JSON body must say
//! `Content-Type: application/json`, so a web page cannot send one as a "simple" form post),
//! `413 payload_too_large`, `400 bad_json` (with line and column) or `422 invalid_request` (with
//! the JSON pointer of the field and serde's message).

use super::error::ApiError;
use super::ApiState;
use crate::mission::ValidationError;
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

/// Parses JSON text into `T`, telling syntax errors (400, with line and column) from shape
/// errors (422 `invalid_request`, with the JSON pointer of the field that is wrong, unknown or
/// missing).
pub fn parse<T: DeserializeOwned>(bytes: &[u8]) -> Result<T, ApiError> {
    let value: serde_json::Value =
        serde_json::from_slice(bytes).map_err(|e| ApiError::BadJson(e.to_string()))?;
    serde_path_to_error::deserialize(value).map_err(|e| {
        ApiError::Invalid(vec![ValidationError {
            pointer: json_pointer(e.path()),
            message: e.inner().to_string(),
        }])
    })
}

/// The JSON pointer (RFC 6901) of a serde path: `/mission/plan/0`.
fn json_pointer(path: &serde_path_to_error::Path) -> String {
    use serde_path_to_error::Segment;
    path.iter()
        .map(|segment| match segment {
            Segment::Seq { index } => format!("/{index}"),
            Segment::Map { key } | Segment::Enum { variant: key } => {
                format!("/{}", key.replace('~', "~0").replace('/', "~1"))
            }
            Segment::Unknown => "/?".to_string(),
        })
        .collect()
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mission::MissionUpdate;

    fn refusal<T: DeserializeOwned + std::fmt::Debug>(body: &str) -> ValidationError {
        match parse::<T>(body.as_bytes()) {
            Err(ApiError::Invalid(mut details)) if details.len() == 1 => details.remove(0),
            other => panic!("expected one invalid field, got {other:?}"),
        }
    }

    #[test]
    fn a_misspelt_key_is_refused_and_named_by_its_pointer() {
        let e = refusal::<MissionUpdate>(r#"{"droneid": "drone_0", "action": 2}"#);
        assert_eq!(e.pointer, "/droneid", "{e}");
        assert!(e.message.contains("unknown field `droneid`"), "{e}");
        let e = refusal::<MissionUpdate>(r#"{"mision_id": 3, "action": "start"}"#);
        assert_eq!(e.pointer, "/mision_id", "{e}");
    }

    #[test]
    fn a_wrong_value_is_named_by_its_pointer() {
        let e = refusal::<MissionUpdate>(r#"{"mission_id": "three", "action": 2}"#);
        assert_eq!(e.pointer, "/mission_id", "{e}");
        let e = refusal::<MissionUpdate>(r#"{"mission_id": 3}"#);
        assert!(e.message.contains("missing field `action`"), "{e}");
    }

    #[test]
    fn the_old_name_of_action_is_taken() {
        let u: MissionUpdate = parse(br#"{"drone_id": 0, "type": 3}"#).unwrap();
        assert_eq!(u.drone_id.as_deref(), Some("drone_0"));
    }

    #[test]
    fn broken_json_is_a_syntax_error_with_its_place() {
        match parse::<MissionUpdate>(b"{\"action\": ") {
            Err(ApiError::BadJson(m)) => assert!(m.contains("line 1"), "{m}"),
            other => panic!("{other:?}"),
        }
    }
}
