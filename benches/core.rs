//! Core speed: one control tick of one drone, and simulated flight time per wall-clock time.
//!
//! Run: `cargo bench --bench core -- --warm-up-time 1 --measurement-time 5`
//! Results and targets are in BENCHMARKS.md (`## Core`).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use kestrel::behavior::fleet::FleetInput;
use kestrel::behavior::Registry;
use kestrel::config::Config;
use kestrel::core::{BehaviorCommand, CoreConfig, DroneCore};
use kestrel::estimator::Measurement;
use kestrel::flightlog::FlightLog;
use kestrel::host::Host;
use kestrel::mission::{Action, MissionUpdate};
use kestrel::platform::{Capabilities, PlatformFeedback};
use kestrel::scenario::demo::demo_missions;
use kestrel::scenario::sim_host::simulated_host;
use kestrel::scenario::SimulatedHost;
use kestrel::sim::world::World;
use kestrel::types::FleetView;
use kestrel::types::{FlightStatus, LinkHealth, PlatformStatus, Pose, Vec3};
use serde_json::json;
use std::hint::black_box;
use std::path::Path;
use std::sync::Arc;
use std::time::Duration;

const RATE_HZ: f64 = 100.0;

/// A fleet of one.
fn alone() -> FleetInput<'static> {
    static VIEW: std::sync::OnceLock<Arc<FleetView>> = std::sync::OnceLock::new();
    FleetInput {
        view: VIEW.get_or_init(Arc::default),
        map: None,
    }
}

/// What an airborne vehicle in offboard reports each tick.
fn flying_feedback(position_m: Vec3) -> PlatformFeedback {
    PlatformFeedback {
        status: PlatformStatus {
            link: LinkHealth::Ok,
            armed: true,
            offboard: true,
            flight: FlightStatus::Flying,
            mode: "OFFBOARD".into(),
            ready_to_fly: true,
            ..PlatformStatus::default()
        },
        measurements: vec![Measurement::GroundTruth {
            pose: Pose::from_position_yaw(position_m, 0.3),
            velocity_enu_mps: Vec3::new(0.5, 0.2, 0.0),
            angular_velocity_flu_radps: Vec3::zeros(),
        }],
        ..PlatformFeedback::default()
    }
}

/// A core flying `behavior` (started on a first tick), ready for timed ticks.
fn busy_core(behavior: &str, goal: serde_json::Value) -> (DroneCore, PlatformFeedback) {
    let sim_capabilities = Capabilities::setpoints_only();
    let mut core = DroneCore::new(
        CoreConfig::new("drone_0"),
        sim_capabilities,
        Registry::with_motion_behaviors(),
    );
    let feedback = flying_feedback(Vec3::new(1.0, 2.0, 3.0));
    core.tick(Duration::ZERO, &feedback, alone());
    core.command(BehaviorCommand::Start {
        behavior: behavior.into(),
        goal,
    })
    .unwrap_or_else(|e| panic!("{behavior}: {e}"));
    (core, feedback)
}

fn control_tick(c: &mut Criterion) {
    let mut group = c.benchmark_group("control_tick");
    let cases = [
        (
            "go_to",
            json!({ "x": 50.0, "y": 20.0, "z": 5.0, "speed": 2.0, "yaw_mode": "path_facing" }),
        ),
        (
            "follow_path",
            json!({ "path": [[10.0, 2.0, 3.0], [10.0, 12.0, 4.0], [0.0, 12.0, 3.0]], "speed": 1.0 }),
        ),
    ];
    for (behavior, goal) in cases {
        let (mut core, feedback) = busy_core(behavior, goal);
        let mut tick = 1u64;
        group.bench_function(behavior, |b| {
            b.iter(|| {
                tick += 1;
                let now = Duration::from_secs_f64(tick as f64 / RATE_HZ);
                black_box(core.tick(now, black_box(&feedback), alone()))
            })
        });
    }
    group.finish();
}

/// The production simulated host with `drones` in the thesis `low` world, each flying its
/// demo mission, logging to nowhere.
fn demo_host(drones: usize) -> Host {
    let world = World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/low.json"))
        .unwrap_or_else(|e| panic!("{e}"));
    let mut config = Config::default();
    config.drone.control_rate_hz = RATE_HZ;
    let mut host = simulated_host(world, drones, 0, &config);
    host.set_log(FlightLog::new(Box::new(std::io::sink()), 10.0));
    host.step();
    let missions = host.sim_world().map(demo_missions).unwrap_or_default();
    for mission in missions {
        let drone = mission["target"].as_str().map(str::to_string);
        host.update(&MissionUpdate {
            drone_id: drone,
            mission_id: None,
            item_id: None,
            action: Action::Execute,
            mission: Some(mission),
        })
        .unwrap_or_else(|e| panic!("demo mission: {e}"));
    }
    host
}

/// Simulated seconds per iteration: takeoff, go_to and most of the path of the demo.
const SIMULATED_S: f64 = 20.0;

fn simulate(host: &mut Host) {
    let ticks = (SIMULATED_S * RATE_HZ) as usize;
    for _ in 0..ticks {
        host.step();
    }
}

fn simulated_flight(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate_20s_low_world");
    group.sample_size(10);
    for drones in [1usize, 10] {
        group.throughput(Throughput::Elements((SIMULATED_S * RATE_HZ) as u64));
        group.bench_function(format!("{drones}_drones"), |b| {
            b.iter_batched(
                || demo_host(drones),
                |mut host| {
                    simulate(&mut host);
                    black_box(host.now())
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, control_tick, simulated_flight);
criterion_main!(benches);
