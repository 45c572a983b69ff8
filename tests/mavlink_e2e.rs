//! End to end: the real `kestrel run` process against the fake autopilot (`sitl/`), both
//! personalities, over real MAVLink sockets. Positions are checked against the fake's true
//! state, setpoint gaps against the fake's own statistics.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink_support::{
    alongside, closest_approaches, demo_mission, demo_targets, serial, Api, Fake, Kestrel,
    Personality, DEMO, LISTEN_ANY,
};
use serde_json::{json, Value};
use std::time::Duration;

const FLIGHT_TIMEOUT: Duration = Duration::from_secs(120);

/// Flies the demo and checks every target; returns the fake, kestrel and the fake's setpoint
/// statistics up to the end of the takeoff (they are reset then: the rest of the flight is
/// what the fake reports at the end).
fn demo_flight(p: Personality, fake_args: &[&str], config: &str) -> (Fake, Kestrel, Value) {
    let fake = Fake::start(p, fake_args);
    let poller = fake.poll_states();
    let mut kestrel = Kestrel::run(p, &fake.connection, config, DEMO);
    kestrel.wait_line("takeoff #1 succeeded", Duration::from_secs(60));
    let takeoff = fake.cmd(json!({"cmd": "setpoint_stats", "reset": true}));
    let status = kestrel.wait(FLIGHT_TIMEOUT);
    let samples = poller.finish();
    assert!(
        status.success(),
        "{p:?} flight failed:\n{}",
        kestrel.output()
    );
    let approaches = closest_approaches(&samples, &demo_targets());
    for (target, d) in demo_targets().iter().zip(&approaches) {
        assert!(
            *d <= 0.3,
            "{p:?}: target {target:?} missed by {d:.2} m (all: {approaches:.2?})\n{}",
            kestrel.output()
        );
    }
    let end = fake.state();
    assert_eq!(end["armed"], false, "{end}");
    assert_eq!(end["on_ground"], true, "{end}");
    (fake, kestrel, takeoff)
}

/// The largest gap between two setpoints the fake saw while offboard (ms).
fn max_gap_ms(p: Personality, part: &str, stats: &Value) -> f64 {
    println!("{p:?} setpoint stream during {part}, seen by the fake: {stats}");
    stats["max_ms"].as_f64().unwrap_or(0.0)
}

#[test]
fn px4_demo_flight_reaches_every_target() {
    let _one = serial();
    let p = Personality::Px4;
    let (fake, _k, takeoff) = demo_flight(p, &[], "");
    let rest = fake.cmd(json!({"cmd": "setpoint_stats"}));
    assert!(rest["count"].as_u64().unwrap() > 500, "{rest}");
    // PX4 leaves OFFBOARD 1 s after the last setpoint: the stream stays far below that, from
    // the OFFBOARD takeoff to the switch to AUTO.LAND.
    for (part, stats) in [("takeoff", &takeoff), ("the rest", &rest)] {
        let max = max_gap_ms(p, part, stats);
        assert!(max < 200.0, "{max} ms gap during {part}: {stats}");
    }
}

#[test]
fn ardupilot_demo_flight_reaches_every_target() {
    let _one = serial();
    let p = Personality::Ardupilot;
    let (fake, _k, takeoff) = demo_flight(p, &[], "");
    let rest = fake.cmd(json!({"cmd": "setpoint_stats"}));
    assert!(rest["count"].as_u64().unwrap() > 500, "{rest}");
    // NAV_TAKEOFF climbs on the autopilot's own target, without setpoints (a position target
    // would cancel it): the fake leaves that climb out of its statistics by its own state, so
    // while the arming and the climb's end are flown on setpoints the stream must be steady.
    let p99 = takeoff["p99_ms"].as_f64().unwrap_or(f64::INFINITY);
    assert!(p99 < 40.0, "{takeoff}");
    for (part, stats) in [("takeoff", &takeoff), ("the rest", &rest)] {
        let max = max_gap_ms(p, part, stats);
        assert!(max < 200.0, "{max} ms gap during {part}: {stats}");
    }
}

