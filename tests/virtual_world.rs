//! A vehicle flying in a virtual world (`kestrel run --virtual-world`), on the production host
//! in stepped time: the "real" vehicle is the simulator's multirotor alone, in an empty world of
//! its own, its local frame starting 3 m west of the shared frame's origin (`Shifted`, as a
//! `[[vehicle]]` with `origin_enu_m`); a pole exists only in the virtual world. Its sensor maps
//! the pole where it is in the shared frame, and flown into it, the running `go_to` fails with
//! `virtual_collision` while the vehicle, unharmed, holds where it was.
#![allow(clippy::unwrap_used, clippy::expect_used)]

use kestrel::behavior::{BehaviorEvent, BehaviorId, BehaviorResult, FailureCode};
use kestrel::config::Config;
use kestrel::core::{BehaviorCommand, CoreConfig, DroneCore};
use kestrel::host::status::{EventBody, HostEvent};
use kestrel::host::Host;
use kestrel::host::HostBuilder;
use kestrel::mapping::grid::DEFAULT_OCCUPIED_THRESHOLD;
use kestrel::platform::shifted::Shifted;
use kestrel::platform::{Capabilities, Platform, PlatformFeedback, PlatformRequest};
use kestrel::sim::dynamics::MultirotorParams;
use kestrel::sim::spatial::ShapeIndex;
use kestrel::sim::vehicle::SimVehicle;
use kestrel::sim::virtual_world::{VirtualRanges, VirtualSensors};
use kestrel::sim::world::World;
use kestrel::types::{FlightStatus, Setpoint, Vec3};
use serde_json::json;
use std::sync::Arc;
use std::time::Duration;

/// The virtual world: 10 x 10 m, one pole of radius 0.3 m at (0, 1).
const WORLD: &str = r#"{"bounds_m": {"x": [-5, 5], "y": [-4, 6]}, "pole_radius_m": 0.3,
    "poles_xy_m": [[0.0, 1.0]], "sensor": {"kind": "multiranger", "noise_std_m": 0.0}}"#;
/// Where the vehicle's own frame starts in the shared one.
const ORIGIN_ENU_M: [f64; 3] = [-3.0, 1.0, 0.0];
const TICK: Duration = Duration::from_millis(10);

/// The simulator's vehicle, its physics advanced to each poll's time, knowing nothing of the
/// virtual world.
struct Autopilot {
    vehicle: SimVehicle,
    stepped_to: Duration,
}

impl Platform for Autopilot {
    fn capabilities(&self) -> Capabilities {
        self.vehicle.capabilities()
    }
    fn poll(&mut self, now: Duration) -> PlatformFeedback {
        while self.stepped_to < now {
            let dt = TICK.min(now - self.stepped_to);
            self.vehicle.step(
                self.stepped_to,
                dt.as_secs_f64(),
                &Vec3::zeros(),
                &Vec3::zeros(),
            );
            self.stepped_to += dt;
        }
        self.vehicle.poll(now)
    }
    fn command(&mut self, now: Duration, setpoint: Option<Setpoint>, requests: &[PlatformRequest]) {
        self.vehicle.command(now, setpoint, requests);
    }
}

struct Flight {
    host: Host,
    now: Duration,
    finished: Vec<(BehaviorId, BehaviorResult)>,
}

impl Flight {
    fn new() -> Self {
        let world: World = serde_json::from_str(WORLD).unwrap();
        let config = Config::default();
        let autopilot = Autopilot {
            vehicle: SimVehicle::new(Vec3::zeros(), 0.0, MultirotorParams::default()),
            stepped_to: Duration::ZERO,
        };
        let shifted = Shifted::new(Box::new(autopilot), Vec3::from(ORIGIN_ENU_M));
        let ranges = VirtualRanges::new(
            Arc::new(ShapeIndex::new(world.shapes())),
            world.sensor,
            config.sim.vehicle_radius_m,
        );
        let platform = VirtualSensors::new(Box::new(shifted), ranges, "drone_0", 1);
        let b = &world.bounds_m;
        let mut core_config = CoreConfig::new("drone_0");
        core_config.map = config.map.config(Some(b.corners())).unwrap();
        let core = DroneCore::new(
            core_config,
            platform.capabilities(),
            kestrel::behavior::payload::registry(),
        );
        let host = HostBuilder::vehicles(vec![(core, Box::new(platform))], &config)
            .world(world)
            .build();
        Self {
            host,
            now: Duration::ZERO,
            finished: Vec::new(),
        }
    }

