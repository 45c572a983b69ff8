#![allow(clippy::unwrap_used, clippy::expect_used)]
//! Every MissionUpdate action in every executor state, flown in the simulator in simulated
//! time. Each test name states the rule it checks (the rules are listed in docs/API.md).

mod mission_rig;

use kestrel::mission::{ExecState, ItemResult};
use mission_rig::*;

#[test]
fn execute_flies_takeoff_go_land_with_the_thesis_status_sequence() {
    let mut rig = Rig::new();
    let s = rig.execute(1, takeoff_go_land());
    assert_eq!(s.state, ExecState::Running);
    assert_eq!((s.done_items, s.pending_items), (0, 2));
    assert!(rig.run_until(120.0, |r| r.is_idle()), "mission did not end");
    let s = rig.status();
    assert_eq!((s.done_items, s.pending_items), (3, 0));
    assert_eq!(s.last_error, None);
    assert!(
        s.done_results
            .iter()
            .all(|d| d.result == ItemResult::Succeeded),
        "{s:?}"
    );
    assert_eq!(rig.started(), ["takeoff", "go_to", "land"]);
    assert!(rig.near(0.0, 5.0, 0.0, 0.3), "{:?}", rig.position());
    // The published sequence: running at items 0, 1, 2, then idle with everything done.
    let seq: Vec<(u8, Option<usize>)> = rig
        .statuses()
        .iter()
        .map(|s| (s.state as u8, s.item_index))
        .collect();
    let mut dedup = seq.clone();
    dedup.dedup();
    assert_eq!(
        dedup,
        [(1, Some(0)), (1, Some(1)), (1, Some(2)), (0, None)],
        "{seq:?}"
    );
    println!("takeoff-go-land took {:.1} simulated s", rig.t());
}

use kestrel::host::engine::{HostError, LoadOptions};
use kestrel::mission::{Action, ActionError};
use serde_json::json;

fn refused(r: Result<kestrel::host::engine::Updated, HostError>) -> String {
    match r {
        Err(HostError::Action(ActionError::Refused(reason))) => reason,
        other => panic!("expected a refusal, got {other:?}"),
    }
}

/// Rig flying `square()` as mission 1, airborne on item `index`.
fn flying_square_at(index: usize) -> Rig {
    let mut rig = Rig::new();
    rig.execute(1, square());
    assert!(
        rig.run_until(60.0, |r| r.at_item(index)),
        "never reached item {index}"
    );
    rig.run_for(0.5);
    rig
}

// ---- LOAD / EXECUTE ----

#[test]
fn load_keeps_the_executor_idle_and_shows_the_mission() {
    let mut rig = Rig::new();
    let s = rig
        .send(Action::Load, Some(4), None, Some(takeoff_go_land()))
        .unwrap()
        .status;
    assert_eq!(s.state, ExecState::Idle);
    assert_eq!(
        (s.mission_id, s.pending_items, s.done_items),
        (Some(4), 3, 0)
    );
    rig.run_for(1.0);
    assert!(rig.started().is_empty());
}

#[test]
fn load_without_mission_id_allocates_one() {
    let mut rig = Rig::new();
    let a = rig
        .send(Action::Load, None, None, Some(takeoff_go_land()))
        .unwrap();
    let b = rig.send(Action::Load, None, None, Some(square())).unwrap();
    assert_ne!(a.status.mission_id, b.status.mission_id);
}

