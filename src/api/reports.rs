//! `GET /api/logs/{name}/report`: the flight report of a listed log, as one HTML page.
//!
//! In: a log name, which must be one `GET /api/logs` lists (so no path reaches outside the
//! log directory). Out: `report::inline_html` of that log (figures inlined as SVG), built on a
//! blocking thread, off the loop; an exploration log is judged against the world its header
//! names (relative paths from the log directory first, then the working directory).

use super::error::{ApiError, ErrorBody};
use super::{logs, ApiState};
use crate::report::{self, Options, ReportError};
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};

#[utoipa::path(get, path = "/api/logs/{name}/report", tag = "system", security(("bearer" = [])),
    params(("name" = String, Path, description = "a log name as `GET /api/logs` lists it")),
    responses((status = 200, content_type = "text/html",
        description = "the flight report: behavior timelines, trajectories, altitude, the \
            per-drone table and, for exploration logs with their world, the explored map and \
            area curve; one page, figures inlined as SVG"),
        (status = 404, body = ErrorBody, description = "no such log in the list"),
        (status = 400, body = ErrorBody, description = "the log cannot be read")))]
pub async fn report(
    State(s): State<ApiState>,
    Path(name): Path<String>,
) -> Result<Response, ApiError> {
    let (read_from, entry) = logs::listed(&s, &name).await?;
    let html = tokio::task::spawn_blocking(move || -> Result<String, ReportError> {
        let flight = report::read_file(&read_from.join(&entry.name))?;
        let options = Options {
            world: None,
            log_dir: Some(read_from),
        };
        report::inline_html(&report::analyse(&entry.name, flight, &options))
    })
    .await
    .map_err(|e| ApiError::NotFound(format!("building the report: {e}")))?
    .map_err(|e| ApiError::BadRequest(format!("flight log {name}: {e}")))?;
    Ok(([(header::CONTENT_TYPE, "text/html; charset=utf-8")], html).into_response())
}
