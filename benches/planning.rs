//! Planning benchmarks on a 500 x 500 grid (0.1 m cells) with 10 % random obstacles, corner to
//! corner: A*, Dijkstra and Voronoi (median time per plan, including pruning), the `pathfinding`
//! crate's A* on the same grid and moves as a baseline, and a 4-drone coverage plan. Also the
//! thesis's "medium" Gazebo world (50 m x 50 m, 315 poles of 0.25 m radius, `sitl/worlds`) at
//! 0.1 m with the Gazebo configuration's 0.4 m safety distance, between two drone starts.
//!
//! Run: `cargo bench --bench planning -- --quick`

use std::hint::black_box;
use std::time::Instant;

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Vector2, Vector3};
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use kestrel::mapping::{GridSpec, OccupancyGrid};
use kestrel::planning::{
    plan_coverage, PathPlanner, PlanBudget, PlanRequest, PlannerKind, Planners, PlanningMap,
    UnknownPolicy,
};

const N: u32 = 500;

fn must<T, E: std::fmt::Debug>(r: Result<T, E>) -> T {
    match r {
        Ok(v) => v,
        Err(e) => panic!("benchmark setup failed: {e:?}"),
    }
}

fn grid() -> OccupancyGrid {
    let spec = GridSpec {
        resolution_m: 0.1,
        width_cells: N,
        height_cells: N,
        origin_enu_m: Vector2::zeros(),
    };
    let mut rng = ChaCha8Rng::seed_from_u64(42);
    let n = spec.cell_count();
    let data = (0..n)
        .map(|i| {
            // Keep the two corners free.
            if i == 0 || i == n - 1 || !rng.gen_bool(0.1) {
                0
            } else {
                100
            }
        })
        .collect();
    must(OccupancyGrid::from_data(spec, data))
}

fn request(kind: PlannerKind) -> PlanRequest {
    PlanRequest {
        start_enu_m: Vector3::new(0.05, 0.05, 1.0),
        goal_enu_m: Vector3::new(49.95, 49.95, 1.0),
        flight_height_m: 1.0,
        safety_distance_m: 0.0,
        unknown: UnknownPolicy::Blocked,
        kind,
        max_map_age_s: None,
        shadow_m: 0.0,
    }
}

fn grid_planners(c: &mut Criterion) {
    let map = PlanningMap::new(grid(), 50);
    let planners = Planners::default();
    let budget = PlanBudget::expansions(usize::MAX);
    for (name, kind) in [
        ("plan/a_star 500x500 10%", PlannerKind::AStar),
        ("plan/dijkstra 500x500 10%", PlannerKind::Dijkstra),
        ("plan/voronoi 500x500 10%", PlannerKind::Voronoi),
    ] {
        let req = request(kind);
        let p = must(planners.plan(&req, &map, &budget));
        println!(
            "{name}: cost {:.2}, length {:.2} m, {} raw cells, {} waypoints, min clearance {:.2} m",
            p.cost,
            p.length_m,
            p.raw_cells,
            p.waypoints_enu_m.len(),
            p.min_clearance_m
        );
        c.bench_function(name, |b| {
            b.iter(|| must(planners.plan(black_box(&req), &map, &budget)))
        });
    }

    // Baseline: pathfinding's A* with the same 8 moves, no corner cutting, costs x1000.
    let g = grid();
    let data = g.data().to_vec();
    let n = i64::from(N);
    let blocked = move |x: i64, y: i64| {
        x < 0
            || y < 0
            || x >= n
            || y >= n
            || data.get((y * n + x) as usize).is_none_or(|&v| v >= 50)
    };
    let goal = (n - 1, n - 1);
    let run = || {
        pathfinding::prelude::astar(
            &(0i64, 0i64),
            |&(x, y)| {
                let mut v = Vec::with_capacity(8);
                for (dx, dy) in [
                    (0, 1),
                    (1, 0),
                    (0, -1),
                    (-1, 0),
                    (1, 1),
                    (1, -1),
                    (-1, -1),
                    (-1, 1),
                ] {
                    let diag = dx != 0 && dy != 0;
                    if blocked(x + dx, y + dy)
                        || (diag && (blocked(x + dx, y) || blocked(x, y + dy)))
                    {
                        continue;
                    }
                    v.push(((x + dx, y + dy), if diag { 1414i64 } else { 1000 }));
                }
                v
            },
            |&(x, y)| {
                let (dx, dy) = ((goal.0 - x).abs(), (goal.1 - y).abs());
                dx.max(dy) * 1000 + dx.min(dy) * 414
            },
            |&p| p == goal,
        )
    };
    if let Some((path, cost)) = run() {
        println!(
            "pathfinding a_star: cost {:.2} (x 0.1 m), {} cells",
            cost as f64 / 10_000.0,
            path.len()
        );
    }
    c.bench_function("plan/pathfinding crate a_star 500x500 10%", |b| {
        b.iter(|| black_box(run()))
    });

    // The machine is shared, so also time both planners alternately (30 rounds, fastest run of
    // each): the ratio holds even when the load changes between criterion's groups.
    let req = request(PlannerKind::AStar);
    let (mut ours, mut theirs) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..30 {
        let t = Instant::now();
        black_box(must(planners.plan(&req, &map, &budget)));
        ours = ours.min(t.elapsed().as_secs_f64() * 1e3);
        let t = Instant::now();
        black_box(run());
        theirs = theirs.min(t.elapsed().as_secs_f64() * 1e3);
    }
    println!(
        "paired fastest of 30: kestrel a_star {ours:.2} ms, pathfinding a_star {theirs:.2} ms, ratio {:.2}",
        ours / theirs
    );
}