#[test]
fn missions_beyond_the_limit_per_drone_are_refused_and_change_nothing() {
    use kestrel::mission::executor::MAX_MISSIONS;
    let mut rig = Rig::new();
    for id in 0..MAX_MISSIONS as i64 {
        rig.send(Action::Load, Some(id), None, Some(takeoff_go_land()))
            .unwrap();
    }
    let before = rig.host.executors()[0].missions().len();
    assert_eq!(before, MAX_MISSIONS);
    for (action, id) in [
        (Action::Load, Some(1000)),
        (Action::Load, None),
        (Action::Execute, None),
    ] {
        let reason = refused(rig.send(action, id, None, Some(square())));
        assert!(
            reason.contains("mission_id") && reason.contains(&MAX_MISSIONS.to_string()),
            "{reason}"
        );
    }
    // The upload path (POST /api/missions) too.
    let err = rig
        .host
        .load_mission(&square(), LoadOptions::default())
        .unwrap_err();
    assert!(err.to_string().contains("missions are loaded"), "{err}");
    assert_eq!(rig.host.executors()[0].missions().len(), before);
    assert!(rig.started().is_empty());
    // Replacing an idle one is still fine.
    let s = rig
        .send(Action::Load, Some(3), None, Some(square()))
        .unwrap();
    assert_eq!(s.status.pending_items, 5);
}

#[test]
fn load_replaces_an_idle_mission_but_not_the_running_one() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(takeoff_go_land()))
        .unwrap();
    let s = rig
        .send(Action::Load, Some(1), None, Some(square()))
        .unwrap()
        .status;
    assert_eq!(s.pending_items, 5);
    rig.send(Action::Start, Some(1), None, None).unwrap();
    let reason = refused(rig.send(Action::Load, Some(1), None, Some(takeoff_go_land())));
    assert!(reason.contains("is running"), "{reason}");
    let reason = refused(rig.send(Action::Execute, Some(1), None, Some(takeoff_go_land())));
    assert!(reason.contains("is running"), "{reason}");
}

#[test]
fn load_and_execute_without_a_mission_are_refused() {
    let mut rig = Rig::new();
    for action in [
        Action::Load,
        Action::Execute,
        Action::Insert,
        Action::Modify,
    ] {
        let reason = refused(rig.send(action, Some(1), Some(0), None));
        assert!(reason.contains("needs a mission"), "{action}: {reason}");
    }
}

#[test]
fn load_of_an_invalid_mission_changes_nothing() {
    let mut rig = Rig::new();
    let bad = json!({"target": "drone_0", "plan": [{"behavior": "go_to", "args": {"x": 1}}]});
    match rig.send(Action::Load, Some(1), None, Some(bad)) {
        Err(HostError::Action(ActionError::Invalid(errors))) => {
            assert!(
                errors.iter().any(|e| e.pointer == "/plan/0/args/y"),
                "{errors:?}"
            )
        }
        other => panic!("{other:?}"),
    }
    assert!(rig.host.executors()[0].missions().is_empty());
}

/// The one load path (`Host::load_mission`, what the CLI, the demo and the API use): started
/// at once it flies as EXECUTE does; under the id of the running mission it is refused and
/// changes nothing, as EXECUTE and LOAD are.
#[test]
fn load_mission_started_flies_as_execute_and_keeps_its_refusals() {
    let mut rig = Rig::new();
    let up = rig
        .host
        .load_mission(&takeoff_go_land(), LoadOptions::start())
        .unwrap();
    assert_eq!(up.drone, "drone_0");
    assert_eq!(rig.status().state, ExecState::Running);
    assert_eq!(rig.status().mission_id, Some(up.mission_id));
    let replace = LoadOptions {
        mission_id: Some(up.mission_id),
        start: false,
    };
    let err = rig.host.load_mission(&square(), replace).unwrap_err();
    assert!(err.to_string().contains("is running"), "{err}");
    assert_eq!(rig.host.executors()[0].missions().len(), 1);
    assert!(rig.run_until(120.0, |r| r.is_idle()), "mission did not end");
    assert_eq!(rig.started(), ["takeoff", "go_to", "land"]);
    assert_eq!(rig.status().last_error, None);
}

// ---- START ----

#[test]
fn start_while_idle_begins_at_item_id() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "go_to", "args": {"x": 50.0, "y": 0.0, "z": 3.0, "speed": 1.0}},
        {"behavior": "takeoff", "args": {"height": 1.0, "speed": 1.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]});
    rig.send(Action::Load, Some(2), None, Some(mission))
        .unwrap();
    let s = rig
        .send(Action::Start, Some(2), Some(1), None)
        .unwrap()
        .status;
    assert_eq!(
        (s.state, s.item_index, s.done_items),
        (ExecState::Running, Some(1), 1)
    );
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert_eq!(rig.started(), ["takeoff", "land"]);
}

