//! Core speed: one control tick of one drone, and simulated flight time per wall-clock time.
//!
//! Run: `cargo bench --bench core -- --warm-up-time 1 --measurement-time 5`
//! Results and targets are in BENCHMARKS.md (`## Core`).

use criterion::{criterion_group, criterion_main, BatchSize, Criterion, Throughput};
use kestrel::behavior::Registry;
use kestrel::core::{BehaviorCommand, CoreConfig, DroneCore};
use kestrel::estimator::Measurement;
use kestrel::flightlog::FlightLog;
use kestrel::platform::{Capabilities, PlatformFeedback};
use kestrel::sim::runner::{SimConfig, SimRunner};
use kestrel::sim::script::{demo_plans, Script};
use kestrel::sim::world::World;
use kestrel::types::{FlightStatus, LinkHealth, PlatformStatus, Pose, Vec3};
use serde_json::json;
use std::hint::black_box;
use std::path::Path;
use std::time::Duration;

const RATE_HZ: f64 = 100.0;

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
    let sim_capabilities = Capabilities {
        setpoints: kestrel::control::AcceptedSetpoints {
            velocity: true,
            position: true,
        },
        native_takeoff: false,
        native_land: false,
    };
    let mut core = DroneCore::new(
        CoreConfig::new("drone_0"),
        sim_capabilities,
        Registry::with_motion_behaviors(),
    );
    let feedback = flying_feedback(Vec3::new(1.0, 2.0, 3.0));
    core.tick(Duration::ZERO, &feedback);
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
                black_box(core.tick(now, black_box(&feedback)))
            })
        });
    }
    group.finish();
}

/// A runner for `drones` in the thesis `low` world, flying the demo, logging to nowhere.
fn demo_runner(drones: usize) -> (SimRunner, Vec<Script>) {
    let world = World::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("sitl/worlds/low.json"))
        .unwrap_or_else(|e| panic!("{e}"));
    let config = SimConfig {
        drones,
        rate_hz: RATE_HZ,
        ..SimConfig::default()
    };
    let mut runner = SimRunner::new(
        world,
        &config,
        |i| CoreConfig::new(&format!("drone_{i}")),
        &Registry::with_motion_behaviors(),
    );
    runner.log = Some(FlightLog::new(Box::new(std::io::sink()), 10.0));
    let scripts = demo_plans(&runner.world)
        .into_iter()
        .map(Script::new)
        .collect();
    (runner, scripts)
}

/// Simulated seconds per iteration: takeoff, go_to and most of the path of the demo.
const SIMULATED_S: f64 = 20.0;

fn simulate(runner: &mut SimRunner, scripts: &mut [Script]) {
    let ticks = (SIMULATED_S * RATE_HZ) as usize;
    for _ in 0..ticks {
        let events = runner.step();
        for ((script, core), events) in scripts.iter_mut().zip(&mut runner.cores).zip(&events) {
            script.update(core, events);
        }
    }
}

fn simulated_flight(c: &mut Criterion) {
    let mut group = c.benchmark_group("simulate_20s_low_world");
    group.sample_size(10);
    for drones in [1usize, 10] {
        group.throughput(Throughput::Elements((SIMULATED_S * RATE_HZ) as u64));
        group.bench_function(format!("{drones}_drones"), |b| {
            b.iter_batched(
                || demo_runner(drones),
                |(mut runner, mut scripts)| {
                    simulate(&mut runner, &mut scripts);
                    black_box(runner.now())
                },
                BatchSize::LargeInput,
            )
        });
    }
    group.finish();
}

criterion_group!(benches, control_tick, simulated_flight);
criterion_main!(benches);
