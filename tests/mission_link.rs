//! Link loss during a mission, in the simulator on the production host: the item in flight ends
//! with `link_lost`, the vehicle's own failsafe holds it, and once the link is back the mission
//! resumes, lands or holds as `[mission] on_link_regained` says (README, "When the link to the
//! autopilot drops"). The same executor runs on PX4 and ArduPilot (tests/mavlink_e2e.rs).
#![allow(clippy::unwrap_used, clippy::expect_used)]

mod mission_rig;

use kestrel::behavior::FailureCode;
use kestrel::config::Config;
use kestrel::mission::executor::LinkRegained;
use kestrel::mission::{Action, ExecState, ItemResult};
use kestrel::scenario::SimulatedHost;
use mission_rig::{square, Rig};
use serde_json::json;

fn rig(policy: LinkRegained) -> Rig {
    let mut config = Config::default();
    config.mission.on_link_regained = policy;
    config.mission.link_wait_s = 10.0;
    Rig::with_config(config, 1)
}

/// Starts the square and cuts the link for `outage_s` during its first leg.
fn cut_during_first_leg(r: &mut Rig, outage_s: f64) {
    r.execute(1, square());
    assert!(r.run_until(30.0, |r| r.at_item(1) && r.speed() > 1.0));
    r.host.set_link_lost(0, true).unwrap();
    r.run_for(outage_s);
    let status = r.status();
    assert_eq!(status.state, ExecState::Running, "waiting for the link");
    let lost = status.done_results.last().unwrap();
    assert_eq!(
        (lost.item, lost.result, lost.code),
        (1, ItemResult::Aborted, Some(FailureCode::LinkLost))
    );
    assert!(
        r.active().is_empty(),
        "nothing commands a vehicle it cannot reach"
    );
    r.host.set_link_lost(0, false).unwrap();
}

#[test]
fn with_resume_the_interrupted_item_starts_again_and_the_mission_finishes() {
    let mut r = rig(LinkRegained::Resume);
    cut_during_first_leg(&mut r, 3.0);
    assert!(r.run_until(60.0, |r| r.is_idle()), "{:?}", r.status());
    let status = r.status();
    assert_eq!(status.outcome(1), Some(Ok(())), "{status:?}");
    assert_eq!(
        r.started(),
        ["takeoff", "go_to", "go_to", "go_to", "go_to", "land"],
        "the interrupted go_to ran again"
    );
    assert!(
        r.near(8.0, 0.0, 0.0, 0.3),
        "landed at the end: {:?}",
        r.position()
    );
}

#[test]
fn with_land_the_mission_ends_with_link_lost_and_the_vehicle_lands() {
    let mut r = rig(LinkRegained::Land);
    cut_during_first_leg(&mut r, 3.0);
    assert!(r.run_until(30.0, |r| !r.host.cores()[0].platform_status().armed));
    let status = r.status();
    assert!(status.outcome(1).unwrap().is_err());
    assert_eq!(status.last_error_code, Some(FailureCode::LinkLost));
    assert!(status
        .last_error
        .unwrap()
        .contains("link to the autopilot lost"));
    assert_eq!(r.started().last().map(String::as_str), Some("land"));
    assert!(r.position()[2] < 0.05, "on the ground: {:?}", r.position());
}

#[test]
fn with_hold_the_mission_pauses_hovering_and_resume_finishes_it() {
    let mut r = rig(LinkRegained::Hold);
    cut_during_first_leg(&mut r, 3.0);
    r.run_for(3.0);
    assert_eq!(r.status().state, ExecState::Paused);
    assert_eq!(r.active(), ["hover"]);
    let held = r.position();
    r.run_for(3.0);
    let now = r.position();
    let drift = ((held[0] - now[0]).powi(2) + (held[1] - now[1]).powi(2)).sqrt();
    assert!(drift < 0.2, "holds where it is: moved {drift} m");
    r.send(Action::Resume, Some(1), None, None).unwrap();
    assert!(r.run_until(60.0, |r| r.is_idle()));
    assert_eq!(r.status().outcome(1), Some(Ok(())));
}

