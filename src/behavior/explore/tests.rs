//! The explorer's behaviour over several ticks, driven by hand.

#![allow(clippy::unwrap_used)]
use super::landing::no_obstacle_within;
use super::*;
use crate::behavior::services::{ServiceAnswer, ServiceCall};
use crate::behavior::testing::Scene;
use crate::exploration::online::service::Allocation;
use crate::mapping::grid::OccupancyGrid;

/// A drone exploring at the origin, 1 m up, that has asked the allocator once (at 1 s).
fn asked_at_the_origin() -> (Scene, Explore, Vec<PlatformRequest>) {
    let mut scene = Scene::flying();
    scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    let mut requests = Vec::new();
    explore.explore_tick(&scene.ctx(1), &mut requests).unwrap();
    (scene, explore, requests)
}

/// The explorer's question this tick, answered with a goal 5 m east of where it asked.
fn answer_with_goal(scene: &Scene) {
    let calls = scene.services.drain_calls();
    let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
        panic!("no question to the allocator");
    };
    let from = job.request.position_enu_m;
    let goal = from + Vec3::new(5.0, 0.0, 0.0);
    let answer = Allocation::Goal {
        goal_enu_m: goal,
        path_enu_m: vec![from, goal],
        frontiers: 1,
        clockwise: None,
    };
    scene
        .services
        .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
}

/// The explorer's question this tick, answered `Done`.
fn answer_done(scene: &Scene, frontiers: usize, held: usize, unreached: usize) {
    let calls = scene.services.drain_calls();
    let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
        panic!("no question to the allocator");
    };
    let answer = Allocation::Done {
        frontiers,
        held,
        unreached,
    };
    scene
        .services
        .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
}

fn other(x: f64, z: f64) -> crate::types::DroneView {
    crate::types::DroneView::at_rest("other", Vec3::new(x, 0.0, z), z > 0.1)
}

#[test]
fn a_drone_lands_beside_one_giving_way_above_but_moves_away_from_one_level_or_landed() {
    let landing_from = |other_drone: crate::types::DroneView| {
        let mut scene = Scene::flying();
        scene.fleet.drones.push(other_drone);
        let mut explore = Explore::new(ExploreGoal::default());
        // It came from 3 m west, along its track.
        for x in [-3.0, -2.0, -1.0, 0.0] {
            scene.set_position(Vec3::new(x, 0.0, 1.0), Vec3::zeros());
            explore.drop_crumb(&scene.ctx(0));
        }
        explore.start_exploring(&scene.ctx(0));
        explore.go_land(&scene.ctx(1)).unwrap();
        explore.phase
    };
    // 1 m aside and 1 m up (giving way): it descends away from it, here.
    assert!(matches!(landing_from(other(1.0, 2.0)), Phase::Landing(_)));
    // Level with it, or landed there: back along its track first.
    assert!(matches!(
        landing_from(other(1.0, 1.0)),
        Phase::Relocating(_)
    ));
    assert!(matches!(
        landing_from(other(1.0, 0.0)),
        Phase::Relocating(_)
    ));
}

#[test]
fn a_landing_spot_is_as_far_from_obstacles_as_the_drone_explored() {
    use crate::mapping::grid::GridSpec;
    let spec = GridSpec {
        resolution_m: 0.1,
        width_cells: 40,
        height_cells: 40,
        origin_enu_m: Vector2::zeros(),
    };
    let mut grid = OccupancyGrid::new(spec).unwrap();
    // One obstacle cell at (2.05, 2.05).
    grid.set(crate::mapping::grid::Cell { x: 20, y: 20 }, 100)
        .unwrap();
    let at = |x: f64| Vec3::new(x, 2.05, 0.0);
    assert!(!no_obstacle_within(&grid, 50, &at(2.5), 0.5), "0.45 m off");
    assert!(no_obstacle_within(&grid, 50, &at(2.7), 0.5), "0.65 m off");
    assert!(
        no_obstacle_within(&grid, 101, &at(2.5), 0.5),
        "below the threshold"
    );
}

