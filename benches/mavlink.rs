//! MAVLink platform speed on a real capture (PX4 SIH offboard session, about 42k frames):
//! decoding alone, and decoding + dispatch through the session (vehicle model, command tracker,
//! texts), as `kestrel run` does for every frame; plus encoding one setpoint frame.
//!
//! Run: `cargo bench --bench mavlink -- --warm-up-time 1 --measurement-time 5`
//! Results, and pymavlink on the same capture, are in BENCHMARKS.md (`## MAVLink`).

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use kestrel::control::{Setpoint, YawTarget};
use kestrel::platform::mavlink::{setpoint, tlog, Profile, Session, SessionConfig};
use kestrel::types::Vec3;
use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::MavHeader;
use std::hint::black_box;
use std::path::PathBuf;
use std::time::Duration;

fn capture() -> Vec<u8> {
    let here = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
    let dir = [
        std::env::var("KESTREL_TRACES").map(PathBuf::from).ok(),
        Some(here.join("../shared/traces")),
        Some(here.join("../../shared/traces")),
    ]
    .into_iter()
    .flatten()
    .find(|p| p.join("README.md").exists())
    .unwrap_or_else(|| panic!("captures not found: set KESTREL_TRACES"));
    std::fs::read(dir.join("px4_sih_offboard_session.tlog")).unwrap_or_default()
}

fn bench(c: &mut Criterion) {
    let bytes = capture();
    let frames: Vec<(Duration, &[u8])> = tlog::frames(&bytes).collect();
    let t0 = frames.first().map_or(Duration::ZERO, |f| f.0);
    let mut group = c.benchmark_group("mavlink");
    group.throughput(Throughput::Elements(frames.len() as u64));
    group.bench_function("decode", |b| {
        b.iter(|| {
            frames
                .iter()
                .filter_map(|(_, f)| tlog::decode_frame(black_box(f)))
                .count()
        })
    });
    let profile = Profile::builtin("px4")
        .and_then(Result::ok)
        .unwrap_or_else(|| panic!("the built-in px4 profile"));
    group.bench_function("decode_dispatch", |b| {
        b.iter(|| {
            let mut session = Session::new(profile.clone(), SessionConfig::default());
            for (stamp, f) in &frames {
                if let Some((header, msg)) = tlog::decode_frame(f) {
                    session.on_message(stamp.saturating_sub(t0), &header, &msg);
                }
            }
            black_box(session.stats().messages_in)
        })
    });
    group.finish();

    let sp = Setpoint::Position {
        position_enu_m: Vec3::new(3.0, 5.0, 3.5),
        velocity_ff_enu_mps: Vec3::new(0.5, 0.0, 0.0),
        yaw: YawTarget::Angle(0.3),
    };
    let header = MavHeader {
        system_id: 1,
        component_id: 191,
        sequence: 0,
    };
    let mut buf = Vec::with_capacity(64);
    c.bench_function("mavlink/encode_setpoint_frame", |b| {
        b.iter(|| {
            buf.clear();
            let msg = MavMessage::SET_POSITION_TARGET_LOCAL_NED(setpoint::encode(
                black_box(&sp),
                1000,
                1,
                1,
            ));
            mavlink::write_v2_msg(&mut buf, header, &msg).map(black_box)
        })
    });
}

criterion_group!(benches, bench);
criterion_main!(benches);