/// The thesis's medium world rasterised at 0.1 m: cells whose centre is inside a pole.
fn medium_world() -> (OccupancyGrid, Vector2<f64>, Vector2<f64>) {
    let text = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/sitl/worlds/medium.json"
    ));
    let world: serde_json::Value = must(serde_json::from_str(text));
    let radius = world["pole_radius_m"].as_f64().unwrap_or(0.25);
    let poles: Vec<Vector2<f64>> = world["poles_xy_m"]
        .as_array()
        .map(|a| {
            a.iter()
                .filter_map(|p| Some(Vector2::new(p[0].as_f64()?, p[1].as_f64()?)))
                .collect()
        })
        .unwrap_or_default();
    let xy = |v: &serde_json::Value| {
        Vector2::new(v[0].as_f64().unwrap_or(0.0), v[1].as_f64().unwrap_or(0.0))
    };
    let starts = &world["starts_xy_yaw"]["2"];
    let spec = GridSpec {
        resolution_m: 0.1,
        width_cells: N,
        height_cells: N,
        origin_enu_m: Vector2::new(-25.0, -25.0),
    };
    let mut grid = must(OccupancyGrid::new(spec));
    for y in 0..N {
        for x in 0..N {
            let c = kestrel::mapping::Cell { x, y };
            let p = spec.cell_center_enu_m(c);
            let hit = poles.iter().any(|q| (p - q).norm() <= radius);
            must(grid.set(c, if hit { 100 } else { 0 }));
        }
    }
    (grid, xy(&starts[0]), xy(&starts[1]))
}

fn thesis_world(c: &mut Criterion) {
    let (grid, from, to) = medium_world();
    let map = PlanningMap::new(grid, 50);
    let planners = Planners::default();
    let budget = PlanBudget::default();
    for (name, kind) in [
        (
            "plan/a_star thesis medium world, 0.4 m safety",
            PlannerKind::AStar,
        ),
        (
            "plan/voronoi thesis medium world, 0.4 m safety",
            PlannerKind::Voronoi,
        ),
    ] {
        let req = PlanRequest {
            start_enu_m: Vector3::new(from.x, from.y, 1.0),
            goal_enu_m: Vector3::new(to.x, to.y, 1.0),
            safety_distance_m: 0.4,
            ..request(kind)
        };
        let p = must(planners.plan(&req, &map, &budget));
        println!(
            "{name}: length {:.2} m, {} raw cells, {} waypoints, min clearance {:.2} m",
            p.length_m,
            p.raw_cells,
            p.waypoints_enu_m.len(),
            p.min_clearance_m
        );
        c.bench_function(name, |b| {
            b.iter(|| must(planners.plan(black_box(&req), &map, &budget)))
        });
    }
}

fn coverage(c: &mut Criterion) {
    let poly = [
        Vector2::new(0.0, 0.0),
        Vector2::new(400.0, 30.0),
        Vector2::new(380.0, 250.0),
        Vector2::new(150.0, 260.0),
        Vector2::new(-20.0, 180.0),
    ];
    let starts: Vec<Vector2<f64>> = (0..4)
        .map(|i| Vector2::new(f64::from(i) * 5.0, -10.0))
        .collect();
    c.bench_function("coverage/5-gon 400 m, 5 m streets, 4 drones", |b| {
        b.iter(|| must(plan_coverage(black_box(&poly), 5.0, None, &starts, 10.0)))
    });
}

criterion_group!(benches, grid_planners, thesis_world, coverage);
criterion_main!(benches);