#[test]
fn a_drone_sensing_where_it_stopped_holds_that_point_against_drift() {
    let mut scene = Scene::flying();
    scene.set_position(Vec3::new(1.0, 2.0, 1.0), Vec3::zeros());
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    let mut requests = Vec::new();
    let point = |r: Option<MotionReference>| match r {
        Some(MotionReference::Position { position_enu_m, .. }) => position_enu_m,
        other => panic!("expected a hold, got {other:?}"),
    };
    let first = point(explore.explore_tick(&scene.ctx(1), &mut requests).unwrap());
    // The autopilot's own drift carries it 0.5 m north: the hold stays where it stopped.
    scene.set_position(Vec3::new(1.0, 2.5, 1.0), Vec3::new(0.0, 0.3, 0.0));
    let later = point(explore.explore_tick(&scene.ctx(2), &mut requests).unwrap());
    assert!((first - Vec3::new(1.0, 2.0, 1.0)).norm() < 1e-9, "{first}");
    assert_eq!(later, first);
    // Paused and flown elsewhere, it hovers where it is then.
    explore.resume(&scene.ctx(3));
    let resumed = point(explore.explore_tick(&scene.ctx(3), &mut requests).unwrap());
    assert!(
        (resumed - Vec3::new(1.0, 2.5, 1.0)).norm() < 1e-9,
        "{resumed}"
    );
}

#[test]
fn a_drone_giving_way_under_another_that_gave_way_comes_back_once_the_level_one_has_gone() {
    // It flew in under a drone already up out of the way; now a level drone with farther
    // to go comes within 2 m, so it gives way too, but the drone above keeps it at 1.35 m.
    let mut scene = Scene::flying();
    scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
    let mut level = other(1.5, 1.0);
    level.id = "drone_1".into();
    level.goal_enu_m = Some(Vec3::new(20.0, 0.0, 1.0));
    let mut above = other(0.1, 2.0);
    above.id = "drone_3".into();
    scene.fleet.drones = vec![level, above];
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    let mut requests = Vec::new();
    explore.run(&scene.ctx(1), &mut requests);
    assert!(matches!(explore.phase, Phase::GivingWay { .. }));
    scene.set_position(Vec3::new(0.0, 0.0, 1.35), Vec3::zeros());
    // The level drone goes on; the one above waits for this one to leave.
    scene.fleet.drones.remove(0);
    let returning = |e: &Explore| {
        matches!(
            e.phase,
            Phase::GivingWay {
                returning: true,
                ..
            }
        )
    };
    explore.run(&scene.ctx(3), &mut requests);
    assert!(!returning(&explore), "still climbing");
    explore.run(&scene.ctx(10), &mut requests);
    assert!(
        returning(&explore),
        "as far up as it gets, and clear: back down"
    );
}

#[test]
fn a_late_answer_from_where_the_drone_no_longer_is_is_asked_again_not_flown() {
    let (mut scene, mut explore, mut requests) = asked_at_the_origin();
    // The answer comes once the drone has drifted 1 m: its path starts where it was.
    scene.set_position(Vec3::new(0.0, 1.0, 1.0), Vec3::zeros());
    answer_with_goal(&scene);
    explore.explore_tick(&scene.ctx(2), &mut requests).unwrap();
    assert!(explore.target.is_none() && explore.child.is_none());
    // It asked again from here; an answer from here is flown.
    answer_with_goal(&scene);
    explore.explore_tick(&scene.ctx(3), &mut requests).unwrap();
    assert_eq!(explore.target, Some(Vec3::new(5.0, 1.0, 1.0)));
    assert!(explore.child.is_some());
}