#[test]
fn a_link_that_never_comes_back_fails_the_mission_after_link_wait_s() {
    let mut r = rig(LinkRegained::Resume);
    r.execute(1, square());
    assert!(r.run_until(30.0, |r| r.at_item(1)));
    r.host.set_link_lost(0, true).unwrap();
    let lost_at = r.t();
    assert!(r.run_until(20.0, |r| r.is_idle()));
    let waited = r.t() - lost_at;
    assert!((10.0..11.0).contains(&waited), "failed after {waited} s");
    let status = r.status();
    assert_eq!(status.last_error_code, Some(FailureCode::LinkLost));
    assert!(status
        .last_error
        .unwrap()
        .contains("did not come back within 10 s"));
}

#[test]
fn a_landing_interrupted_by_the_link_counts_as_done_when_the_autopilot_landed() {
    let mut r = rig(LinkRegained::Land);
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 1.0, "speed": 1.0}},
        {"behavior": "land", "args": {"speed": 0.5}}]});
    r.execute(1, mission);
    assert!(r.run_until(30.0, |r| r.at_item(1) && r.position()[2] < 0.7));
    r.host.set_link_lost(0, true).unwrap();
    // The simulated autopilot holds on setpoint loss; then it lands by itself (its failsafe).
    assert!(r.run_until(5.0, |r| r.status().done_results.len() == 2));
    r.host.sim_world_mut().unwrap().vehicles[0].autopilot_land();
    assert!(
        r.run_until(10.0, |r| !r.host.sim_world().unwrap().vehicles[0]
            .is_armed())
    );
    r.host.set_link_lost(0, false).unwrap();
    assert!(r.run_until(5.0, |r| r.is_idle()));
    let status = r.status();
    assert_eq!(status.outcome(1), Some(Ok(())), "{status:?}");
    let last = status.done_results.last().unwrap();
    assert_eq!(
        (last.behavior.as_str(), last.result),
        ("land", ItemResult::Succeeded)
    );
}

/// Issue 29, item 10a: the same landing, but the link comes back only after `link_wait_s` has
/// failed the mission; once the vehicle reports it landed, the landing counts as done.
#[test]
fn a_landing_that_outlasts_link_wait_counts_as_done_once_the_vehicle_reports_it_landed() {
    let mut r = rig(LinkRegained::Land);
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 1.0, "speed": 1.0}},
        {"behavior": "land", "args": {"speed": 0.5}}]});
    r.execute(1, mission);
    assert!(r.run_until(30.0, |r| r.at_item(1) && r.position()[2] < 0.7));
    r.host.set_link_lost(0, true).unwrap();
    r.host.sim_world_mut().unwrap().vehicles[0].autopilot_land();
    assert!(
        r.run_until(15.0, |r| r.is_idle()),
        "link_wait_s (10 s) fails it"
    );
    let failed = r.status();
    assert_eq!(failed.last_error_code, Some(FailureCode::LinkLost));
    assert!(failed.outcome(1).unwrap().is_err());
    assert!(!r.host.sim_world().unwrap().vehicles[0].is_armed());
    r.host.set_link_lost(0, false).unwrap();
    r.run_for(1.0);
    let status = r.status();
    assert_eq!(status.outcome(1), Some(Ok(())), "{status:?}");
    assert_eq!(status.last_error_code, None);
    let last = status.done_results.last().unwrap();
    assert_eq!(
        (last.behavior.as_str(), last.result),
        ("land", ItemResult::Succeeded)
    );
    assert!(r.host.executors()[0].missions()[&1].progress.finished);
}

/// A landing whose vehicle is still in the air when the link comes back stays failed.
#[test]
fn a_landing_that_outlasts_link_wait_stays_failed_while_the_vehicle_flies() {
    let mut r = rig(LinkRegained::Land);
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 1.0, "speed": 1.0}},
        {"behavior": "land", "args": {"speed": 0.5}}]});
    r.execute(1, mission);
    assert!(r.run_until(30.0, |r| r.at_item(1) && r.position()[2] < 0.7));
    r.host.set_link_lost(0, true).unwrap();
    assert!(r.run_until(15.0, |r| r.is_idle()));
    r.host.set_link_lost(0, false).unwrap();
    r.run_for(1.0);
    let status = r.status();
    assert!(status.outcome(1).unwrap().is_err(), "{status:?}");
    assert_eq!(status.last_error_code, Some(FailureCode::LinkLost));
}
