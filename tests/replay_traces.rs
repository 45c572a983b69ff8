//! Replay: the real PX4 and ArduPilot captures in `../shared/traces/` decoded through the
//! platform layer. Every HEARTBEAT, EXTENDED_SYS_STATE and LOCAL_POSITION_NED line of the
//! independent pymavlink listing (`.txt`) is checked against the vehicle model right after the
//! same frame went through it; the companion's commands are re-issued through the command
//! tracker, whose outcomes must match the autopilot's acks and carry its reasons.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kestrel::platform::mavlink::commands::{CommandOutcome, CommandSpec, CommandTracker};
use kestrel::platform::mavlink::model::VehicleModel;
use kestrel::platform::mavlink::{tlog, Profile};
use kestrel::types::Vec3;
use mavlink::dialects::ardupilotmega::{MavMessage, MavResult, LOCAL_POSITION_NED_DATA};
use mavlink::Message;
use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Duration;

fn traces() -> PathBuf {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let candidates = [
        std::env::var("KESTREL_TRACES").map(PathBuf::from).ok(),
        Some(here.join("../shared/traces")),
        Some(here.join("../../shared/traces")),
    ];
    candidates
        .into_iter()
        .flatten()
        .find(|p| p.join("README.md").exists())
        .expect("captures not found: set KESTREL_TRACES to the shared/traces directory")
}

/// One line of the decoded listing.
struct Line {
    /// Seconds since the first message (PX4 listings) or since the epoch (ArduPilot).
    time_s: f64,
    src: String,
    name: String,
    fields: HashMap<String, String>,
}

impl Line {
    fn f64(&self, k: &str) -> f64 {
        self.fields[k].parse().unwrap()
    }
}

/// Parses both listing formats: `NAME t= 1.0 src=1/1 k=v ...` and
/// `EPOCH + REL < 1/1 NAME k=v ...`.
fn listing(name: &str) -> Vec<Line> {
    let text = std::fs::read_to_string(traces().join(name)).unwrap();
    let mut out = Vec::new();
    for l in text.lines().filter(|l| !l.starts_with('#')) {
        let tokens: Vec<&str> = l.split_whitespace().collect();
        let (time_s, src, name, rest) = match tokens.as_slice() {
            [epoch, "+", _, "<" | ">", src, name, rest @ ..] => (
                epoch.parse().unwrap(),
                src.to_string(),
                name.to_string(),
                rest,
            ),
            [name, "t=", t, src, rest @ ..] if src.starts_with("src=") => (
                t.parse().unwrap(),
                src[4..].to_string(),
                name.to_string(),
                rest,
            ),
            _ => continue,
        };
        let fields = rest
            .iter()
            .filter_map(|kv| kv.split_once('='))
            .map(|(k, v)| (k.to_string(), v.to_string()))
            .collect();
        out.push(Line {
            time_s,
            src,
            name,
            fields,
        });
    }
    out
}

struct Replay {
    model: VehicleModel,
    tracker: CommandTracker,
    commands: Vec<(kestrel::platform::mavlink::commands::CommandId, String)>,
    outcomes: Vec<(String, CommandOutcome)>,
    checked: HashMap<&'static str, usize>,
}

fn close(a: f64, b: f64) -> bool {
    (a - b).abs() <= 1e-3 * b.abs().max(1.0)
}

