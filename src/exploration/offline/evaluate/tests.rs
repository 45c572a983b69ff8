use super::*;
use crate::sim::world::Bounds;
use std::f64::consts::{FRAC_PI_4, PI, TAU};

/// A 10 m x 10 m world centred on the origin with poles of radius 0.25 m.
fn world(poles: &[[f64; 2]]) -> World {
    let mut w = World::empty();
    w.bounds_m = Bounds {
        x: [-5.0, 5.0],
        y: [-5.0, 5.0],
    };
    w.pole_radius_m = 0.25;
    w.poles_xy_m = poles.to_vec();
    w
}

fn pose(t_s: f64, drone: &str, x: f64, y: f64, z: f64, yaw: f64) -> PoseSample {
    PoseSample {
        t_s,
        drone: drone.into(),
        x_m: x,
        y_m: y,
        z_m: z,
        yaw_rad: yaw,
        crashed: false,
    }
}

/// Whether the cell holding (x, y) is known to drone `drone` after casting `samples`.
fn known_at(w: &World, samples: &[PoseSample], drone: usize, x: f64, y: f64) -> bool {
    let p = EvalParams::default();
    let raster = Raster::over(&w.bounds_m, p.cell_m).unwrap();
    let index = ShapeIndex::new(w.shapes());
    let tracks = motion::Tracks::new(samples, p.airborne_z_m);
    let known = coverage::cast(&raster, &index, &tracks, &p);
    let (ix, iy) = raster.cell_of(x, y).unwrap();
    known.per_drone()[drone].contains(iy * raster.nx + ix)
}

#[test]
fn a_full_turn_in_the_open_sees_a_disc_of_the_beam_range() {
    let samples: Vec<PoseSample> = (0..=720)
        .map(|k| {
            let t = f64::from(k) * 0.05;
            pose(t, "d0", 0.05, 0.05, 1.0, TAU * f64::from(k) / 720.0)
        })
        .collect();
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    // pi R^2 over the 100 m^2 world; the cells the beams' ends cross add a rim.
    let disc_pct = PI * 16.0;
    assert!(
        (m.area_pct - disc_pct).abs() < 0.04 * disc_pct,
        "{} vs {disc_pct}",
        m.area_pct
    );
    assert!(m.area_closed_pct >= m.area_pct);
    assert!((m.observable_share_pct - 100.0).abs() < 1e-9, "open world");
    assert!((m.observable_pct - m.area_pct).abs() < 1e-9);
    assert_eq!(m.drones_flown, 1);
    assert_eq!(m.min_obstacle_clearance_m, None);
    assert_eq!(m.min_separation_m, None);
    assert_eq!(m.overlap_pct, 0.0);
}

#[test]
fn a_pole_blocks_the_beam_and_the_hit_cell_is_known() {
    let w = world(&[[2.1, 0.05]]);
    let samples = [pose(0.0, "d0", 0.05, 0.05, 1.0, 0.0)];
    assert!(known_at(&w, &samples, 0, 1.0, 0.05), "in front of the pole");
    assert!(known_at(&w, &samples, 0, 1.82, 0.05), "the hit cell");
    assert!(!known_at(&w, &samples, 0, 1.95, 0.05), "inside the pole");
    assert!(!known_at(&w, &samples, 0, 3.0, 0.05), "behind the pole");
    assert!(
        known_at(&w, &samples, 0, -3.0, 0.05),
        "the back beam is free"
    );
    assert!(
        known_at(&w, &samples, 0, 0.05, 3.9),
        "the left beam reaches 4 m"
    );
    assert!(!known_at(&w, &samples, 0, 0.05, 4.2), "and no further");
    let grounded = [pose(0.0, "d0", 0.05, 0.05, 0.2, 0.0)];
    assert!(
        !known_at(&w, &grounded, 0, 1.0, 0.05),
        "no sensing on the ground"
    );
    let m = evaluate(&w, &samples, &EvalParams::default()).unwrap();
    let clearance = m.min_obstacle_clearance_m.unwrap();
    assert!((clearance - 1.8).abs() < 1e-9, "{clearance}");
    assert_eq!(m.collisions, 0);
    assert!(m.observable_share_pct < 100.0 && m.observable_share_pct > 99.0);
}

#[test]
fn two_drones_looking_along_one_row_overlap_on_it() {
    let samples = [
        pose(0.0, "a", -0.95, 0.05, 1.0, 0.0),
        pose(0.0, "b", 1.05, 0.05, 1.0, 0.0),
    ];
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    // Both know the row from x = -2.95 to 3.05: 61 cells of 10 000.
    assert!((m.overlap_pct - 0.61).abs() <= 0.021, "{}", m.overlap_pct);
    let known = m.area_pct * 100.0;
    assert!((m.multi_observed_pct - 100.0 * 61.0 / known).abs() < 2.5);
    assert_eq!(m.drones.len(), 2);
    assert!((m.drones[0].area_pct - m.drones[1].area_pct).abs() < 0.03);
    let sep = m.min_separation_m.unwrap();
    assert!((sep - 2.0).abs() < 1e-9, "{sep}");
}

