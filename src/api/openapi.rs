//! The OpenAPI 3 description of the API, served at `/api/openapi.json`: generated from the
//! handlers' annotations and the Rust types by [`spec`], written to `docs/openapi.json` by a
//! test, and served as that text. Building the document at run time took about 0.55 MB of the
//! binary (BENCHMARKS.md, "Release binary size"); the test fails when the text is stale.

use super::error::ErrorBody;
use super::{coverage, exploration, geofence, map, scans};
use super::{logs, reports, routes};
use crate::host::engine::{FrameRegistration, MissionView, Updated, Uploaded};
use crate::host::runtime::BehaviorInfo;
use crate::host::status::{BatteryStatus, DroneStatus, GeoStatus};
use crate::mission::ValidationError;
use crate::mission::{DoneResult, ItemResult, Mission, MissionItem, MissionStatus, MissionUpdate};
use utoipa::openapi::security::{HttpAuthScheme, HttpBuilder, SecurityScheme};
use utoipa::{Modify, OpenApi};

struct BearerAuth;

impl Modify for BearerAuth {
    fn modify(&self, openapi: &mut utoipa::openapi::OpenApi) {
        if let Some(components) = openapi.components.as_mut() {
            components.add_security_scheme(
                "bearer",
                SecurityScheme::Http(HttpBuilder::new().scheme(HttpAuthScheme::Bearer).build()),
            );
        }
    }
}

#[derive(OpenApi)]
#[openapi(
    info(title = "Kestrel ground-station API", description = "Missions, MissionUpdate actions, frames, status and telemetry of Kestrel drones. WebSocket: GET /api/ws (see docs/API.md)."),
    paths(
        routes::health, routes::status, routes::behaviors, routes::missions, routes::upload,
        routes::mission, routes::delete_mission, routes::mission_update, routes::set_frame,
        routes::frames, routes::log, routes::logs, logs::download, reports::report, routes::sim_fault
    ),
    components(schemas(
        ErrorBody, ValidationError, Mission, MissionItem, MissionUpdate, MissionStatus,
        DoneResult, ItemResult, DroneStatus, BatteryStatus, GeoStatus, FrameRegistration,
        MissionView, Uploaded, Updated, BehaviorInfo, routes::Health, routes::StatusAnswer,
        routes::UpdateAnswer, routes::UploadAnswer, crate::api::saved::Durability,
        crate::host::store::StoreHealth, crate::host::store::Problem, routes::Fault,
        crate::flightlog::files::LogEntry
    )),
    modifiers(&BearerAuth),
    tags((name = "missions"), (name = "vehicles"), (name = "frames"), (name = "system"))
)]
pub struct ApiDoc;

/// Maps, scans, coverage and geofence (`api::map`, `api::coverage`, `api::geofence`).
#[derive(OpenApi)]
#[openapi(
    paths(map::grid, map::png, map::info, map::exploration, exploration::start, exploration::stop,
        exploration::report, map::post_scans, coverage::plan, geofence::geofence),
    components(schemas(
        map::MapInfo, crate::exploration::online::service::ExplorationView,
        crate::exploration::online::service::FrontierView, crate::exploration::online::service::ClaimView,
        crate::exploration::online::progress::ProgressView, crate::exploration::online::progress::RunDroneView,
        exploration::StartRequest, exploration::StopRequest,
        crate::host::engine::ExplorationStarted, crate::host::engine::StartedDrone,
        scans::ScanInput, scans::ScanBatch, coverage::CoverageRequest,
        coverage::CoverageAnswer
    )),
    tags((name = "map"))
)]
struct MapDoc;

/// The document as served: `docs/openapi.json`, as [`spec`] generated it.
pub const SPEC_JSON: &str = include_str!("../../docs/openapi.json");

/// The document generated from the annotations (tests and `docs/openapi.json`).
pub fn spec() -> utoipa::openapi::OpenApi {
    ApiDoc::openapi().merge_from(MapDoc::openapi())
}

/// `GET /api/openapi.json`.
pub async fn serve() -> impl axum::response::IntoResponse {
    (
        [(axum::http::header::CONTENT_TYPE, "application/json")],
        SPEC_JSON,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The served text is what the annotations generate now; `KESTREL_WRITE_OPENAPI=1` rewrites
    /// it.
    #[test]
    fn served_document_is_the_generated_one() {
        let generated = serde_json::to_value(spec()).unwrap();
        if std::env::var_os("KESTREL_WRITE_OPENAPI").is_some() {
            let text = serde_json::to_string_pretty(&generated).unwrap() + "\n";
            let path = concat!(env!("CARGO_MANIFEST_DIR"), "/docs/openapi.json");
            std::fs::write(path, text).unwrap();
            return;
        }
        let served: serde_json::Value = serde_json::from_str(SPEC_JSON).unwrap();
        assert!(
            served == generated,
            "docs/openapi.json is stale: rerun this test with KESTREL_WRITE_OPENAPI=1"
        );
    }
}