#[test]
fn with_nothing_worth_a_trip_left_a_drone_ends_at_once_unless_others_hold_frontiers() {
    // (frontiers left, held by others, without a path from here, flights so far) ->
    // whether the first answer ends the exploration.
    let ends_after = |here_s: u64, frontiers: usize, held: usize, unreached: usize, flown| {
        let scene = Scene::flying();
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        explore.allocations = flown;
        // A flight leaves a metre or more of track.
        if flown > 0 {
            explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
        }
        // It came within a metre of where it is `here_s` ago.
        explore.anchor.1 = Duration::from_secs(12 - here_s);
        let mut requests = Vec::new();
        // After the first quarter turn (10.5 s at the thesis's rate).
        explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
        answer_done(&scene, frontiers, held, unreached);
        explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
        matches!(explore.phase, Phase::Landing(_) | Phase::Relocating(_))
    };
    let ends_at_once =
        |frontiers, held, unreached, flown| ends_after(1, frontiers, held, unreached, flown);
    assert!(ends_at_once(0, 0, 0, 0));
    // Left only frontiers it can reach but that are not worth its trip, after a flight to
    // a frontier: over. Before any (space may open up as it turns): it waits.
    assert!(ends_at_once(3, 0, 0, 1));
    assert!(!ends_at_once(3, 0, 0, 0));
    // Frontiers others hold: it waits (a failed drone's claims lapse, its part comes back).
    assert!(!ends_at_once(3, 1, 0, 1));
    // Frontiers it has no path to from here (boxed in by unknown space): it turns and
    // asks again instead of leaving a third of the world unexplored; once it has turned
    // a quarter turn where it is, sensing opens no more: over.
    assert!(!ends_at_once(3, 0, 2, 1));
    assert!(ends_after(11, 3, 0, 2, 1));
    assert!(
        !ends_after(11, 3, 1, 2, 1),
        "others hold frontiers: it waits"
    );
}

#[test]
fn a_goal_where_the_drone_hovers_is_no_flight_for_the_end_rule() {
    // At its start, the space round the drone opens up as it turns: a goal given where it
    // hovers, then frontiers it has no path to yet, must not end its exploration.
    let scene = Scene::flying();
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    explore.allocations = 1;
    explore.crumbs = vec![Vec3::zeros()];
    explore.anchor.1 = Duration::ZERO;
    let mut requests = Vec::new();
    explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
    answer_done(&scene, 3, 0, 3);
    explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
    assert!(matches!(explore.phase, Phase::Exploring), "it waits");
}

#[test]
fn the_goals_settings_override_the_configs_field_by_field_in_the_question() {
    let mut scene = Scene::flying();
    scene.exploration.keep_bonus_m = 3.0;
    scene.exploration.pocket_area_m2 = 1.0;
    let mut goal = ExploreGoal::default();
    goal.settings.edge_bonus_m = Some(0.0);
    let mut explore = Explore::new(goal);
    explore.start_exploring(&scene.ctx(0));
    explore
        .explore_tick(&scene.ctx(1), &mut Vec::new())
        .unwrap();
    let calls = scene.services.drain_calls();
    let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
        panic!("no question to the allocator");
    };
    let settings = job.request.settings;
    assert_eq!(settings.edge_bonus_m, 0.0, "the goal's");
    assert_eq!(settings.keep_bonus_m, 3.0, "the config's");
    // 1 m^2 at the 0.1 m cells of a drone without a map.
    assert_eq!(job.request.space.min_gain_cells, 100);
}