#[test]
fn paths_sum_over_drones_in_euclidean_and_l1() {
    let samples = [
        pose(0.0, "a", 0.0, 0.0, 1.0, 0.0),
        pose(1.0, "a", 3.0, 4.0, 1.0, 0.0),
        pose(2.0, "a", 3.0, 4.0, 2.0, 0.0),
        pose(0.0, "b", 0.0, 0.0, 1.0, 0.0),
        pose(1.0, "b", 0.0, -2.0, 1.0, 0.0),
    ];
    // Out of order on purpose: the evaluator sorts each drone's samples by time.
    let mut shuffled = samples.to_vec();
    shuffled.reverse();
    let m = evaluate(&world(&[]), &shuffled, &EvalParams::default()).unwrap();
    assert!(
        (m.drones[0].path_m - 5.0).abs() < 1e-9,
        "vertical moves do not count"
    );
    assert!((m.drones[0].path_l1_m - 7.0).abs() < 1e-9);
    assert!((m.path_m - 7.0).abs() < 1e-9 && (m.path_l1_m - 9.0).abs() < 1e-9);
}

#[test]
fn separation_compares_samples_close_in_time_only() {
    let samples = [
        pose(0.0, "a", 0.0, 0.0, 1.0, 0.0),
        pose(0.0, "b", 1.5, 0.0, 1.0, 0.0),
        pose(1.0, "a", 0.0, 0.0, 1.0, 0.0),
        pose(1.1, "b", 0.1, 0.0, 1.0, 0.0),
        pose(2.0, "a", 0.0, 0.0, 1.0, 0.0),
        pose(2.05, "b", 0.0, 0.15, 1.0, 0.0),
        pose(3.0, "a", 0.0, 0.0, 1.0, 0.0),
        pose(3.0, "b", 0.0, 0.5, 0.1, 0.0),
    ];
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    let sep = m.min_separation_m.unwrap();
    assert!(
        (sep - 0.15).abs() < 1e-9,
        "t = 1.0 vs 1.1 is too far apart: {sep}"
    );
    assert_eq!(m.drone_collision_pairs, 1);
    assert_eq!(m.collisions, 1);
}

#[test]
fn time_runs_from_first_takeoff_to_last_landing() {
    let mut samples = Vec::new();
    for k in 0..=120 {
        let t = f64::from(k) * 0.1;
        // a: on the ground until 2 s, flies to 10 s; b: flies from 3 s to 11 s.
        let za = if (2.0..=10.0).contains(&t) { 1.0 } else { 0.0 };
        let zb = if (3.0..=11.0).contains(&t) { 1.0 } else { 0.0 };
        samples.push(pose(t, "a", -2.0 + 0.3 * t, -2.0, za, 0.0));
        samples.push(pose(t, "b", 2.0, -2.0 + 0.3 * t, zb, FRAC_PI_4));
    }
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    assert!((m.first_takeoff_s - 2.0).abs() < 1e-9);
    assert!((m.last_landing_s - 11.0).abs() < 1e-9);
    assert!((m.time_s - 9.0).abs() < 1e-9);
    assert_eq!(m.drones_flown, 2);
    let ts: Vec<f64> = m.area_curve.iter().map(|p| p.t_s).collect();
    assert_eq!(ts, [0.0, 10.0, 12.0]);
    assert_eq!(m.area_curve[0].area_pct, 0.0);
    assert!((m.area_curve[2].area_pct - m.area_pct).abs() < 1e-9);
    assert_eq!(m.time_to_pct.len(), 3);
    for w in m.time_to_pct.windows(2) {
        assert!(w[0].time_s <= w[1].time_s);
    }
    assert!(m.time_to_pct[2].time_s <= m.time_s);
    let expected = lower_bound_s(m.area_pct / 100.0 * 100.0, 2, 4.0, 0.75);
    assert!((m.lower_bound_s - expected).abs() < 1e-9);
    let never = [pose(0.0, "a", 0.0, 0.0, 0.1, 0.0)];
    assert!(matches!(
        evaluate(&world(&[]), &never, &EvalParams::default()),
        Err(EvalError::NeverAirborne(_))
    ));
}

#[test]
fn lower_bound_matches_the_research_table() {
    // Low density, one drone: (2484 - 50.3) / 6 = 405.7 s.
    let t = lower_bound_s(0.9937 * 2500.0, 1, 4.0, 0.75);
    assert!((t - 405.7).abs() < 0.2, "{t}");
    assert_eq!(lower_bound_s(10.0, 1, 4.0, 0.75), 0.0);
    assert_eq!(lower_bound_s(100.0, 0, 4.0, 0.75), 0.0);
}

