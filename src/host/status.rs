//! What the host publishes: each drone's status and telemetry, and the events of a tick.
//!
//! In: a drone core and its executor. Out: [`DroneStatus`] (the API's `DroneStatus`) and
//! [`HostEvent`]s, serialised by the API as they are.

use crate::behavior::{ActiveInfo, BehaviorEvent};
use crate::core::DroneCore;
use crate::mapping::merged::MapPatch;
use crate::mapping::GridSpec;
use crate::mission::{Action, MissionExecutor, MissionStatus};
use crate::types::{FlightStatus, LinkHealth};
use serde::{Deserialize, Serialize};
use std::sync::Arc;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct BatteryStatus {
    pub voltage_v: f64,
    pub remaining_fraction: Option<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct GeoStatus {
    pub lat_deg: f64,
    pub lon_deg: f64,
    pub alt_m: f64,
}

/// One drone, as `GET /api/status` and WebSocket telemetry show it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct DroneStatus {
    pub drone: String,
    #[schema(value_type = String)]
    pub link: LinkHealth,
    pub armed: bool,
    pub offboard: bool,
    pub mode: String,
    #[schema(value_type = String)]
    pub flight: FlightStatus,
    pub ready_to_fly: bool,
    /// Autopilot reboots seen since Kestrel started.
    #[serde(default)]
    pub boot_counter: u32,
    pub battery: Option<BatteryStatus>,
    pub last_error: Option<String>,
    /// Where the autopilot is heard and answered (MAVLink `udpin`: `IP:port`); null on other
    /// transports and in the simulator.
    #[serde(default)]
    pub autopilot_address: Option<String>,
    /// How many times another address took the autopilot's place (README, "Who is answered on
    /// `udpin`").
    #[serde(default)]
    pub autopilot_address_changes: u32,
    /// Whether the autopilot (or simulator) has given a position: until it has, position,
    /// yaw, velocity and geo are `null`.
    pub has_position: bool,
    /// The link is lost: everything below is the last known, `age_s` old.
    pub stale: bool,
    /// Seconds since the last valid position; absent before the first.
    pub age_s: Option<f64>,
    pub position_enu_m: Option<[f64; 3]>,
    pub yaw_rad: Option<f64>,
    pub velocity_enu_mps: Option<[f64; 3]>,
    pub geo: Option<GeoStatus>,
    #[schema(value_type = Vec<Object>)]
    pub active_behaviors: Vec<ActiveInfo>,
    /// Absent in telemetry frames (mission status has its own message).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mission: Option<MissionStatus>,
}

impl DroneStatus {
    pub fn of(core: &DroneCore, executor: &MissionExecutor) -> Self {
        let s = core.vehicle_state();
        let age = core.position_age();
        // Nothing is made up before the first position: a client plotting these without
        // reading `has_position` would draw a drone that is not there.
        let known = age.is_some().then_some(&s.estimate);
        let p = known.map(|e| e.pose.position_m);
        Self {
            drone: s.drone,
            link: s.platform.link,
            armed: s.platform.armed,
            offboard: s.platform.offboard,
            mode: s.platform.mode,
            flight: s.platform.flight,
            ready_to_fly: s.platform.ready_to_fly,
            boot_counter: s.platform.boot_counter,
            battery: s.platform.battery.map(|b| BatteryStatus {
                voltage_v: b.voltage_v,
                remaining_fraction: b.remaining_fraction,
            }),
            last_error: s.platform.last_error,
            autopilot_address: s.platform.autopilot_address,
            autopilot_address_changes: s.platform.autopilot_address_changes,
            has_position: age.is_some(),
            stale: s.platform.link == LinkHealth::Lost,
            age_s: age.map(|a| a.as_secs_f64()),
            position_enu_m: p.map(|p| [p.x, p.y, p.z]),
            yaw_rad: known.map(|e| e.pose.yaw_rad()),
            velocity_enu_mps: known.map(|e| {
                let v = e.velocity_enu_mps;
                [v.x, v.y, v.z]
            }),
            geo: p.map(|p| {
                let geo = core.geo_origin().to_geo(&p);
                GeoStatus {
                    lat_deg: geo.lat_deg,
                    lon_deg: geo.lon_deg,
                    alt_m: geo.alt_m,
                }
            }),
            active_behaviors: core.server().active(),
            mission: Some(executor.status(core)),
        }
    }
}