#[test]
fn a_drone_held_for_a_silent_peer_neither_gives_its_goal_up_nor_ends() {
    // A peer's drone fell silent while flying: the safety stage holds this one in place.
    let held = |silent_peer: bool| {
        let mut scene = Scene::flying();
        let mut peer = other(4.0, 1.0);
        peer.local = false;
        peer.silent = silent_peer;
        peer.unaccounted = silent_peer;
        scene.fleet.drones.push(peer);
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
        answer_with_goal(&scene);
        explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
        assert!(explore.target.is_some(), "a goal to fly to");
        // Where it is for longer than a sweep and the stuck allowance (12.5 s), shorter
        // than a held child takes to fail `fleet_peer_lost` (20 s).
        for t in 13..30 {
            explore.explore_tick(&scene.ctx(t), &mut requests).unwrap();
            scene.services.drain_calls();
        }
        let kept_goal = explore.given_up == 0;
        // After a flight, every answer says nothing is left that is worth a trip, for
        // longer than it would wait with frontiers others hold.
        explore.allocations = 1;
        explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
        explore.target = None;
        explore.child = None;
        explore.pending = None;
        let mut ended = false;
        for t in 30..50 {
            explore.explore_tick(&scene.ctx(t), &mut requests).unwrap();
            ended |= matches!(explore.phase, Phase::Landing(_) | Phase::Relocating(_));
            if explore.pending.is_some() {
                answer_done(&scene, 2, 0, 0);
            }
        }
        (kept_goal, ended)
    };
    assert_eq!(held(false), (false, true), "unheld: gives up, then ends");
    assert_eq!(held(true), (true, false), "held: keeps its goal, waits");
}

#[test]
fn an_obstacle_mapped_on_the_path_ahead_drops_the_path_and_asks_again() {
    use crate::mapping::config::MapConfig;
    use crate::mapping::server::MapServer;
    use crate::mapping::{Beam, RangeScan};
    // A map with one hit 2.5 m east, `y` m off the path the allocator gave (east along y = 0).
    let hit_at = |y: f64| {
        let mut map = MapServer::new(&MapConfig::open_field().unwrap());
        let scan = RangeScan {
            origin_enu_m: Vec3::new(0.0, y, 1.0),
            yaw_rad: 0.0,
            range_min_m: 0.05,
            range_max_m: 4.0,
            beams: vec![Beam {
                angle_rad: 0.0,
                range_m: Some(2.5),
            }],
        };
        map.insert(Duration::from_secs(2), &[scan]);
        map
    };
    for (y, blocked) in [(1.0, false), (0.0, true)] {
        let mut scene = Scene::flying();
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(1), &mut requests).unwrap();
        answer_with_goal(&scene);
        explore.explore_tick(&scene.ctx(2), &mut requests).unwrap();
        assert!(explore.child.is_some());
        // Before the next retarget is due.
        let map = hit_at(y);
        let mut ctx = scene.ctx_at(Duration::from_millis(2500));
        ctx.map = Some(&map);
        explore.explore_tick(&ctx, &mut requests).unwrap();
        assert_eq!(explore.child.is_none(), blocked, "a hit {y} m off the path");
        let asked = matches!(
            scene.services.drain_calls().first(),
            Some(ServiceCall::Explore(_))
        );
        assert_eq!(asked, blocked, "asked again: a hit {y} m off the path");
    }
}

#[test]
fn an_end_short_of_frontiers_reachable_without_the_straying_room_is_said() {
    // A drone that strayed 0.5 m (0.3 m kept beyond its safety distance), boxed in with that
    // room, still straying: before it ends, it asks once more without the room.
    let run = |probe_finds_a_goal: bool| {
        let scene = Scene::flying();
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        for _ in 0..100 {
            explore.tracking.observe(
                Vec3::new(0.5, 0.0, 1.0),
                Vec3::zeros(),
                Vec3::new(0.0, 0.0, 1.0),
                Vec3::zeros(),
                0.01,
            );
        }
        assert!((explore.tracking.extra_m() - 0.3).abs() < 1e-9);
        explore.allocations = 1;
        explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
        explore.anchor.1 = Duration::ZERO;
        // Boxed in since the start: it has waited its while for the stray to settle.
        explore.boxed_since = Some(Duration::ZERO);
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
        answer_done(&scene, 3, 0, 2);
        explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
        assert!(matches!(explore.phase, Phase::Exploring), "not ended yet");
        let calls = scene.services.drain_calls();
        let Some(ServiceCall::Explore(job)) = calls.into_iter().next() else {
            panic!("no second question");
        };
        assert_eq!(job.request.space.safety_distance_m, 0.4, "without the room");
        assert!(
            !job.request.claim,
            "a question only: nothing is held for others"
        );
        let answer = if probe_finds_a_goal {
            let from = job.request.position_enu_m;
            Allocation::Goal {
                goal_enu_m: from + Vec3::new(2.0, 0.0, 0.0),
                path_enu_m: vec![from, from + Vec3::new(2.0, 0.0, 0.0)],
                frontiers: 3,
                clockwise: None,
            }
        } else {
            Allocation::Done {
                frontiers: 3,
                held: 0,
                unreached: 3,
            }
        };
        scene
            .services
            .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
        explore.explore_tick(&scene.ctx(31), &mut requests).unwrap();
        assert!(
            matches!(explore.phase, Phase::Landing(_) | Phase::Relocating(_)),
            "it ends (and lands) either way: the goal is not flown"
        );
        assert!(explore.target.is_none());
        explore.feedback()["frontiers_left_within_room"].clone()
    };
    assert_eq!(
        run(true),
        serde_json::json!(3),
        "said: three left within the room"
    );
    assert_eq!(
        run(false),
        serde_json::Value::Null,
        "nothing left: nothing to say"
    );
}