#[test]
fn start_with_item_id_out_of_range_is_refused() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(takeoff_go_land()))
        .unwrap();
    for item in [3, -1, 1000] {
        let reason = refused(rig.send(Action::Start, Some(1), Some(item), None));
        assert!(reason.contains("out of range"), "{reason}");
    }
    assert!(rig.is_idle());
}

#[test]
fn start_of_an_unknown_mission_is_refused() {
    let mut rig = Rig::new();
    match rig.send(Action::Start, Some(9), None, None) {
        Err(HostError::Action(ActionError::UnknownMission(9))) => {}
        other => panic!("{other:?}"),
    }
}

#[test]
fn start_with_nothing_loaded_is_refused() {
    let mut rig = Rig::new();
    let reason = refused(rig.send(Action::Start, None, None, None));
    assert!(reason.contains("no mission is loaded"), "{reason}");
}

#[test]
fn start_of_the_running_mission_is_refused() {
    let mut rig = flying_square_at(1);
    let reason = refused(rig.send(Action::Start, Some(1), None, None));
    assert!(reason.contains("already running"), "{reason}");
    assert!(rig.at_item(1));
}

#[test]
fn start_of_the_paused_mission_is_refused() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Pause, Some(1), None, None).unwrap();
    let reason = refused(rig.send(Action::Start, Some(1), None, None));
    assert!(reason.contains("paused"), "{reason}");
    assert_eq!(rig.status().state, ExecState::Paused);
}

#[test]
fn start_of_another_mission_while_running_switches_plans_after_a_hold() {
    let mut rig = flying_square_at(1);
    let inspection = json!({"target": "drone_0", "plan": [
        {"behavior": "go_to", "args": {"x": -5.0, "y": 0.0, "z": 4.0, "speed": 2.0}},
        {"behavior": "land", "args": {"speed": 1.0}}]});
    rig.send(Action::Load, Some(2), None, Some(inspection))
        .unwrap();
    let t0 = rig.t();
    let s = rig.send(Action::Start, Some(2), None, None).unwrap().status;
    assert_eq!((s.mission_id, s.state), (Some(2), ExecState::Running));
    // The old go_to is stopped at once; the new plan starts after the switch hold (1 s).
    assert!(rig.active().is_empty(), "{:?}", rig.active());
    assert!(rig.run_until(5.0, |r| r.active() == ["go_to"]));
    assert!(rig.t() - t0 >= 0.99, "started after {:.2} s", rig.t() - t0);
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert!(rig.near(-5.0, 0.0, 0.0, 0.3), "{:?}", rig.position());
    // The old mission stays loaded, idle, with its history.
    let old = &rig.host.executors()[0].missions()[&1];
    assert_eq!(
        old.progress.done.last().unwrap().result,
        ItemResult::Stopped
    );
}

// ---- PAUSE / RESUME ----

#[test]
fn pause_while_running_holds_the_vehicle_and_resume_continues() {
    let mut rig = flying_square_at(2);
    let s = rig.send(Action::Pause, Some(1), None, None).unwrap().status;
    assert_eq!(s.state, ExecState::Paused);
    rig.run_for(3.0);
    let held = rig.position();
    rig.run_for(3.0);
    assert!(
        rig.near(held[0], held[1], held[2], 0.1),
        "drifted while paused"
    );
    assert!(rig.speed() < 0.1);
    let s = rig
        .send(Action::Resume, Some(1), None, None)
        .unwrap()
        .status;
    assert_eq!((s.state, s.item_index), (ExecState::Running, Some(2)));
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert!(rig.near(8.0, 0.0, 0.0, 0.3), "{:?}", rig.position());
}