/// The latest state of every drone; replaced, never queued.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct HostSnapshot {
    /// Seconds since the host started (simulated time in the simulator).
    pub t: f64,
    pub drones: Vec<DroneStatus>,
    /// The drones other Kestrels of the fleet fly, as heard over the fleet bus (no commands:
    /// those go to their own Kestrel).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub remote: Vec<crate::fleet_bus::remote::RemoteDroneStatus>,
    /// The fleet bus, when this Kestrel is on one (refreshed once a second).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fleet_bus: Option<BusReport>,
}

/// The fleet bus as the API shows it: traffic since start, refusals, and the latency from a
/// peer sending a state to this Kestrel taking it in (its fleet view has it at the next tick).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct BusReport {
    pub fleet: String,
    pub node: String,
    pub state_sent: u64,
    pub state_sent_bytes: u64,
    pub map_sent: u64,
    pub map_sent_bytes: u64,
    pub received: u64,
    pub received_bytes: u64,
    /// Peer messages that did not decode, check or apply.
    pub refused: u64,
    /// Messages not queued because a queue was full.
    pub dropped: u64,
    /// Over the last states received (at most 2048).
    pub latency_samples: usize,
    pub latency_p50_ms: Option<f64>,
    pub latency_p99_ms: Option<f64>,
    /// Whether this node has joined its fleet: every peer of `[fleet] connect` answered once
    /// (listing none: a peer was heard). Latched: a peer lost later follows the lost-peer rules.
    pub joined: bool,
    /// Missions and explorations are refused (`409 fleet_not_joined`) until joined: peers are
    /// listed and `[fleet] require_join` is on.
    pub join_required: bool,
    /// Handshakes refused for their credentials, by a peer or by this node.
    pub refused_joins: u64,
    /// The peers of `connect` not joined yet, each with why.
    pub waiting_for: Vec<String>,
}

/// Something that happened, for WebSocket clients and logs.
#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "type", rename_all = "snake_case")]
pub enum HostEvent {
    /// A mission status changed.
    MissionStatus {
        drone: String,
        status: MissionStatus,
    },
    Event {
        drone: String,
        t: f64,
        event: EventBody,
    },
    /// A changed region of a map (`drone` None = the merged map), throttled by the runtime.
    MapUpdate {
        drone: Option<String>,
        /// The drone whose scans changed it.
        changed_by: String,
        /// `[x_min, y_min, x_max, y_max]` (ENU m).
        bbox: [f64; 4],
        /// The region as a grid of its own (origin = its south-west corner).
        spec: GridSpec,
        /// Row-major from the south-west cell: -1 unknown, else 0..=100.
        data: Vec<i8>,
    },
}

impl HostEvent {
    /// A changed region of the merged map.
    pub fn map_update(patch: MapPatch) -> Self {
        HostEvent::MapUpdate {
            drone: None,
            changed_by: patch.drone,
            bbox: patch.bbox_enu_m,
            spec: patch.spec,
            data: patch.data,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum EventBody {
    /// Behavior started, paused, resumed, modified, finished.
    Behavior(BehaviorEvent),
    /// A MissionUpdate and its answer.
    MissionUpdate {
        action: Action,
        mission_id: Option<u32>,
        accepted: bool,
        reason: Option<String>,
    },
    /// The autopilot's own words (MAVLink STATUSTEXT, a refusal).
    Autopilot { text: String },
    /// Link changes, collisions, faults.
    Alert { message: String },
}

pub type SharedEvent = Arc<HostEvent>;

/// Link state in words, for alerts.
pub fn link_word(link: LinkHealth) -> &'static str {
    match link {
        LinkHealth::Connecting => "connecting",
        LinkHealth::Ok => "ok",
        LinkHealth::Lost => "lost",
    }
}