/// A drone whose estimate drifts flies its paths no faster than its turning beams sweep ahead
/// (a quarter turn a beam range less the stopping room): 0.33 m/s at the defaults, 0.75 m/s
/// where nothing drifts, the goal's own speed with a heading that does not turn.
#[test]
fn a_drifting_drone_flies_no_faster_than_its_turning_beams_see_ahead() {
    let g = ExploreGoal::default();
    assert_eq!(g.cruise_mps(0.0), 0.75);
    let sighted = (4.0 - goal::SIGHT_STOP_M) * 0.15 / std::f64::consts::FRAC_PI_2;
    assert!((g.cruise_mps(0.02) - sighted).abs() < 1e-12);
    assert!((sighted - 0.334).abs() < 1e-3, "{sighted}");
    let slow = ExploreGoal {
        speed: 0.2,
        ..ExploreGoal::default()
    };
    assert_eq!(slow.cruise_mps(0.02), 0.2);
    let aligned = ExploreGoal {
        heading: HeadingMode::Align,
        ..ExploreGoal::default()
    };
    assert_eq!(aligned.cruise_mps(0.02), 0.75);
    // What the path's references ask, over 10 s along a 5 m path.
    let fastest = |drift_mps: f64| {
        let mut scene = Scene::flying();
        scene.estimate_drift_mps = drift_mps;
        scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
        let mut explore = Explore::new(ExploreGoal::default());
        explore.start_exploring(&scene.ctx(0));
        let mut requests = Vec::new();
        explore.explore_tick(&scene.ctx(1), &mut requests).unwrap();
        answer_with_goal(&scene);
        let mut fastest: f64 = 0.0;
        for tenth in 20..120 {
            let ctx = scene.ctx_at(Duration::from_millis(100 * tenth));
            if let Some(MotionReference::Trajectory {
                velocity_enu_mps, ..
            }) = explore.explore_tick(&ctx, &mut requests).unwrap()
            {
                fastest = fastest.max(velocity_enu_mps.xy().norm());
            }
        }
        fastest
    };
    let (free, drifting) = (fastest(0.0), fastest(0.02));
    assert!(free > 0.7, "{free}");
    assert!(drifting <= sighted + 1e-9 && drifting > 0.3, "{drifting}");
}

