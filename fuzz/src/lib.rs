//! Fuzz targets: untrusted bytes in, Kestrel's real parsing and dispatch code called, nothing
//! returned. A target fails only by panicking, running away with memory or time (AFL's `-m` and
//! `-t` limits in `run.sh`), never by rejecting its input: rejecting garbage is the job.
//!
//! - [`mavlink`]: a `.tlog` (8-byte big-endian microsecond stamp + one MAVLink frame, as the
//!   captures in `../shared/traces/`) decoded frame by frame and dispatched into a
//!   [`Session`] (vehicle model, command tracker, actions), with the session's timers, control
//!   ticks, requests and feedback driven between frames as `kestrel run` does;
//! - [`mission`]: mission JSON text through `validate_text` (JSON, behaviors, arguments,
//!   limits, frames, geofence) as `kestrel mission validate` and `POST /api/missions` do;
//! - [`scans`]: a `POST /api/scans` body as `KSC1` binary and as JSON (every scan kind);
//! - [`config`]: TOML text as a Kestrel config (`kestrel.toml`) and as a platform profile
//!   (`platforms/*.toml`), with what `kestrel run` derives from a validated config (safety,
//!   executor, mission limits, MAVLink session and peers, the map grid);
//! - [`fleet_wire`]: a fleet-bus message from a peer, as a drone-state message and as a map
//!   region (bounds checks, inflating), applied to remote drones and a merged map as
//!   `kestrel run` does with what a peer sends;
//! - [`fleet_intake`]: a sample heard on the fleet bus, through the intake every peer's message
//!   passes (roster, size, signed envelope, replay counter, decoding, whose node and drones),
//!   once as it came and once sealed with the member's own key, so that the checks behind the
//!   signature are reached too.

use kestrel::behavior::Registry;
use kestrel::config::Config;
use kestrel::estimator::frames::FrameTree;
use kestrel::estimator::geodetic::GeodeticOrigin;
use kestrel::mission::validate::{validate_text, ValidationContext};
use kestrel::mission::Limits;
use kestrel::platform::mavlink::{tlog, Profile, Session, SessionConfig};
use kestrel::safety::LowestHeight;
use kestrel::types::{PlatformRequest, Setpoint, Vec3, YawTarget};
use std::hint::black_box;
use std::sync::OnceLock;
use std::time::Duration;

/// Requests a frame's stamp can ask for (see [`mavlink`]).
const REQUESTS: [PlatformRequest; 8] = [
    PlatformRequest::Arm,
    PlatformRequest::Disarm,
    PlatformRequest::StartOffboard,
    PlatformRequest::Takeoff { height_m: 2.5 },
    PlatformRequest::Land,
    PlatformRequest::PointGimbal {
        pitch_rad: -0.5,
        yaw_rad: 0.2,
    },
    PlatformRequest::TakePhoto,
    PlatformRequest::Arm,
];

fn profiles() -> &'static [Profile] {
    static PROFILES: OnceLock<Vec<Profile>> = OnceLock::new();
    PROFILES.get_or_init(|| {
        ["px4", "ardupilot-copter"]
            .into_iter()
            .filter_map(Profile::builtin)
            .filter_map(Result::ok)
            .collect()
    })
}