    fn step(&mut self) {
        self.now += TICK;
        self.host.step_at(self.now);
        for e in self.host.drain_events() {
            if let HostEvent::Event {
                event: EventBody::Behavior(BehaviorEvent::Finished { id, result, .. }),
                ..
            } = e
            {
                self.finished.push((id, result));
            }
        }
    }

    fn start(&mut self, behavior: &str, goal: serde_json::Value) -> BehaviorId {
        self.host
            .behavior_command(
                0,
                BehaviorCommand::Start {
                    behavior: behavior.into(),
                    goal,
                },
            )
            .unwrap()
            .unwrap()
    }

    /// Steps until `id` finishes (at most `limit_s` simulated seconds).
    fn wait_for(&mut self, id: BehaviorId, limit_s: f64) -> BehaviorResult {
        let until = self.now + Duration::from_secs_f64(limit_s);
        while self.now < until {
            self.step();
            if let Some((_, r)) = self.finished.iter().find(|(i, _)| *i == id) {
                return r.clone();
            }
        }
        panic!("behavior {id} not finished in {limit_s} s");
    }

    fn position(&self) -> Vec3 {
        self.host.cores()[0].estimate().pose.position_m
    }
}

#[test]
fn a_vehicle_flown_into_a_virtual_pole_fails_with_virtual_collision_and_holds() {
    let mut f = Flight::new();
    f.step();
    let start = f.position();
    assert!(
        (start - Vec3::from(ORIGIN_ENU_M)).norm() < 1e-6,
        "starts at its origin in the shared frame: {start}"
    );
    let takeoff = f.start("takeoff", json!({"height": 1.5, "speed": 1.0}));
    assert_eq!(f.wait_for(takeoff, 30.0), BehaviorResult::Succeeded);

    // Its front beam has mapped the pole's west face, 2.7 m ahead, in the shared frame.
    let grid = f.host.map().unwrap().merged();
    let spec = grid.spec();
    let occupied: Vec<(f64, f64)> = (0..spec.height_cells)
        .flat_map(|r| (0..spec.width_cells).map(move |c| (c, r)))
        .filter(|&(c, r)| {
            grid.data()[(r * spec.width_cells + c) as usize] >= DEFAULT_OCCUPIED_THRESHOLD
        })
        .map(|(c, r)| {
            (
                spec.origin_enu_m.x + (f64::from(c) + 0.5) * spec.resolution_m,
                spec.origin_enu_m.y + (f64::from(r) + 0.5) * spec.resolution_m,
            )
        })
        .collect();
    assert!(!occupied.is_empty(), "the pole is mapped");
    for (x, y) in &occupied {
        assert!(
            (x + 0.3).abs() < 0.2 && (y - 1.0).abs() < 0.2,
            "obstacle cell at ({x:.2}, {y:.2}), the pole's face is at (-0.3, 1.0)"
        );
    }

    let go = f.start("go_to", json!({"x": 3.0, "y": 1.0, "z": 1.5, "speed": 1.0}));
    let result = f.wait_for(go, 20.0);
    let BehaviorResult::Failed { code, reason } = &result else {
        panic!("{result:?}");
    };
    assert_eq!(*code, FailureCode::VirtualCollision, "{reason}");
    assert!(reason.contains("virtual collision"), "{reason}");
    // Stopped within its radius of the pole's face, short of the pole's centre.
    let hit = f.position();
    assert!(hit.x > -0.5 && hit.x < 0.0, "collided at {hit}");

    // Unharmed, it holds there: flying, within 0.3 m of where it collided, 3 s on.
    for _ in 0..300 {
        f.step();
    }
    let status = f.host.cores()[0].platform_status();
    assert_eq!(status.flight, FlightStatus::Flying);
    assert!(status.armed);
    let held = f.position();
    assert!(
        (held - hit).norm() < 0.3,
        "held at {held}, collided at {hit}"
    );
    assert_eq!(f.finished.len(), 2, "{:?}", f.finished);
}
