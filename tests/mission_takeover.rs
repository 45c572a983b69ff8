//! In the simulator on the production host: a pilot takes the vehicle mid-mission, and a mission
//! that fails in the air ends hovering, landed or back home as `[mission] on_failure` says
//! (README, "When a pilot takes over" and "When a mission fails in the air"). The same
//! executor runs against the fake PX4 and ArduPilot in tests/pilot_takeover_e2e.rs.
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mission_rig;

use kestrel::behavior::FailureCode;
use kestrel::config::Config;
use kestrel::host::status::EventBody;
use kestrel::host::HostEvent;
use kestrel::mission::executor::InFlightFailure;
use kestrel::mission::{Action, ExecState, ItemResult};
use kestrel::scenario::SimulatedHost;
use mission_rig::Rig;
use serde_json::json;

/// Takeoff, a 12 m leg, land.
fn long_leg() -> serde_json::Value {
    json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 12.0, "y": 0.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]})
}

fn alerts(r: &Rig) -> Vec<String> {
    r.events
        .iter()
        .filter_map(|e| match e {
            HostEvent::Event {
                event: EventBody::Alert { message },
                ..
            } => Some(message.clone()),
            _ => None,
        })
        .collect()
}

fn offboard(r: &Rig) -> bool {
    r.host.cores()[0].platform_status().offboard
}

fn last_setpoint_s(r: &Rig) -> f64 {
    r.host.sim_world().unwrap().vehicles[0]
        .last_setpoint_at()
        .unwrap()
        .as_secs_f64()
}

/// Flies to the middle of the leg and lets the pilot take over there.
fn taken_mid_leg(r: &mut Rig) -> f64 {
    r.execute(1, long_leg());
    assert!(r.run_until(30.0, |r| r.at_item(1) && r.position()[0] > 4.0));
    r.host.sim_world_mut().unwrap().vehicles[0].pilot_takeover();
    let t = r.t();
    r.step();
    t
}

#[test]
fn a_takeover_pauses_the_mission_and_kestrel_stops_commanding() {
    let mut r = Rig::new();
    let taken_at = taken_mid_leg(&mut r);
    let status = r.status();
    assert_eq!(status.state, ExecState::Paused, "{status:?}");
    assert_eq!(status.last_error_code, Some(FailureCode::PilotTakeover));
    assert_eq!(
        status.last_error.as_deref(),
        Some("pilot took over (mode HOLD)")
    );
    let failed = status.done_results.last().unwrap();
    assert_eq!(
        (failed.item, failed.result, failed.code),
        (1, ItemResult::Failed, Some(FailureCode::PilotTakeover))
    );
    assert!(alerts(&r).contains(&"pilot took over (mode HOLD)".to_string()));
    assert!(r.active().is_empty(), "every behavior ended");
    r.run_for(5.0);
    assert!(
        last_setpoint_s(&r) <= taken_at,
        "a setpoint at {} s after the takeover at {taken_at} s",
        last_setpoint_s(&r)
    );
    assert!(!offboard(&r), "the mode stays the pilot's");
    assert_eq!(r.status().state, ExecState::Paused);
}

#[test]
fn resume_takes_the_vehicle_back_and_finishes_the_interrupted_item() {
    let mut r = Rig::new();
    taken_mid_leg(&mut r);
    r.run_for(2.0);
    let status = r.send(Action::Resume, Some(1), None, None).unwrap().status;
    assert_eq!(status.state, ExecState::Running);
    assert_eq!(status.last_error, None, "the takeover is over");
    assert!(r.run_until(5.0, offboard), "offboard again");
    assert!(r.run_until(60.0, |r| r.is_idle()), "{:?}", r.status());
    assert_eq!(r.status().outcome(1), Some(Ok(())), "{:?}", r.status());
    assert_eq!(
        r.started(),
        ["takeoff", "go_to", "go_to", "land"],
        "the interrupted go_to ran again"
    );
    assert!(r.near(12.0, 0.0, 0.0, 0.3), "{:?}", r.position());
}

#[test]
fn stop_after_a_takeover_leaves_the_vehicle_with_the_pilot() {
    let mut r = Rig::new();
    let taken_at = taken_mid_leg(&mut r);
    let status = r.send(Action::Stop, Some(1), None, None).unwrap().status;
    assert_eq!(status.state, ExecState::Idle);
    let held = r.position();
    r.run_for(5.0);
    assert!(r.active().is_empty(), "no land, no hover: {:?}", r.active());
    assert!(!offboard(&r));
    assert!(last_setpoint_s(&r) <= taken_at);
    assert!(
        r.position()[2] > 1.5,
        "still in the air: {:?}",
        r.position()
    );
    let moved = ((r.position()[0] - held[0]).powi(2) + (r.position()[1] - held[1]).powi(2)).sqrt();
    assert!(moved < 0.5, "the autopilot holds it: moved {moved} m");
}

/// A mission whose third item fails in the air (a second takeoff, flying already), with
/// `on_failure` set.
fn fail_in_the_air(policy: InFlightFailure) -> Rig {
    let mut config = Config::default();
    config.mission.on_failure = policy;
    config.mission.rtl_height_m = 3.0;
    config.mission.rtl_speed_mps = 2.0;
    let mut r = Rig::with_config(config, 1);
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 6.0, "y": 3.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "land", "args": {}}]});
    r.execute(1, mission);
    assert!(r.run_until(60.0, |r| r.is_idle()), "{:?}", r.status());
    let status = r.status();
    assert!(
        status.last_error.as_deref().unwrap().contains("item 2"),
        "{status:?}"
    );
    r
}

fn alert_of(r: &Rig, doing: &str) -> String {
    let code = r.status().last_error_code.unwrap();
    let expected = format!("drone_0 {doing} after takeoff #2 failed: {}", code.as_str());
    let all = alerts(r);
    assert!(all.contains(&expected), "{expected:?} not in {all:?}");
    expected
}

#[test]
fn on_failure_hold_hovers_where_the_failure_left_the_vehicle() {
    let mut r = fail_in_the_air(InFlightFailure::Hold);
    alert_of(&r, "holding");
    r.run_for(5.0);
    assert!(r.near(6.0, 3.0, 2.0, 0.3), "{:?}", r.position());
    assert!(r.host.cores()[0].platform_status().armed);
}

#[test]
fn on_failure_land_lands_where_the_vehicle_is() {
    let mut r = fail_in_the_air(InFlightFailure::Land);
    alert_of(&r, "landing");
    assert!(r.run_until(30.0, |r| !r.host.cores()[0].platform_status().armed));
    assert!(r.near(6.0, 3.0, 0.0, 0.3), "{:?}", r.position());
}

#[test]
fn on_failure_rtl_flies_home_and_lands() {
    let mut r = fail_in_the_air(InFlightFailure::Rtl);
    alert_of(&r, "returning to launch");
    assert!(r.run_until(60.0, |r| !r.host.cores()[0].platform_status().armed));
    assert!(r.near(0.0, 0.0, 0.0, 0.3), "{:?}", r.position());
}
