//! End to end: a second sender floods Kestrel's `udpin` port during a flight on the fake PX4
//! (garbage, and HEARTBEATs that claim to be the autopilot). Kestrel keeps answering the
//! autopilot it pinned, so the setpoint stream reaches it and the demo flight completes.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mavlink_support;
mod support;

use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
};
use mavlink::{MavHeader, MavlinkVersion};
use mavlink_support::{closest_approaches, demo_targets, serial, Fake, Kestrel, Personality, DEMO};
use serde_json::json;
use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;

/// A HEARTBEAT that says it is the fake's autopilot (system 1, component 1), armed.
fn spoofed_heartbeat(sequence: u8) -> Vec<u8> {
    let header = MavHeader {
        system_id: 1,
        component_id: 1,
        sequence,
    };
    let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED,
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    });
    let mut out = Vec::new();
    mavlink::write_versioned_msg(&mut out, MavlinkVersion::V2, header, &msg).unwrap();
    out
}

/// Sends `rate_hz` datagrams a second to `target` from another socket until stopped.
struct Flood {
    stop: Arc<AtomicBool>,
    sent: Arc<AtomicU64>,
    handle: Option<std::thread::JoinHandle<()>>,
}

impl Flood {
    fn start(target: &str, rate_hz: u64) -> Self {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket.connect(target).unwrap();
        let (stop, sent) = (
            Arc::new(AtomicBool::new(false)),
            Arc::new(AtomicU64::new(0)),
        );
        let (s, n) = (stop.clone(), sent.clone());
        let period = Duration::from_micros(1_000_000 / rate_hz);
        let handle = std::thread::spawn(move || {
            let mut i: u64 = 0;
            while !s.load(Ordering::Relaxed) {
                let datagram = match i % 3 {
                    0 => spoofed_heartbeat(i as u8),
                    1 => b"\xfd\x09garbage that is not MAVLink at all".to_vec(),
                    _ => (0..64).map(|k| (k * 37 + i) as u8).collect(),
                };
                // A full buffer or a closed port is the sender's problem, not the test's.
                if socket.send(&datagram).is_ok() {
                    n.fetch_add(1, Ordering::Relaxed);
                }
                i += 1;
                std::thread::sleep(period);
            }
        });
        Self {
            stop,
            sent,
            handle: Some(handle),
        }
    }

    fn finish(mut self) -> u64 {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(h) = self.handle.take() {
            h.join().unwrap();
        }
        self.sent.load(Ordering::Relaxed)
    }
}

#[test]
fn px4_flight_completes_while_a_second_sender_floods_the_udpin_port() {
    let _one = serial();
    let p = Personality::Px4;
    let fake = Fake::start(p, &[]);
    let port = fake.connection.trim_start_matches("udpin:").to_string();
    let poller = fake.poll_states();
    let mut kestrel = Kestrel::run(p, &fake.connection, "", DEMO);
    kestrel.wait_line("takeoff #1 started", Duration::from_secs(60));
    // Three times the rate that made the autopilot failsafe and land.
    let flood = Flood::start(&port, 1500);
    kestrel.wait_line("takeoff #1 succeeded", Duration::from_secs(60));
    let airborne = fake.cmd(json!({"cmd": "setpoint_stats", "reset": true}));
    let status = kestrel.wait(Duration::from_secs(120));
    let sent = flood.finish();
    let samples = poller.finish();
    let out = kestrel.output();
    assert!(
        sent > 10_000,
        "the flood ran through the flight ({sent} datagrams)"
    );
    assert!(status.success(), "flight failed under the flood:\n{out}");
    let approaches = closest_approaches(&samples, &demo_targets());
    assert!(
        approaches.iter().all(|d| *d <= 0.3),
        "targets missed: {approaches:.2?}\n{out}"
    );
    // PX4 leaves OFFBOARD 1 s after the last setpoint: the stream never came close.
    let rest = fake.cmd(json!({"cmd": "setpoint_stats"}));
    for stats in [&airborne, &rest] {
        let max = stats["max_ms"].as_f64().unwrap_or(f64::INFINITY);
        assert!(max < 200.0, "setpoint gap {max} ms: {stats}\n{out}");
    }
    let end = fake.state();
    assert_eq!(end["armed"], false, "{end}");
    assert_eq!(end["on_ground"], true, "{end}");
    assert!(
        out.contains("ignored"),
        "the foreign datagrams are reported:\n{out}"
    );
}