/// A tlog decoded and dispatched into a fresh session. The low bit of the first stamp picks the
/// autopilot profile (PX4 or ArduPilot); a frame whose stamp (µs) is 0 mod 16 also brings the
/// request `REQUESTS[(stamp / 16) % 8]`, so inputs reach the action and command-retry code.
pub fn mavlink(data: &[u8]) {
    let pick = data.get(7).map_or(0, |b| usize::from(b & 1));
    let Some(profile) = profiles().get(pick).or(profiles().first()) else {
        return;
    };
    let mut session = Session::new(profile.clone(), SessionConfig::default());
    let mut t0 = None;
    for (stamp, frame) in tlog::frames(data) {
        let start = *t0.get_or_insert(stamp);
        // Captures go backwards at times (clock steps); the session must bear that.
        let now = stamp.saturating_sub(start);
        if let Some((header, msg)) = tlog::decode_frame(frame) {
            session.on_message(now, &header, &msg);
        }
        let micros = stamp.as_micros();
        let requests: &[PlatformRequest] = if micros % 16 == 0 {
            let i = usize::try_from((micros / 16) % 8).unwrap_or(0);
            REQUESTS.get(i..=i).unwrap_or(&[])
        } else {
            &[]
        };
        let setpoint = Setpoint::Position {
            position_enu_m: Vec3::new(1.0, 2.0, 3.0),
            velocity_ff_enu_mps: Vec3::zeros(),
            yaw: YawTarget::Angle(0.0),
        };
        session.on_control(now, Some(setpoint), requests);
        session.on_tick(now);
        black_box(session.feedback(now));
        black_box(session.drain_outgoing());
    }
    // Time runs on with the link silent: link loss, retries running out, actions failing.
    if let Some(start) = t0 {
        let mut now = start;
        for _ in 0..4 {
            now += Duration::from_secs(3);
            session.on_tick(now);
            black_box(session.feedback(now));
        }
    }
    black_box(session.stats());
}

struct MissionRig {
    registry: Registry,
    limits: Limits,
    frames: FrameTree,
    geo_origin: GeodeticOrigin,
}

fn mission_rig() -> &'static MissionRig {
    static RIG: OnceLock<MissionRig> = OnceLock::new();
    RIG.get_or_init(|| MissionRig {
        registry: kestrel::behavior::payload::registry(),
        limits: Limits::default(),
        frames: FrameTree::new(),
        geo_origin: GeodeticOrigin::default(),
    })
}

/// Mission text validated for `drone_0` at home (0, 0, 0) with the default config's limits and
/// geofence, the behaviors missions can use, the fixed frames and a lowest flight height (an
/// autopilot's on a barometer).
pub fn mission(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let rig = mission_rig();
    let ctx = ValidationContext {
        drone_id: "drone_0",
        registry: &rig.registry,
        limits: &rig.limits,
        frames: &rig.frames,
        now: Duration::ZERO,
        home_enu_m: Vec3::zeros(),
        geo_origin: &rig.geo_origin,
        lowest_height: Some(LowestHeight {
            height_m: 2.0,
            error_m: 1.5,
        }),
    };
    match validate_text(text, &ctx) {
        Ok(valid) => {
            // What the API stores and returns for an accepted mission.
            black_box(
                valid
                    .as_written()
                    .and_then(|m| serde_json::to_string(&m))
                    .ok(),
            );
        }
        Err(errors) => {
            black_box(errors.iter().map(ToString::to_string).count());
        }
    }
}

/// A scans body, decoded both as `KSC1` binary and as JSON.
pub fn scans(data: &[u8]) {
    let as_binary = kestrel::api::scans::body_scans(data, true, None);
    black_box(as_binary.is_ok());
    let as_json = kestrel::api::scans::body_scans(data, false, Some("drone_0".into()));
    black_box(as_json.is_ok());
}

/// TOML text, parsed and validated as a Kestrel config and as a platform profile.
pub fn config(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    if let Ok(config) = Config::parse(text, "fuzz") {
        black_box(config.safety_config());
        black_box(config.executor_config());
        black_box(config.mission_limits());
        black_box(config.mavlink.peer_policy());
        black_box(config.mavlink.session_config());
        // What `kestrel run` builds from [map]: the grid (bounded by MAX_CELLS) and its timing.
        black_box(config.map.config(None).is_ok());
    }
    black_box(Profile::parse(text, "fuzz").is_ok());
}

