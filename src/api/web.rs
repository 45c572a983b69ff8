//! The static ground station: `web/dist` (built by the web app's Vite build), embedded in
//! release builds and read from disk in debug builds; a short page when it was not built.
//!
//! In: any GET outside `/api`. Out: the file, `index.html` for app routes, or the notice page.

use axum::http::{header, StatusCode, Uri};
use axum::response::{Html, IntoResponse, Response};

#[derive(rust_embed::RustEmbed)]
#[folder = "$CARGO_MANIFEST_DIR/web/dist"]
#[allow_missing = true]
struct Dist;

const NOT_BUILT: &str = "<!doctype html><html><head><title>Kestrel</title></head><body>\
<h1>Kestrel</h1><p>The ground station is not built. Build it with <code>npm ci &amp;&amp; npm run build</code> \
in <code>web/</code>, then rebuild Kestrel. The API is at <a href=\"/api/health\">/api/health</a> \
(<a href=\"/api/openapi.json\">OpenAPI</a>).</p></body></html>";

pub async fn static_file(uri: Uri) -> Response {
    let path = uri.path().trim_start_matches('/');
    if path.starts_with("api/") || path == "api" {
        return (StatusCode::NOT_FOUND, axum::Json(serde_json::json!({
            "error": {"code": "not_found", "message": format!("no route {}", uri.path()), "details": []}
        })))
            .into_response();
    }
    let path = if path.is_empty() { "index.html" } else { path };
    if let Some(file) = Dist::get(path) {
        let mime = mime_guess::from_path(path).first_or_octet_stream();
        return (
            [(header::CONTENT_TYPE, mime.as_ref().to_string())],
            file.data,
        )
            .into_response();
    }
    match Dist::get("index.html") {
        // An app route (no file extension): the app's router handles it.
        Some(index) if !path.contains('.') => {
            ([(header::CONTENT_TYPE, "text/html")], index.data).into_response()
        }
        Some(_) => StatusCode::NOT_FOUND.into_response(),
        None => Html(NOT_BUILT).into_response(),
    }
}
