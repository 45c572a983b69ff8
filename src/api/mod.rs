//! The HTTP/WebSocket ground-station API (axum), as `docs/API.md` describes it.
//!
//! In: HTTP requests and WebSocket messages. Out: commands to the host (bounded channel,
//! one-shot replies) and answers built from the host's latest published state. Security:
//! bearer token on everything but health, the OpenAPI spec and the static ground station;
//! CORS allow-list; body size limit; request timeout; and before any of that, a connection
//! limit with header-read and idle timeouts (`serve`).

pub mod auth;
pub mod body;
pub mod coverage;
pub mod error;
pub mod exploration;
pub mod geofence;
pub mod logs;
pub mod map;
pub mod openapi;
pub mod quiet;
pub mod reports;
pub mod routes;
pub mod saved;
pub mod scans;
pub mod serve;
pub mod web;
pub mod ws;

use crate::config::ApiSection;
use crate::flightlog::writer::LogFile;
use crate::host::store::Sink;
use crate::host::HostHandle;
use axum::extract::DefaultBodyLimit;
use axum::http::{header, HeaderValue, Method};
use axum::routing::{get, post};
use axum::{middleware, Router};
use std::sync::atomic::AtomicUsize;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tower_http::cors::{AllowOrigin, CorsLayer};

#[derive(Clone)]
pub struct ApiState {
    pub host: HostHandle,
    pub token: Option<Arc<str>>,
    pub started: Instant,
    pub max_body_bytes: usize,
    pub max_ws_clients: usize,
    pub ws_clients: Arc<AtomicUsize>,
    pub log: Option<LogFile>,
    /// Browser origins allowed besides the server's own (`[api] cors_origins`).
    pub cors_origins: Arc<[String]>,
    /// The state directory's writer: changes are acknowledged once it saved them.
    pub store: Option<Sink>,
}

impl ApiState {
    pub fn new(
        host: HostHandle,
        token: Option<String>,
        api: &ApiSection,
        log: Option<LogFile>,
    ) -> Self {
        Self {
            host,
            token: token.map(Arc::from),
            started: Instant::now(),
            max_body_bytes: api.max_body_bytes,
            max_ws_clients: api.max_ws_clients,
            ws_clients: Arc::new(AtomicUsize::new(0)),
            log,
            cors_origins: api.cors_origins.clone().into(),
            store: None,
        }
    }

    /// Acknowledges changes only once `store` saved them (`None`: nothing is kept).
    pub fn with_store(mut self, store: Option<Sink>) -> Self {
        self.store = store;
        self
    }
}

/// Map, scans, coverage, exploration and geofence routes (`api::map`, `api::scans`,
/// `api::coverage`, `api::exploration`).
fn map_routes() -> Router<ApiState> {
    Router::new()
        .route("/api/map", get(map::grid))
        .route("/api/map.png", get(map::png))
        .route("/api/map/info", get(map::info))
        .route("/api/exploration", get(map::exploration))
        .route("/api/exploration/start", post(exploration::start))
        .route("/api/exploration/stop", post(exploration::stop))
        .route("/api/exploration/report", get(exploration::report))
        .route("/api/scans", post(map::post_scans))
        .route("/api/coverage", post(coverage::plan))
        .route("/api/geofence", get(geofence::geofence))
}

/// Every route, with its layers.
pub fn router(state: ApiState, api: &ApiSection) -> Router {
    let protected = Router::new()
        .route("/api/status", get(routes::status))
        .route("/api/behaviors", get(routes::behaviors))
        .route("/api/missions", get(routes::missions).post(routes::upload))
        .route(
            "/api/missions/{id}",
            get(routes::mission).delete(routes::delete_mission),
        )
        .route("/api/mission_update", post(routes::mission_update))
        .route("/api/frames", get(routes::frames).post(routes::set_frame))
        .route("/api/log", get(routes::log))
        .route("/api/logs", get(routes::logs))
        .route("/api/logs/{name}", get(logs::download))
        .route("/api/logs/{name}/report", get(reports::report))
        .route("/api/sim/fault", post(routes::sim_fault))
        .route("/api/ws", get(ws::upgrade))
        .merge(map_routes())
        .route_layer(middleware::from_fn_with_state(
            state.clone(),
            auth::require_token,
        ));
    let open = Router::new()
        .route("/api/health", get(routes::health))
        .route("/api/openapi.json", get(openapi::serve));
    let mut app = protected
        .merge(open)
        .fallback(web::static_file)
        .layer(DefaultBodyLimit::max(api.max_body_bytes))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            body::refuse_large,
        ))
        .layer(middleware::from_fn_with_state(
            state.clone(),
            auth::this_site_only_without_token,
        ))
        .layer(tower_http::timeout::TimeoutLayer::with_status_code(
            axum::http::StatusCode::REQUEST_TIMEOUT,
            Duration::from_secs_f64(api.request_timeout_s),
        ))
        .layer(middleware::from_fn(error::json_errors))
        .layer(tower_http::trace::TraceLayer::new_for_http());
    let origins: Vec<HeaderValue> = api
        .cors_origins
        .iter()
        .filter_map(|o| HeaderValue::from_str(o).ok())
        .collect();
    if !origins.is_empty() {
        app = app.layer(
            CorsLayer::new()
                .allow_origin(AllowOrigin::list(origins))
                .allow_methods([Method::GET, Method::POST, Method::DELETE])
                .allow_headers([header::AUTHORIZATION, header::CONTENT_TYPE]),
        );
    }
    app.with_state(state)
}