/// A fleet-bus payload (what is left once the intake opened its signed envelope; the envelope
/// itself needs the `fleet-bus` feature, which this crate leaves out): decoded as a state and as
/// a map message; what decodes is applied as the host does: to a remote fleet whose roster gives the message's
/// node its drones, and through the map inbox (coalesced, taken a few rows at a time) to a
/// merged map on the open-field grid.
pub fn fleet_wire(data: &[u8]) {
    use kestrel::fleet_bus::inbox::MapInbox;
    use kestrel::fleet_bus::remote::{RemoteFleet, SilencePolicy};
    use kestrel::fleet_bus::wire::{MapMsg, StateMsg};
    use kestrel::mapping::config::MapConfig;
    use kestrel::mapping::merged::{FleetMap, LayerRegion};
    use std::time::Duration;
    if let Ok(msg) = StateMsg::decode(data) {
        let drones = msg.drones.iter().map(|d| d.id.clone()).collect();
        let roster = [(msg.node.clone(), drones)].into();
        let mut remote = RemoteFleet::new(
            SilencePolicy {
                peer_timeout: Duration::from_millis(1500),
                lost_after: Duration::from_secs(10),
                keepout_m: 0.5,
            },
            roster,
        );
        black_box(remote.apply(msg, Duration::from_secs(1), &["drone_0".to_string()]));
        black_box(remote.views(Duration::from_secs(3)).count());
        black_box(remote.claims());
    }
    let Ok(config) = MapConfig::open_field() else {
        return;
    };
    let Ok(mut map) = FleetMap::new(&config) else {
        return;
    };
    let cells = map.merged().spec().cell_count();
    if let Ok(msg) = MapMsg::decode(data, cells) {
        let inbox = MapInbox::default();
        black_box(inbox.offer(msg.clone()).is_ok());
        black_box(inbox.offer(msg).is_ok());
        while let Some(slice) = inbox.take(4096) {
            let region = LayerRegion {
                drone: slice.drone,
                grid: slice.grid,
                region: slice.region,
                cells: slice.cells,
            };
            black_box(map.apply_remote(&region).is_ok());
        }
    }
}

/// Key expressions a sample can arrive on: a member's state and map, a made-up node's state,
/// and a kind the intake does not read. The first byte of the input picks one.
const INTAKE_KEYS: [(&str, &str); 4] = [
    ("node_1", "state"),
    ("node_1", "map"),
    ("ghost", "state"),
    ("node_1", "status"),
];

/// The fleet's name in the keys of [`fleet_intake`].
const INTAKE_FLEET: &str = "fuzz";

pub fn fleet_intake(data: &[u8]) {
    use kestrel::fleet_bus::identity::Signer;
    use kestrel::fleet_bus::inbox::MapInbox;
    use kestrel::fleet_bus::intake::{Intake, Member};
    use kestrel::fleet_bus::stats::BusStats;
    use std::sync::Arc;
    let Some((&pick, sample)) = data.split_first() else {
        return;
    };
    let (node, kind) = INTAKE_KEYS[usize::from(pick) % INTAKE_KEYS.len()];
    let Ok(mut member_key) = Signer::from_seed(&[1; 32]) else {
        return;
    };
    let member = Member {
        keys: vec![member_key.public()],
        drones: vec!["drone_1".to_string()],
    };
    let (states, mut heard) = tokio::sync::mpsc::channel(4);
    let maps = Arc::new(MapInbox::default());
    let intake = Intake::new(
        INTAKE_FLEET,
        "node_0",
        [("node_1".to_string(), member)].into(),
        64 * 64,
        Arc::new(BusStats::default()),
        states,
        maps.clone(),
    );
    let key = format!("kestrel/{INTAKE_FLEET}/{node}/{kind}");
    black_box(intake.take(&key, sample).is_ok());
    let sealed = member_key.seal(INTAKE_FLEET, node, kind, sample);
    black_box(intake.take(&key, &sealed).is_ok());
    // Played again: refused by its counter.
    black_box(intake.take(&key, &sealed).is_ok());
    while let Ok(state) = heard.try_recv() {
        black_box(state);
    }
    while let Some(slice) = maps.take(4096) {
        black_box(slice);
    }
}