#[test]
fn observable_excludes_pole_interiors_and_enclosed_pockets() {
    // A closed ring of poles around (3, 3): its inside is not reachable, but within 4 m of
    // reachable space; beams pass between the poles only where the ring leaves gaps.
    let ring: Vec<[f64; 2]> = (0..24)
        .map(|k| {
            let a = TAU * f64::from(k) / 24.0;
            [3.0 + 1.0 * a.cos(), 3.0 + 1.0 * a.sin()]
        })
        .collect();
    let w = world(&ring);
    let samples = [pose(0.0, "a", -3.0, -3.0, 1.0, 0.0)];
    let m = evaluate(&w, &samples, &EvalParams::default()).unwrap();
    let ring_area_pct = PI * 1.25 * 1.25;
    assert!(m.observable_share_pct < 100.0 - 0.5 * ring_area_pct);
    assert!(m.observable_share_pct > 100.0 - 1.2 * ring_area_pct);
}

#[test]
fn bad_parameters_are_refused() {
    let p = EvalParams {
        cell_m: 0.0,
        ..EvalParams::default()
    };
    let samples = [pose(0.0, "a", 0.0, 0.0, 1.0, 0.0)];
    assert!(matches!(
        evaluate(&world(&[]), &samples, &p),
        Err(EvalError::Param("cell_m"))
    ));
}

#[test]
fn the_map_lists_its_cells_in_the_order_they_became_known() {
    // a casts its four beams in the south-west at 1 s, b in the north-east at 3 s.
    let samples = [
        pose(1.0, "a", -4.0, -4.0, 1.0, 0.0),
        pose(3.0, "b", 4.0, 4.0, 1.0, PI),
    ];
    let (m, map) = evaluate_with_map(&world(&[]), &samples, &EvalParams::default()).unwrap();
    assert_eq!(map.order.len(), m.known_cells);
    assert!(map.order.iter().all(|&i| map.known[i as usize]));
    let times: Vec<f64> = map.growth.iter().map(|g| g.0).collect();
    assert_eq!(times, [1.0, 3.0]);
    let (_, at_first) = map.growth[0];
    assert!((100.0 * at_first as f64 / m.grid_cells as f64 - m.drones[0].area_pct).abs() < 1e-9);
    assert_eq!(map.growth[1].1, m.known_cells);
    // The first cells listed are exactly the ones a alone makes known.
    let (_, a_map) = evaluate_with_map(&world(&[]), &samples[..1], &EvalParams::default()).unwrap();
    let mut first: Vec<u32> = map.order[..at_first].to_vec();
    first.sort_unstable();
    let a_cells: Vec<u32> = (0..a_map.known.len() as u32)
        .filter(|&i| a_map.known[i as usize])
        .collect();
    assert_eq!(first, a_cells);
}

#[test]
fn a_contact_between_two_samples_is_a_collision() {
    // Past a pole at the origin (radius 0.25 m) 0.3 m off its centre: both samples are 0.33 m
    // from its surface, the flight between them 0.05 m.
    let w = world(&[[0.0, 0.0]]);
    let samples = [
        pose(0.0, "d0", -0.5, 0.3, 1.0, 0.0),
        pose(0.1, "d0", 0.5, 0.3, 1.0, 0.0),
    ];
    let m = evaluate(&w, &samples, &EvalParams::default()).unwrap();
    let clearance = m.min_obstacle_clearance_m.unwrap();
    assert!((clearance - 0.05).abs() < 1e-6, "{clearance}");
    assert_eq!((m.obstacle_collision_samples, m.collisions), (1, 1));
    // 0.5 m off: near, no contact.
    let wide = [
        pose(0.0, "d0", -0.5, 0.5, 1.0, 0.0),
        pose(0.1, "d0", 0.5, 0.5, 1.0, 0.0),
    ];
    let m = evaluate(&w, &wide, &EvalParams::default()).unwrap();
    assert!((m.min_obstacle_clearance_m.unwrap() - 0.25).abs() < 1e-6);
    assert_eq!(m.collisions, 0);
}

#[test]
fn a_crashed_flight_is_a_collision() {
    let mut samples = vec![
        pose(0.0, "d0", 0.0, 2.0, 1.0, 0.0),
        pose(0.1, "d0", 0.0, 2.0, 1.0, 0.0),
    ];
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    assert_eq!((m.crashes, m.collisions), (0, 0));
    // The simulator ends the flight at a contact its samples need not show.
    for t in [0.2, 0.3] {
        samples.push(PoseSample {
            crashed: true,
            ..pose(t, "d0", 0.0, 2.0, 0.9, 0.0)
        });
    }
    let m = evaluate(&world(&[]), &samples, &EvalParams::default()).unwrap();
    assert_eq!((m.crashes, m.collisions), (1, 1));
}