#[test]
fn a_drone_boxed_in_by_its_straying_room_that_holds_its_path_again_lets_it_go_and_explores_on() {
    // It strayed 0.5 m (a map correction's jump), then held its path for 20 s: the slow peak
    // still keeps 0.2 m, which boxes it in.
    let mut scene = Scene::flying();
    // A drifting estimate: the room was widened by a map correction's jump.
    scene.estimate_drift_mps = 0.02;
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    let on_path = Vec3::new(0.0, 0.0, 1.0);
    let stray = |explore: &mut Explore, point: Vec3, seconds: f64| {
        for _ in 0..(seconds * 100.0) as usize {
            explore
                .tracking
                .observe(point, Vec3::zeros(), on_path, Vec3::zeros(), 0.01);
        }
    };
    stray(&mut explore, Vec3::new(0.5, 0.0, 1.0), 1.0);
    stray(&mut explore, on_path, 20.0);
    assert!(
        explore.tracking.extra_m() > 0.15,
        "{}",
        explore.tracking.extra_m()
    );
    explore.allocations = 1;
    explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
    explore.anchor.1 = Duration::ZERO;
    let mut requests = Vec::new();
    explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
    answer_done(&scene, 3, 0, 2);
    explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
    let Some(ServiceCall::Explore(job)) = scene.services.drain_calls().into_iter().next() else {
        panic!("no second question");
    };
    assert!(!job.request.claim);
    let from = job.request.position_enu_m;
    let answer = Allocation::Goal {
        goal_enu_m: from + Vec3::new(2.0, 0.0, 0.0),
        path_enu_m: vec![from, from + Vec3::new(2.0, 0.0, 0.0)],
        frontiers: 3,
        clockwise: None,
    };
    scene
        .services
        .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
    explore.explore_tick(&scene.ctx(13), &mut requests).unwrap();
    assert!(matches!(explore.phase, Phase::Exploring), "it explores on");
    assert_eq!(explore.tracking.extra_m(), 0.0, "the room let go");
    assert_eq!(
        explore.feedback()["frontiers_left_within_room"],
        serde_json::Value::Null
    );
    // Its next question claims a goal without the room.
    explore.explore_tick(&scene.ctx(15), &mut requests).unwrap();
    let Some(ServiceCall::Explore(job)) = scene.services.drain_calls().into_iter().next() else {
        panic!("no next question");
    };
    assert!(job.request.claim);
    assert_eq!(job.request.space.safety_distance_m, 0.4);
}

#[test]
fn a_drone_boxed_in_while_it_still_strays_hovers_for_its_stray_to_settle_before_it_ends() {
    let mut scene = Scene::flying();
    // A drifting estimate: the room was widened by a map correction's jump.
    scene.estimate_drift_mps = 0.02;
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    for _ in 0..100 {
        explore.tracking.observe(
            Vec3::new(0.5, 0.0, 1.0),
            Vec3::zeros(),
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::zeros(),
            0.01,
        );
    }
    explore.allocations = 1;
    explore.crumbs = vec![Vec3::zeros(), Vec3::new(1.5, 0.0, 0.0)];
    explore.anchor.1 = Duration::ZERO;
    let mut requests = Vec::new();
    explore.explore_tick(&scene.ctx(11), &mut requests).unwrap();
    answer_done(&scene, 3, 0, 2);
    explore.explore_tick(&scene.ctx(12), &mut requests).unwrap();
    let Some(ServiceCall::Explore(job)) = scene.services.drain_calls().into_iter().next() else {
        panic!("no second question");
    };
    let from = job.request.position_enu_m;
    let answer = Allocation::Goal {
        goal_enu_m: from + Vec3::new(2.0, 0.0, 0.0),
        path_enu_m: vec![from, from + Vec3::new(2.0, 0.0, 0.0)],
        frontiers: 3,
        clockwise: None,
    };
    scene
        .services
        .deliver(job.ticket, ServiceAnswer::Explore(Ok(answer)), job.cancel);
    explore.explore_tick(&scene.ctx(13), &mut requests).unwrap();
    assert!(matches!(explore.phase, Phase::Exploring), "it waits");
    assert!(explore.target.is_none(), "the goal is not flown");
    assert!(explore.tracking.extra_m() > 0.25, "the room is kept");
    assert_eq!(explore.boxed_since, Some(Duration::from_secs(13)));
}