#[test]
fn pause_while_paused_is_refused() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Pause, Some(1), None, None).unwrap();
    let reason = refused(rig.send(Action::Pause, Some(1), None, None));
    assert!(reason.contains("already paused"), "{reason}");
}

#[test]
fn pause_and_resume_while_idle_are_refused() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(square()))
        .unwrap();
    for action in [Action::Pause, Action::Resume] {
        let reason = refused(rig.send(action, Some(1), None, None));
        assert!(reason.contains("no mission is running"), "{reason}");
    }
}

#[test]
fn pause_of_a_mission_that_is_not_the_running_one_is_refused() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Load, Some(2), None, Some(takeoff_go_land()))
        .unwrap();
    let reason = refused(rig.send(Action::Pause, Some(2), None, None));
    assert!(reason.contains("mission 1 is"), "{reason}");
    assert_eq!(rig.status().state, ExecState::Running);
}

#[test]
fn resume_while_running_is_refused() {
    let mut rig = flying_square_at(1);
    let reason = refused(rig.send(Action::Resume, Some(1), None, None));
    assert!(reason.contains("not paused"), "{reason}");
}

// ---- STOP ----

#[test]
fn stop_while_running_ends_the_mission_and_the_vehicle_holds() {
    let mut rig = flying_square_at(2);
    let s = rig.send(Action::Stop, Some(1), None, None).unwrap().status;
    assert_eq!((s.state, s.last_error.clone()), (ExecState::Idle, None));
    assert_eq!(s.done_results.last().unwrap().result, ItemResult::Stopped);
    rig.run_for(3.0);
    let held = rig.position();
    rig.run_for(3.0);
    assert!(
        rig.near(held[0], held[1], held[2], 0.15),
        "vehicle did not hold"
    );
    assert!(held[2] > 1.5, "vehicle came down: {held:?}");
}

#[test]
fn stop_while_paused_ends_the_mission() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Pause, Some(1), None, None).unwrap();
    let s = rig.send(Action::Stop, Some(1), None, None).unwrap().status;
    assert_eq!(s.state, ExecState::Idle);
    assert!(rig.active().is_empty());
}

#[test]
fn stop_while_idle_is_accepted_and_changes_nothing() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(square()))
        .unwrap();
    let s = rig.send(Action::Stop, Some(1), None, None).unwrap().status;
    assert_eq!((s.state, s.pending_items), (ExecState::Idle, 5));
}

#[test]
fn stop_of_a_mission_that_is_not_running_while_another_runs_is_refused() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Load, Some(2), None, Some(takeoff_go_land()))
        .unwrap();
    let reason = refused(rig.send(Action::Stop, Some(2), None, None));
    assert!(reason.contains("mission 1 is"), "{reason}");
    assert_eq!(rig.status().state, ExecState::Running);
}

// ---- NEXT_ITEM ----

#[test]
fn next_item_while_running_skips_to_the_next_item() {
    let mut rig = flying_square_at(1);
    let s = rig
        .send(Action::NextItem, Some(1), None, None)
        .unwrap()
        .status;
    assert_eq!(s.item_index, Some(2));
    assert_eq!(s.done_results.last().unwrap().result, ItemResult::Stopped);
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert_eq!(
        rig.started(),
        ["takeoff", "go_to", "go_to", "go_to", "land"]
    );
}

#[test]
fn next_item_on_the_last_item_completes_the_mission() {
    let mut rig = flying_square_at(4);
    let s = rig
        .send(Action::NextItem, Some(1), None, None)
        .unwrap()
        .status;
    assert_eq!(
        (s.state, s.done_items, s.pending_items),
        (ExecState::Idle, 5, 0)
    );
}

#[test]
fn next_item_while_paused_moves_on_but_stays_paused_until_resume() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Pause, Some(1), None, None).unwrap();
    let s = rig
        .send(Action::NextItem, Some(1), None, None)
        .unwrap()
        .status;
    assert_eq!((s.state, s.item_index), (ExecState::Paused, Some(2)));
    rig.run_for(2.0);
    assert!(rig.active().is_empty());
    rig.send(Action::Resume, Some(1), None, None).unwrap();
    assert_eq!(rig.active(), ["go_to"]);
}