/// Replays a capture; `epoch_times` says whether the listing stamps are absolute.
fn replay(
    capture: &str,
    listing_name: &str,
    profile: &str,
    companion: (u8, u8),
    epoch_times: bool,
) -> Replay {
    let profile = Profile::builtin(profile).unwrap().unwrap();
    let bytes = std::fs::read(traces().join(capture)).unwrap();
    let log = tlog::read(&bytes);
    assert!(
        log.records.len() > 1000,
        "{capture}: {} records",
        log.records.len()
    );
    let t0 = log.records[0].stamp;
    let key = |s: f64| (s * if epoch_times { 1e6 } else { 1e3 }).round() as i64;
    let mut expected: HashMap<(String, i64), Line> = HashMap::new();
    for l in listing(listing_name) {
        if l.src == "1/1"
            && ["HEARTBEAT", "EXTENDED_SYS_STATE", "LOCAL_POSITION_NED"].contains(&l.name.as_str())
        {
            expected.insert((l.name.clone(), key(l.time_s)), l);
        }
    }
    let total_expected = expected.len();
    let mut before_contact = 0;
    let mut r = Replay {
        model: VehicleModel::new(profile.clone(), None),
        tracker: CommandTracker::new(Duration::from_millis(1500), 0),
        commands: Vec::new(),
        outcomes: Vec::new(),
        checked: HashMap::new(),
    };
    for rec in &log.records {
        let now = rec.stamp - t0;
        let from_companion = rec.header.system_id == u32::from(companion.0)
            && rec.header.component_id == companion.1;
        if from_companion {
            if let MavMessage::COMMAND_LONG(c) = &rec.msg {
                let id = r.tracker.submit(CommandSpec {
                    command: c.command,
                    params: [
                        c.param1, c.param2, c.param3, c.param4, c.param5, c.param6, c.param7,
                    ],
                    target_component: c.target_component,
                });
                let sent = r.tracker.poll(now, c.target_system);
                assert_eq!(
                    sent.len(),
                    1,
                    "one command in flight at a time in this capture"
                );
                r.commands.push((id, format!("{:?}", c.command)));
            }
        } else {
            r.model.ingest(now, &rec.header, &rec.msg);
            if let MavMessage::COMMAND_ACK(ack) = &rec.msg {
                r.tracker.on_ack(now, ack, companion.0, companion.1);
            }
            if let Some(text) = r.model.texts().last().filter(|t| t.at == now) {
                r.tracker.on_text(&text.clone());
            }
        }
        r.tracker.poll(now, 1);
        let commands = std::mem::take(&mut r.commands);
        for (id, name) in commands {
            match r.tracker.take_outcome(id) {
                Some(o) => r.outcomes.push((name, o)),
                None => r.commands.push((id, name)),
            }
        }
        let stamp_s = if epoch_times {
            rec.stamp.as_secs_f64()
        } else {
            now.as_secs_f64()
        };
        let name = rec.msg.message_name();
        let line = [0, -1, 1]
            .iter()
            .find_map(|d| expected.remove(&(name.to_string(), key(stamp_s) + d)));
        let from_autopilot = rec.header.system_id == 1 && rec.header.component_id == 1;
        match line.filter(|_| from_autopilot) {
            // Telemetry before the first HEARTBEAT is not followed: the autopilot is unknown.
            Some(_) if r.model.autopilot().is_none() => before_contact += 1,
            Some(line) => {
                check(&r.model, &profile, now, &line);
                *r.checked.entry(name).or_default() += 1;
            }
            None => {}
        }
    }
    let checked: usize = r.checked.values().sum();
    assert!(
        before_contact < 5,
        "{capture}: {before_contact} lines before the first HEARTBEAT"
    );
    assert!(
        (checked + before_contact) * 100 >= total_expected * 98,
        "{capture}: only {checked} of {total_expected} listing lines matched a frame"
    );
    r
}

fn check(model: &VehicleModel, profile: &Profile, now: Duration, line: &Line) {
    let at = format!("{} at {:.3} s", line.name, now.as_secs_f64());
    let status = model.status(now);
    match line.name.as_str() {
        "HEARTBEAT" => {
            let armed = line.f64("base_mode") as u32 & 128 != 0;
            assert_eq!(status.armed, armed, "{at}");
            let custom = line.f64("custom_mode") as u32;
            assert_eq!(model.custom_mode(), Some(custom), "{at}");
            let name = line
                .fields
                .get("mode")
                .cloned()
                .unwrap_or_else(|| profile.mode_name(custom));
            assert_eq!(status.mode, name, "{at}");
        }
        "EXTENDED_SYS_STATE" => {
            let landed = model.landed_state().map(|s| s as u8);
            assert_eq!(landed, Some(line.f64("landed_state") as u8), "{at}");
        }
        "LOCAL_POSITION_NED" => {
            let Some(kestrel::estimator::Measurement::AutopilotOdometry {
                pose,
                velocity_enu_mps,
                ..
            }) = model.odometry(now)
            else {
                panic!("{at}: no odometry");
            };
            let p = pose.position_m;
            let v = velocity_enu_mps;
            let want_p = Vec3::new(line.f64("y"), line.f64("x"), -line.f64("z"));
            // The velocity as reported, less the bias the profile's velocity check found
            // against the position (zero without the check).
            let want_v = Vec3::new(line.f64("vy"), line.f64("vx"), -line.f64("vz"))
                - model.velocity_bias_enu_mps();
            for i in 0..3 {
                assert!(
                    close(p[i], want_p[i]) && close(v[i], want_v[i]),
                    "{at}: {p} {v} vs {want_p} {want_v}"
                );
            }
        }
        _ => {}
    }
}