/// Indoors without GPS, ArduPilot has no position (and refuses GUIDED and arming) until it
/// gets an EKF origin: Kestrel sends the configured one with SET_GPS_GLOBAL_ORIGIN.
#[test]
fn ardupilot_without_gps_flies_once_given_the_configured_ekf_origin() {
    let _one = alongside();
    let config =
        "[mavlink]\nekf_origin = { lat_deg = 40.4405, lon_deg = -3.68982, alt_m = 100.0 }\n";
    demo_flight(Personality::Ardupilot, &["--no-gps"], config);
}

#[test]
fn px4_flight_completes_with_ten_percent_packet_loss() {
    let _one = alongside();
    let p = Personality::Px4;
    let (fake, _k, _) = demo_flight(p, &["--packet-loss", "0.1"], "");
    let rest = fake.cmd(json!({"cmd": "setpoint_stats"}));
    let max = max_gap_ms(p, "the flight after takeoff, 10% loss", &rest);
    assert!(max < 1000.0, "PX4 would have left OFFBOARD: {rest}");
}

#[test]
fn ardupilot_flight_completes_with_ten_percent_packet_loss() {
    let _one = alongside();
    demo_flight(Personality::Ardupilot, &["--packet-loss", "0.1"], "");
}

fn arming_denied(p: Personality, expected: &str) {
    let _one = alongside();
    let fake = Fake::start(p, &["--deny-arm", "Throttle too high"]);
    let mut kestrel = Kestrel::run(p, &fake.connection, "", DEMO);
    let status = kestrel.wait(FLIGHT_TIMEOUT);
    let out = kestrel.output();
    assert!(!status.success(), "{out}");
    assert!(
        out.lines()
            .any(|l| l.contains("flight failed") && l.contains(expected)),
        "the autopilot's reason `{expected}` must end the run:\n{out}"
    );
    assert_eq!(fake.state()["armed"], false);
}

#[test]
fn px4_arming_denied_surfaces_the_event_text() {
    arming_denied(
        Personality::Px4,
        "Arming denied: Resolve system health failures first",
    );
}

#[test]
fn ardupilot_arming_denied_surfaces_the_statustext() {
    arming_denied(Personality::Ardupilot, "Arm: Throttle too high");
}

/// Drops the link for 3 s once `behavior` has flown for a while; returns when the drop began.
fn drop_link_during(fake: &Fake, kestrel: &Kestrel, behavior: &str) -> std::time::Instant {
    kestrel.wait_line(&format!("{behavior} #2 started"), Duration::from_secs(60));
    std::thread::sleep(Duration::from_millis(1500));
    let dropped_at = std::time::Instant::now();
    fake.cmd(json!({"cmd": "link_drop", "duration_s": 3.0}));
    dropped_at
}

/// When Kestrel saw the link go.
fn dropped_at_line(kestrel: &Kestrel) -> std::time::Instant {
    kestrel.line_at("link: lost").expect("a link loss")
}

fn link_lost_detected_quickly(kestrel: &Kestrel, dropped_at: std::time::Instant) {
    let lost = kestrel.wait_line("link: lost", Duration::from_secs(5));
    let detection = lost.duration_since(dropped_at);
    assert!(
        detection < Duration::from_secs(2),
        "link loss seen after {detection:?}\n{}",
        kestrel.output()
    );
    let out = kestrel.output();
    assert!(
        out.contains("link to the autopilot lost"),
        "the running behavior must end with the reason:\n{out}"
    );
}

/// `kestrel run` serving the API on a free port, with `config`.
fn kestrel_with_api(p: Personality, fake: &Fake, config: &str) -> (Kestrel, Api) {
    let kestrel = Kestrel::run(p, &fake.connection, config, &["--listen", LISTEN_ANY]);
    let api = kestrel.api();
    (kestrel, api)
}