#[test]
fn next_item_while_idle_is_refused() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(square()))
        .unwrap();
    let reason = refused(rig.send(Action::NextItem, Some(1), None, None));
    assert!(reason.contains("no mission is running"), "{reason}");
}

// ---- JUMP_TO ----

#[test]
fn jump_to_backwards_flies_an_item_again() {
    let mut rig = flying_square_at(3);
    let s = rig
        .send(Action::JumpTo, Some(1), Some(1), None)
        .unwrap()
        .status;
    assert_eq!((s.item_index, s.done_items), (Some(1), 1));
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert_eq!(
        rig.started(),
        ["takeoff", "go_to", "go_to", "go_to", "go_to", "go_to", "go_to", "land"]
    );
}

#[test]
fn jump_to_forwards_skips_items() {
    let mut rig = flying_square_at(1);
    rig.send(Action::JumpTo, Some(1), Some(3), None).unwrap();
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert_eq!(rig.started(), ["takeoff", "go_to", "go_to", "land"]);
}

#[test]
fn jump_to_out_of_range_or_without_item_id_is_refused() {
    let mut rig = flying_square_at(1);
    let reason = refused(rig.send(Action::JumpTo, Some(1), Some(5), None));
    assert!(reason.contains("out of range"), "{reason}");
    let reason = refused(rig.send(Action::JumpTo, Some(1), Some(-2), None));
    assert!(reason.contains("out of range"), "{reason}");
    let reason = refused(rig.send(Action::JumpTo, Some(1), None, None));
    assert!(reason.contains("needs item_id"), "{reason}");
    assert!(rig.at_item(1));
}

#[test]
fn jump_to_while_idle_is_refused() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(square()))
        .unwrap();
    let reason = refused(rig.send(Action::JumpTo, Some(1), Some(2), None));
    assert!(reason.contains("no mission is running"), "{reason}");
}

#[test]
fn jump_to_while_paused_moves_the_cursor_and_stays_paused() {
    let mut rig = flying_square_at(2);
    rig.send(Action::Pause, Some(1), None, None).unwrap();
    let s = rig
        .send(Action::JumpTo, Some(1), Some(4), None)
        .unwrap()
        .status;
    assert_eq!((s.state, s.item_index), (ExecState::Paused, Some(4)));
    rig.send(Action::Resume, Some(1), None, None).unwrap();
    assert_eq!(rig.active(), ["land"]);
}

// ---- INSERT ----

#[test]
fn insert_after_the_running_item_flies_it_next() {
    let mut rig = flying_square_at(1);
    let detour = item(
        "go_to",
        json!({"x": -3.0, "y": 4.0, "z": 3.0, "speed": 2.0}),
    );
    let s = rig
        .send(Action::Insert, Some(1), Some(1), Some(detour))
        .unwrap()
        .status;
    assert_eq!(s.pending_items, 4);
    assert!(rig.run_until(60.0, |r| r.at_item(2)));
    assert!(rig.run_until(30.0, |r| r.at_item(3)));
    assert!(rig.near(-3.0, 4.0, 3.0, 0.3), "{:?}", rig.position());
    assert!(rig.run_until(60.0, |r| r.is_idle()));
}

#[test]
fn insert_before_the_running_item_is_refused() {
    let mut rig = flying_square_at(2);
    let detour = item(
        "go_to",
        json!({"x": -3.0, "y": 4.0, "z": 3.0, "speed": 2.0}),
    );
    let reason = refused(rig.send(Action::Insert, Some(1), Some(0), Some(detour)));
    assert!(reason.contains("cannot insert after item 0"), "{reason}");
}