#[test]
fn px4_offboard_session_replays_modes_landed_states_positions_and_acks() {
    let r = replay(
        "px4_sih_offboard_session.tlog",
        "px4_sih_offboard_session.txt",
        "px4",
        (1, 191),
        false,
    );
    assert!(r.checked["HEARTBEAT"] >= 100, "{:?}", r.checked);
    assert!(r.checked["EXTENDED_SYS_STATE"] >= 90);
    assert!(r.checked["LOCAL_POSITION_NED"] >= 90);
    // Every command of the session ended; the arm without an offboard stream was refused
    // with PX4's own words, which PX4 sends as an EVENT after the ack.
    assert_eq!(r.outcomes.len(), 22, "{:?}", r.outcomes);
    let refusals: Vec<_> = r
        .outcomes
        .iter()
        .filter(|(_, o)| *o != CommandOutcome::Accepted)
        .collect();
    let arm = refusals
        .iter()
        .find(|(n, _)| n == "MAV_CMD_COMPONENT_ARM_DISARM")
        .expect("the denied arm");
    assert_eq!(
        arm.1,
        CommandOutcome::Rejected {
            result: MavResult::MAV_RESULT_TEMPORARILY_REJECTED,
            reason: Some("Arming denied: Resolve system health failures first".into()),
        }
    );
    assert!(
        refusals
            .iter()
            .any(|(n, o)| n == "MAV_CMD_SET_MESSAGE_INTERVAL"
                && matches!(
                    o,
                    CommandOutcome::Rejected {
                        result: MavResult::MAV_RESULT_FAILED,
                        ..
                    }
                )),
        "HEARTBEAT's rate cannot be changed: {refusals:?}"
    );
    // The offboard-loss failsafe is reported as PX4's EVENT.
    assert!(r.model.texts().any(|t| t.text == "Failsafe activated"));
}

#[test]
fn px4_failsafe_land_variant_replays() {
    let r = replay(
        "px4_sih_offboard_failsafe_land_variant.tlog",
        "px4_sih_offboard_failsafe_land_variant.txt",
        "px4",
        (1, 191),
        false,
    );
    assert!(r.checked["HEARTBEAT"] >= 20);
    assert!(r
        .outcomes
        .iter()
        .all(|(_, o)| !matches!(o, CommandOutcome::TimedOut { .. })));
}

#[test]
fn ardupilot_guided_session_replays_modes_landed_states_positions_and_acks() {
    let r = replay(
        "ardupilot_copter_guided_session.tlog",
        "ardupilot_copter_guided_session.txt",
        "ardupilot-copter",
        (255, 190),
        true,
    );
    assert!(r.checked["HEARTBEAT"] >= 80);
    assert!(r.checked["EXTENDED_SYS_STATE"] >= 50);
    assert!(r.checked["LOCAL_POSITION_NED"] >= 40);
    assert!(!r.outcomes.is_empty());
    assert!(
        r.outcomes
            .iter()
            .all(|(_, o)| *o == CommandOutcome::Accepted),
        "{:?}",
        r.outcomes
    );
    // The EKF gained its absolute position during the capture: the model says ready.
    let end = Duration::from_secs(89);
    assert!(r.model.texts().any(|t| t.text == "EKF3 IMU0 is using GPS"));
    assert_eq!(r.model.status(end).mode, "LAND");
    assert!(!r.model.status(end).armed);
}

#[test]
fn ardupilot_proximity_sectors_become_scans() {
    let bytes = std::fs::read(traces().join("ardupilot_copter_sensors_probe.tlog")).unwrap();
    let log = tlog::read(&bytes);
    let profile = Profile::builtin("ardupilot-copter").unwrap().unwrap();
    let mut model = VehicleModel::new(profile, None);
    let t0 = log.records[0].stamp;
    let mut beams = Vec::new();
    for rec in &log.records {
        let first_contact = model.autopilot().is_none();
        model.ingest(rec.stamp - t0, &rec.header, &rec.msg);
        if first_contact && model.autopilot().is_some() {
            // This probe has no position estimate: place the vehicle at the origin so that the
            // recorded DISTANCE_SENSOR frames can be turned into scans.
            let here = MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA::DEFAULT);
            model.ingest(rec.stamp - t0, &rec.header, &here);
        }
        for scan in model.take_scans() {
            beams.extend(
                scan.beams
                    .iter()
                    .map(|b| (b.angle_rad.to_degrees().round() as i64, b.range_m)),
            );
        }
    }
    let mut angles: Vec<i64> = beams.iter().map(|(a, _)| a.rem_euclid(360)).collect();
    angles.sort_unstable();
    angles.dedup();
    assert_eq!(
        angles,
        vec![0, 45, 90, 135, 180, 225, 270, 315],
        "eight 45-degree sectors"
    );
}