/// On the API path: the demo uploaded and started over REST, the link cut for 3 s during its
/// go_to; with `resume` the interrupted go_to starts again and the mission finishes.
fn link_drop_resumes_the_mission(p: Personality) {
    let _one = alongside();
    let fake = Fake::start(p, &[]);
    let poller = fake.poll_states();
    let config = "[mission]\non_link_regained = \"resume\"\n";
    let (kestrel, api) = kestrel_with_api(p, &fake, config);
    api.fly(&demo_mission());
    let dropped_at = drop_link_during(&fake, &kestrel, "go_to");
    link_lost_detected_quickly(&kestrel, dropped_at);
    let mission = api.wait_mission_end(FLIGHT_TIMEOUT);
    let samples = poller.finish();
    let out = kestrel.output();
    assert!(mission["last_error"].is_null(), "{mission}\n{out}");
    assert_eq!(mission["pending_items"], 0, "{mission}");
    let lost: Vec<&Value> = mission["done_results"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|d| d["code"] == "link_lost")
        .collect();
    assert_eq!(lost.len(), 1, "{mission}");
    let back = kestrel.line_after("link: ok", dropped_at_line(&kestrel));
    assert!(
        back.is_some_and(|t| kestrel.line_after("go_to #3 started", t).is_some()),
        "the interrupted go_to must start again once the link is back:\n{out}"
    );
    // The autopilot's failsafe acted during the outage; the resumed plan still reaches what
    // follows the interrupted go_to.
    let targets = demo_targets();
    let approaches = closest_approaches(&samples, targets.get(1..).unwrap());
    assert!(
        approaches.iter().all(|d| *d <= 0.3),
        "{approaches:.2?}\n{out}"
    );
    let end = fake.state();
    assert_eq!(
        (end["armed"].clone(), end["on_ground"].clone()),
        (json!(false), json!(true)),
        "{end}"
    );
}

/// The same with `land`: the mission ends with `link_lost` and the vehicle lands where it is.
fn link_drop_lands(p: Personality) {
    let _one = alongside();
    let fake = Fake::start(p, &[]);
    let config = "[mission]\non_link_regained = \"land\"\n";
    let (kestrel, api) = kestrel_with_api(p, &fake, config);
    api.fly(&demo_mission());
    let dropped_at = drop_link_during(&fake, &kestrel, "go_to");
    link_lost_detected_quickly(&kestrel, dropped_at);
    let mission = api.wait_mission_end(FLIGHT_TIMEOUT);
    assert_eq!(mission["last_error_code"], "link_lost", "{mission}");
    let deadline = std::time::Instant::now() + Duration::from_secs(60);
    while fake.state()["armed"] == true && std::time::Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(200));
    }
    let end = fake.state();
    assert_eq!(
        (end["armed"].clone(), end["on_ground"].clone()),
        (json!(false), json!(true)),
        "{end}\n{}",
        kestrel.output()
    );
}

#[test]
fn px4_link_drop_mid_flight_resumes_the_mission() {
    link_drop_resumes_the_mission(Personality::Px4);
}

#[test]
fn ardupilot_link_drop_mid_flight_resumes_the_mission() {
    link_drop_resumes_the_mission(Personality::Ardupilot);
}

#[test]
fn px4_link_drop_mid_flight_lands_when_configured() {
    link_drop_lands(Personality::Px4);
}

#[test]
fn ardupilot_link_drop_mid_flight_lands_when_configured() {
    link_drop_lands(Personality::Ardupilot);
}

#[test]
fn px4_reboot_is_detected_and_the_link_comes_back() {
    let _one = alongside();
    let p = Personality::Px4;
    let fake = Fake::start(p, &[]);
    let mut kestrel = Kestrel::run(p, &fake.connection, "", &["--no-api", "--max-time-s", "9"]);
    kestrel.wait_line("ready to fly: true", Duration::from_secs(10));
    std::thread::sleep(Duration::from_secs(2));
    fake.cmd(json!({"cmd": "reboot", "gap_s": 2.5}));
    kestrel.wait(Duration::from_secs(30));
    let out = kestrel.output();
    let lost = kestrel.line_at("link: lost");
    let lost = lost.unwrap_or_else(|| panic!("no link loss during the reboot:\n{out}"));
    assert!(kestrel.line_after("link: ok", lost).is_some(), "{out}");
    assert!(
        kestrel.line_after("autopilot reboot #1", lost).is_some(),
        "{out}"
    );
}

/// The autopilot process goes away and comes back on the same port: Kestrel reconnects (TCP:
/// a new connection; UDP: the new peer is answered) and sees a fresh boot.
fn reconnects_after_the_autopilot_restarts(p: Personality) {
    let _one = alongside();
    let mut fake = Fake::start(p, &[]);
    let mut kestrel = Kestrel::run(p, &fake.connection, "", &["--no-api", "--max-time-s", "14"]);
    kestrel.wait_line("ready to fly: true", Duration::from_secs(10));
    std::thread::sleep(Duration::from_secs(2));
    fake.restart(Duration::from_secs(2));
    let lost = kestrel.wait_line("link: lost", Duration::from_secs(5));
    kestrel.wait(Duration::from_secs(30));
    let out = kestrel.output();
    assert!(kestrel.line_after("link: ok", lost).is_some(), "{out}");
    // ArduPilot streams only what this connection asked for: telemetry again means the
    // message rates were requested again after reconnecting.
    let ready_again = kestrel.line_after("ready to fly: true", lost);
    assert!(
        ready_again.is_some(),
        "no telemetry after reconnecting:\n{out}"
    );
    assert_eq!(fake.state()["boot_count"], 1, "a new process");
}

