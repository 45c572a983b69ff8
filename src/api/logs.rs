//! `GET /api/logs/{name}`: one listed flight log as it is on disk, for download; and the lookup
//! it shares with `GET /api/logs/{name}/report`.
//!
//! In: a log name, which must be one `GET /api/logs` lists (so no path reaches outside the log
//! directory). Out: the file streamed in 64 KiB chunks (`application/x-ndjson`, with a
//! `Content-Disposition` naming it), never held whole in memory; the current log is flushed
//! first so the download holds what was written up to the request.

use super::error::{ApiError, ErrorBody};
use super::ApiState;
use crate::flightlog::files::{self, LogEntry};
use crate::host::Command;
use axum::body::Body;
use axum::extract::{Path, State};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use std::path::PathBuf;
use tokio::io::AsyncReadExt;

/// Bytes read from the file per chunk of the response.
const CHUNK_BYTES: usize = 64 * 1024;

/// A log `GET /api/logs` lists under `name`, and the directory it is in (`.` for a bare
/// `--log` name). Flushes the log when it is the current one. `404` when `name` is not listed.
pub(super) async fn listed(s: &ApiState, name: &str) -> Result<(PathBuf, LogEntry), ApiError> {
    let file = s
        .log
        .clone()
        .ok_or_else(|| ApiError::NotFound("no flight log is being written".into()))?;
    let dir = match file.path.parent() {
        Some(d) if !d.as_os_str().is_empty() => d.to_path_buf(),
        _ => PathBuf::from("."),
    };
    let listed = {
        let (dir, current) = (dir.clone(), file.path.clone());
        tokio::task::spawn_blocking(move || files::list(&dir, Some(&current)))
            .await
            .map_err(|e| ApiError::NotFound(format!("listing flight logs: {e}")))?
            .map_err(|e| ApiError::NotFound(format!("listing flight logs: {e}")))?
    };
    let Some(entry) = listed.into_iter().find(|e| e.name == name) else {
        return Err(ApiError::NotFound(format!(
            "no flight log named `{name}`: GET /api/logs lists them"
        )));
    };
    if entry.current {
        s.host.call(|reply| Command::FlushLog { reply }).await?;
        // The writer thread flushes when idle, at most 100 ms after the hand-over.
        tokio::time::sleep(std::time::Duration::from_millis(150)).await;
    }
    Ok((dir, entry))
}

#[utoipa::path(get, path = "/api/logs/{name}", tag = "system", security(("bearer" = [])),
    params(("name" = String, Path, description = "a log name as `GET /api/logs` lists it")),
    responses((status = 200, content_type = "application/x-ndjson",
        description = "the whole flight log file, one JSON record per line (header first), \
            as an attachment named after the log"),
        (status = 404, body = ErrorBody, description = "no such log in the list")))]
pub async fn download(
    State(s): State<ApiState>,
    Path(name): Path<String>,
) -> Result<Response, ApiError> {
    let (dir, entry) = listed(&s, &name).await?;
    let path = dir.join(&entry.name);
    let file = tokio::fs::File::open(&path)
        .await
        .map_err(|e| ApiError::NotFound(format!("flight log {}: {e}", path.display())))?;
    let chunks = futures::stream::try_unfold(file, |mut file| async move {
        let mut buf = vec![0u8; CHUNK_BYTES];
        let n = file.read(&mut buf).await?;
        if n == 0 {
            return Ok::<_, std::io::Error>(None);
        }
        buf.truncate(n);
        Ok(Some((buf, file)))
    });
    // Listed names are `kestrel-...Z.jsonl` (or `.mcap`) or the file name given to `--log`; only printable
    // ASCII other than quote and backslash is kept, so the header is valid whatever that was.
    let filename: String = entry
        .name
        .chars()
        .filter(|c| (c.is_ascii_graphic() || *c == ' ') && *c != '"' && *c != '\\')
        .collect();
    Ok((
        [
            (header::CONTENT_TYPE, content_type(&entry.name).to_string()),
            (
                header::CONTENT_DISPOSITION,
                format!("attachment; filename=\"{filename}\""),
            ),
        ],
        Body::from_stream(chunks),
    )
        .into_response())
}

/// An MCAP log is binary; every other log is JSON lines.
fn content_type(name: &str) -> &'static str {
    if name.ends_with(".mcap") {
        "application/octet-stream"
    } else {
        "application/x-ndjson"
    }
}
