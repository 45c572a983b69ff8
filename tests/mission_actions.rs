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