#[test]
fn insert_into_an_idle_mission_at_the_start_and_the_end() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(takeoff_go_land()))
        .unwrap();
    let hover = item("hover", json!({"duration": 1.0}));
    rig.send(Action::Insert, Some(1), Some(-1), Some(hover.clone()))
        .unwrap();
    rig.send(Action::Insert, Some(1), None, Some(hover))
        .unwrap();
    let plan: Vec<String> = rig.host.executors()[0].missions()[&1]
        .mission
        .items
        .iter()
        .map(|i| i.behavior().to_string())
        .collect();
    assert_eq!(plan, ["hover", "takeoff", "go_to", "land", "hover"]);
    let reason = refused(rig.send(
        Action::Insert,
        Some(1),
        Some(5),
        Some(item("land", json!({}))),
    ));
    assert!(reason.contains("out of range"), "{reason}");
}

// ---- MODIFY ----

#[test]
fn modify_of_the_running_item_changes_the_goal_in_flight() {
    let mut rig = flying_square_at(1);
    let new = item("go_to", json!({"x": 2.0, "y": 4.0, "z": 5.0, "speed": 2.0}));
    rig.send(Action::Modify, Some(1), Some(1), Some(new))
        .unwrap();
    assert_eq!(rig.active(), ["go_to"], "same behavior, not restarted");
    assert!(rig.run_until(30.0, |r| r.at_item(2)));
    assert!(rig.near(2.0, 4.0, 5.0, 0.3), "{:?}", rig.position());
    let modified = rig
        .behavior_events()
        .iter()
        .any(|e| matches!(e, kestrel::behavior::BehaviorEvent::Modified { .. }));
    assert!(modified);
}

#[test]
fn modify_of_the_running_item_with_another_behavior_is_refused() {
    let mut rig = flying_square_at(1);
    let reason = refused(rig.send(
        Action::Modify,
        Some(1),
        Some(1),
        Some(item("land", json!({}))),
    ));
    assert!(reason.contains("keeps the behavior"), "{reason}");
}

#[test]
fn modify_of_a_pending_item_rewrites_it() {
    let mut rig = flying_square_at(1);
    let new = item("go_to", json!({"x": 1.0, "y": 1.0, "z": 6.0, "speed": 2.0}));
    rig.send(Action::Modify, Some(1), Some(3), Some(new))
        .unwrap();
    assert!(rig.run_until(60.0, |r| r.at_item(4)));
    assert!(rig.near(1.0, 1.0, 6.0, 0.3), "{:?}", rig.position());
}

#[test]
fn modify_of_a_done_item_is_refused() {
    let mut rig = flying_square_at(2);
    let new = item("go_to", json!({"x": 1.0, "y": 1.0, "z": 6.0, "speed": 2.0}));
    let reason = refused(rig.send(Action::Modify, Some(1), Some(1), Some(new)));
    assert!(reason.contains("is done"), "{reason}");
}

#[test]
fn modify_out_of_range_or_with_two_items_is_refused() {
    let mut rig = flying_square_at(1);
    let new = item("go_to", json!({"x": 1.0, "y": 1.0, "z": 6.0, "speed": 2.0}));
    let reason = refused(rig.send(Action::Modify, Some(1), Some(9), Some(new)));
    assert!(reason.contains("out of range"), "{reason}");
    let reason = refused(rig.send(Action::Modify, Some(1), Some(2), Some(takeoff_go_land())));
    assert!(reason.contains("exactly one item"), "{reason}");
}

// ---- REMOVE ----

#[test]
fn remove_of_a_pending_item_drops_it() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Remove, Some(1), Some(2), None).unwrap();
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    assert_eq!(rig.started(), ["takeoff", "go_to", "go_to", "land"]);
}

#[test]
fn remove_of_the_running_item_is_refused() {
    let mut rig = flying_square_at(2);
    let reason = refused(rig.send(Action::Remove, Some(1), Some(2), None));
    assert!(reason.contains("use NEXT_ITEM"), "{reason}");
}

#[test]
fn remove_of_a_done_item_is_refused() {
    let mut rig = flying_square_at(2);
    let reason = refused(rig.send(Action::Remove, Some(1), Some(0), None));
    assert!(reason.contains("is done"), "{reason}");
}