#[test]
fn a_drone_the_safety_stage_holds_for_a_peer_is_not_straying_nor_on_its_way_back() {
    // Its path runs east at 0.5 m/s; the stage holds it at the origin for a silent peer, so the
    // reference runs ahead (along the path) and past it sideways where the path turns north.
    let mut scene = Scene::flying();
    scene.estimate_drift_mps = 0.02;
    scene.dt_s = 0.1;
    scene.set_position(Vec3::new(0.0, 0.0, 1.0), Vec3::zeros());
    let mut explore = Explore::new(ExploreGoal::default());
    explore.start_exploring(&scene.ctx(0));
    let ahead_and_aside = |k: u64| MotionReference::Trajectory {
        position_enu_m: Vec3::new(0.6, 0.05 * k as f64, 1.0),
        velocity_enu_mps: Vec3::new(0.0, 0.5, 0.0),
        acceleration_enu_mps2: Vec3::zeros(),
        yaw: YawTarget::Rate(0.0),
        max_speed_mps: 0.75,
    };
    let hold = |explore: &mut Explore, scene: &Scene, from_ms: u64, ticks: u64| {
        for k in 0..ticks {
            let ctx = scene.ctx_at(Duration::from_millis(from_ms + 100 * k));
            explore.watch_tracking(&ctx, Some(&ahead_and_aside(k)));
        }
    };
    scene.safety_override = Some(OverrideKind::Separation);
    hold(&mut explore, &scene, 0, 30);
    assert_eq!(explore.tracking.extra_m(), 0.0, "held for a peer: no stray");
    // Let go, it catches up within the grace: still none.
    scene.safety_override = None;
    hold(&mut explore, &scene, 3_000, 20);
    assert_eq!(explore.tracking.extra_m(), 0.0, "catching up: no stray");
    // Past the grace, the same error is its own.
    hold(&mut explore, &scene, 8_100, 10);
    assert!(
        explore.tracking.extra_m() >= 0.3,
        "{}",
        explore.tracking.extra_m()
    );
}

#[test]
fn a_map_correction_step_drops_the_path_and_the_hover_point_moves_with_it() {
    let (mut scene, mut explore, mut requests) = asked_at_the_origin();
    answer_with_goal(&scene);
    explore.explore_tick(&scene.ctx(2), &mut requests).unwrap();
    assert!(explore.child.is_some(), "flying to its frontier");
    // A small step is followed: the path goes on.
    scene.map_step_m = Vec3::new(0.1, 0.0, 0.0);
    scene.set_position(Vec3::new(0.1, 0.0, 1.0), Vec3::zeros());
    explore.explore_tick(&scene.ctx(3), &mut requests).unwrap();
    assert!(explore.child.is_some(), "a 0.1 m step keeps the path");
    // A 0.6 m step: the map now has the drone 0.6 m north of where its path starts.
    scene.map_step_m = Vec3::new(0.0, 0.6, 0.0);
    scene.set_position(Vec3::new(0.1, 0.6, 1.0), Vec3::zeros());
    let held = explore.explore_tick(&scene.ctx(4), &mut requests).unwrap();
    assert!(explore.child.is_none(), "the path is dropped");
    let Some(MotionReference::Position { position_enu_m, .. }) = held else {
        panic!("no hold: {held:?}");
    };
    assert!(
        (position_enu_m - Vec3::new(0.1, 0.6, 1.0)).norm() < 1e-9,
        "it holds where the vehicle is, not where the map had it: {position_enu_m}"
    );
    assert!(
        matches!(
            scene.services.drain_calls().first(),
            Some(ServiceCall::Explore(_))
        ),
        "and asks again at once"
    );
    // Hovering, a further step moves the hover point with it.
    scene.map_step_m = Vec3::new(-0.3, 0.0, 0.0);
    scene.set_position(Vec3::new(-0.2, 0.6, 1.0), Vec3::zeros());
    let held = explore.explore_tick(&scene.ctx(5), &mut requests).unwrap();
    let Some(MotionReference::Position { position_enu_m, .. }) = held else {
        panic!("no hold: {held:?}");
    };
    assert!(
        (position_enu_m - Vec3::new(-0.2, 0.6, 1.0)).norm() < 1e-9,
        "{position_enu_m}"
    );
}