#[test]
fn px4_reconnects_after_the_autopilot_restarts() {
    reconnects_after_the_autopilot_restarts(Personality::Px4);
}

#[test]
fn ardupilot_reconnects_after_the_autopilot_restarts() {
    reconnects_after_the_autopilot_restarts(Personality::Ardupilot);
}

/// Kestrel between the autopilot and a ground station: the GCS gets the autopilot's own frames
/// and its commands reach the autopilot, whose answer comes back to it.
#[test]
fn ground_station_endpoint_gets_the_stream_and_its_commands_through() {
    use mavlink::dialects::ardupilotmega::{MavCmd, MavMessage, COMMAND_LONG_DATA};
    use mavlink::{MavHeader, MavlinkReader};
    let _one = alongside();
    let p = Personality::Px4;
    let fake = Fake::start(p, &[]);
    let gcs = std::net::UdpSocket::bind("127.0.0.1:0").unwrap();
    gcs.set_read_timeout(Some(Duration::from_millis(200)))
        .unwrap();
    let port = gcs.local_addr().unwrap().port();
    let config = format!("[mavlink]\nforward = [\"udpout:127.0.0.1:{port}\"]\n");
    let _kestrel = Kestrel::run(
        p,
        &fake.connection,
        &config,
        &["--no-api", "--max-time-s", "20"],
    );
    let mut buf = [0u8; 2048];
    let recv = |buf: &mut [u8]| -> Option<(std::net::SocketAddr, MavHeader, MavMessage)> {
        let (n, from) = gcs.recv_from(buf).ok()?;
        let (h, m) = MavlinkReader::new(&buf[..n])
            .read_any_message::<MavMessage>()
            .ok()?;
        Some((from, h, m))
    };
    let deadline = std::time::Instant::now() + Duration::from_secs(10);
    let kestrel_addr = loop {
        assert!(
            std::time::Instant::now() < deadline,
            "no autopilot HEARTBEAT forwarded"
        );
        if let Some((from, h, MavMessage::HEARTBEAT(_))) = recv(&mut buf) {
            if h.system_id == 1 && h.component_id == 1 {
                break from;
            }
        }
    };
    let request = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        param1: 148.0, // AUTOPILOT_VERSION
        command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
        target_system: 1,
        target_component: 1,
        ..COMMAND_LONG_DATA::DEFAULT
    });
    let gcs_header = MavHeader {
        system_id: 255,
        component_id: 190,
        sequence: 0,
    };
    let mut frame = Vec::new();
    mavlink::write_v2_msg(&mut frame, gcs_header, &request).unwrap();
    gcs.send_to(&frame, kestrel_addr).unwrap();
    let deadline = std::time::Instant::now() + Duration::from_secs(5);
    loop {
        assert!(
            std::time::Instant::now() < deadline,
            "no answer to the GCS command"
        );
        if let Some((_, _, MavMessage::AUTOPILOT_VERSION(v))) = recv(&mut buf) {
            assert_eq!(
                v.uid,
                0x4B45_5354_5245_4C00 + 1,
                "the fake's version record"
            );
            break;
        }
    }
}

/// `platforms/sim.toml`: the same `kestrel run` loop over the built-in simulator in real time.
#[test]
fn run_flies_the_demo_on_the_simulator_platform() {
    let _one = alongside();
    let mut kestrel = Kestrel::run_with_platform("platforms/sim.toml", "udpin:0.0.0.0:0", "", DEMO);
    let status = kestrel.wait(FLIGHT_TIMEOUT);
    assert!(status.success(), "{}", kestrel.output());
    let log = kestrel.flight_log();
    let finished = log
        .iter()
        .filter(|r| r["type"] == "behavior" && r["event"] == "finished")
        .count();
    assert_eq!(finished, 4, "takeoff, go_to, follow_path, land");
}