#[test]
fn remove_of_the_only_item_is_refused() {
    let mut rig = Rig::new();
    rig.send(Action::Load, Some(1), None, Some(item("land", json!({}))))
        .unwrap();
    let reason = refused(rig.send(Action::Remove, Some(1), Some(0), None));
    assert!(reason.contains("last item"), "{reason}");
}

// ---- RESET ----

#[test]
fn reset_of_the_running_mission_stops_and_unloads_it() {
    let mut rig = flying_square_at(1);
    let s = rig.send(Action::Reset, Some(1), None, None).unwrap().status;
    assert_eq!((s.state, s.mission_id), (ExecState::Idle, None));
    assert!(rig.host.executors()[0].missions().is_empty());
    assert!(rig.active().is_empty());
}

#[test]
fn reset_of_an_idle_mission_unloads_it_and_leaves_the_running_one() {
    let mut rig = flying_square_at(1);
    rig.send(Action::Load, Some(2), None, Some(takeoff_go_land()))
        .unwrap();
    rig.send(Action::Reset, Some(2), None, None).unwrap();
    assert_eq!(rig.status().state, ExecState::Running);
    assert!(!rig.host.executors()[0].missions().contains_key(&2));
}

#[test]
fn reset_of_an_unknown_mission_is_refused() {
    let mut rig = Rig::new();
    assert!(matches!(
        rig.send(Action::Reset, Some(3), None, None),
        Err(HostError::Action(ActionError::UnknownMission(3)))
    ));
}

// ---- failures, parallel items, timed items ----

#[test]
fn a_refused_first_item_refuses_start_and_says_why() {
    let mut rig = Rig::new();
    let reason = refused(rig.send(
        Action::Execute,
        Some(1),
        None,
        Some(item(
            "go_to",
            json!({"x": 1.0, "y": 0.0, "z": 2.0, "speed": 1.0}),
        )),
    ));
    assert!(reason.contains("not flying"), "{reason}");
    let s = rig.status();
    assert_eq!(s.state, ExecState::Idle);
    assert!(s.last_error.unwrap().contains("item 0 (go_to)"));
}

#[test]
fn a_failed_item_stops_the_mission_and_the_vehicle_holds() {
    let mut config = kestrel::config::Config::default();
    config.behaviors.no_progress_timeout_s = 2.0;
    let mut rig = Rig::with_config(config, 1);
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "hover", "args": {"duration": 1.0}},
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "land", "args": {}}]});
    rig.execute(1, mission);
    assert!(rig.run_until(30.0, |r| r.is_idle()));
    let s = rig.status();
    assert!(
        s.last_error
            .as_deref()
            .unwrap()
            .contains("item 2 (takeoff)"),
        "{s:?}"
    );
    assert_eq!(s.done_results.last().unwrap().result, ItemResult::Failed);
    rig.run_for(2.0);
    assert!(
        rig.position()[2] > 1.5,
        "vehicle did not hold: {:?}",
        rig.position()
    );
}

#[test]
fn on_failure_continue_goes_on_with_the_next_item() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0, "on_failure": "continue"}},
        {"behavior": "land", "args": {}}]});
    rig.execute(1, mission);
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    let s = rig.status();
    let results: Vec<ItemResult> = s.done_results.iter().map(|d| d.result).collect();
    assert_eq!(
        results,
        [
            ItemResult::Succeeded,
            ItemResult::Failed,
            ItemResult::Succeeded
        ]
    );
    assert_eq!(s.last_error, None);
}

#[test]
fn wait_false_runs_point_gimbal_in_parallel_with_follow_path() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
        {"behavior": "point_gimbal", "args": {"x": 5.0, "y": 5.0, "z": 0.0, "follow": true, "wait": false}},
        {"behavior": "follow_path", "args": {"path": [[0, 5, 3], [5, 5, 3]], "speed": 1.5}},
        {"behavior": "land", "args": {}}]});
    rig.execute(1, mission);
    assert!(rig.run_until(30.0, |r| r.at_item(2)));
    rig.run_for(1.0);
    let mut active = rig.active();
    active.sort();
    assert_eq!(active, ["follow_path", "point_gimbal"]);
    assert!(rig.run_until(60.0, |r| r.is_idle()));
    let s = rig.status();
    assert_eq!(s.done_results[1].result, ItemResult::Stopped, "{s:?}");
    assert!(
        rig.active().is_empty(),
        "parallel behaviors end with the mission"
    );
}

#[test]
fn run_for_s_ends_a_behavior_that_never_ends_by_itself() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "follow_reference", "args": {"x": 1.0, "y": 1.0, "z": 2.0, "frame_id": "earth", "wait": true, "run_for_s": 4.0}},
        {"behavior": "land", "args": {}}]});
    rig.execute(1, mission);
    assert!(rig.run_until(30.0, |r| r.at_item(1)));
    let t0 = rig.t();
    assert!(rig.run_until(30.0, |r| r.at_item(2)));
    assert!((rig.t() - t0 - 4.0).abs() < 0.1, "{}", rig.t() - t0);
    assert!(rig.run_until(30.0, |r| r.is_idle()));
    let s = rig.status();
    // Its time being up is how the item was meant to end: done, not "aborted: stopped".
    assert_eq!(s.done_results[1].result, ItemResult::Succeeded, "{s:?}");
    assert_eq!(s.last_error, None);
}

#[test]
fn rtl_composes_go_to_home_and_land() {
    let mut rig = Rig::new();
    let mission = json!({"target": "drone_0", "plan": [
        {"behavior": "takeoff", "args": {"height": 2.0, "speed": 1.0}},
        {"behavior": "go_to", "args": {"x": 6.0, "y": 3.0, "z": 2.0, "speed": 2.0}},
        {"behavior": "rtl", "args": {"height": 4.0, "speed": 2.0, "land_speed": 1.0}}]});
    rig.execute(1, mission);
    assert!(rig.run_until(90.0, |r| r.is_idle()));
    assert_eq!(rig.status().last_error, None);
    assert!(rig.near(0.0, 0.0, 0.0, 0.3), "{:?}", rig.position());
}

/// The rules after the link comes back are in tests/mission_link.rs.
#[test]
fn link_loss_holds_the_mission_then_fails_it_when_the_link_stays_away() {
    let mut rig = flying_square_at(1);
    let (tx, _rx) = tokio::sync::oneshot::channel();
    rig.host.handle(kestrel::host::Command::Fault {
        drone_id: "drone_0".into(),
        link_lost: true,
        reply: tx,
    });
    assert!(!rig.run_until(25.0, |r| r.is_idle()), "waits for the link");
    assert!(
        rig.run_until(10.0, |r| r.is_idle()),
        "[mission] link_wait_s = 30"
    );
    let status = rig.status();
    let e = status.last_error.unwrap();
    assert!(e.contains("did not come back within 30 s"), "{e}");
    assert_eq!(
        status.last_error_code,
        Some(kestrel::behavior::FailureCode::LinkLost)
    );
}

#[test]
fn a_restart_keeps_missions_loaded_but_never_resumes_them() {
    let mut rig = flying_square_at(2);
    rig.send(Action::Load, Some(7), None, Some(takeoff_go_land()))
        .unwrap();
    let saved = serde_json::to_string(&rig.host.persisted()).unwrap();
    let mut fresh = Rig::new();
    fresh.host.restore(serde_json::from_str(&saved).unwrap());
    let ex = &fresh.host.executors()[0];
    assert_eq!(ex.missions().keys().copied().collect::<Vec<_>>(), [1, 7]);
    assert_eq!(ex.state(), ExecState::Idle);
    assert_eq!(ex.missions()[&1].progress.cursor, 2);
    fresh.run_for(2.0);
    assert!(fresh.active().is_empty());
    assert!(fresh.status().last_error.unwrap().contains("not resumed"));
}
