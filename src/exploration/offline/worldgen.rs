//! Seeded exploration worlds in the thesis layout (exploration-research §4.1).
//!
//! In: [`WorldGenParams`] (side, pole count or density, seed, open or fenced, dispersed or
//! co-located starts). Out: a [`World`] whose poles (radius 0.25 m) and nested start lists
//! (`starts_xy_yaw` keyed "1", "2", "3", "5", "7") follow the thesis generator, and
//! [`world_file_json`] to write it in the layout of `sitl/worlds/low.json`. The same
//! parameters and seed always give the same world (`ChaCha8Rng`).
//!
//! Rules: pole centres iid uniform over the square, rounded to 0.01 m, overlaps allowed; 7 starts
//! uniform in the square shrunk by 1 m, at least 2.4 m apart (1.2 m when co-located), with yaw
//! uniform in [0, 2 pi). A pole whose surface would come within 2 m of a start is resampled (the
//! thesis checks the centre against drone 0 only; this is stricter and checks every start). The
//! fence variant rings the square with poles 0.6 m apart, 0.5 m inside the border, leaving one
//! opening at least 2 m wide, and puts the random poles and the starts inside it.

use crate::sim::world::{Bounds, World};
use crate::types::SensorConfig;
use rand::Rng;
use rand::SeedableRng;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;
use std::collections::BTreeMap;
use std::f64::consts::TAU;

/// Radius of every generated pole (m), the thesis's pole model.
pub const POLE_RADIUS_M: f64 = 0.25;
/// Drone counts the start lists are written for (nested: the first N of 7).
pub const START_COUNTS: [usize; 5] = [1, 2, 3, 5, 7];
/// Least distance from a start to any pole's surface (m).
pub const START_POLE_CLEARANCE_M: f64 = 2.0;
/// Least distance between dispersed starts (m): above the 2.0 m safeguard trigger.
pub const START_SEPARATION_M: f64 = 2.4;
/// Least distance between co-located starts (m).
pub const CO_LOCATED_SEPARATION_M: f64 = 1.2;
/// Radius of the disc co-located starts share (m): a 3 m disc.
pub const CO_LOCATED_RADIUS_M: f64 = 1.5;
/// Fence: centre-to-centre spacing (m), inset from the border (m), clear opening (m).
pub const FENCE_SPACING_M: f64 = 0.6;
pub const FENCE_INSET_M: f64 = 0.5;
pub const FENCE_OPENING_M: f64 = 2.0;

const MAX_STARTS: usize = 7;
/// Upper bound on random poles, so a typo in a density cannot exhaust memory.
const MAX_POLES: usize = 1_000_000;
/// Draws per pole or start before the generator gives up.
const MAX_DRAWS: usize = 100_000;

/// How many random poles to place.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PoleCount {
    Exactly(usize),
    /// Poles per m^2 of the area they are spread over (the fence's inside for a fence world).
    PerM2(f64),
}

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldGenParams {
    /// Side of the square world, centred on the origin (m).
    pub size_m: f64,
    pub poles: PoleCount,
    pub seed: u64,
    /// Ring the area with a fence of poles that has one opening.
    pub fence: bool,
    /// All starts in one 3 m disc at a seeded point instead of spread over the area.
    pub co_located: bool,
}

#[derive(Debug, thiserror::Error, PartialEq)]
pub enum WorldGenError {
    #[error("size_m must be between 12 and 10000 m, got {0}")]
    Size(f64),
    #[error("pole density must be finite and >= 0 poles/m^2, got {0}")]
    Density(f64),
    #[error("{0} poles is more than the {MAX_POLES} allowed")]
    TooManyPoles(usize),
    #[error("cannot write the world as JSON: {0}")]
    Json(String),
    #[error("could not place {what} after {MAX_DRAWS} draws; the world is too crowded")]
    Crowded { what: &'static str },
}

/// Generates the world described by `params`.
pub fn generate(params: &WorldGenParams) -> Result<World, WorldGenError> {
    let size = params.size_m;
    if !(12.0..=10_000.0).contains(&size) {
        return Err(WorldGenError::Size(size));
    }
    let half = size / 2.0;
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    let fence = if params.fence {
        fence_poles(half, &mut rng)
    } else {
        Vec::new()
    };
    let pole_half = random_pole_half_m(params);
    // Starts keep their clearance from the fence too.
    let start_half = if params.fence {
        pole_half - POLE_RADIUS_M - START_POLE_CLEARANCE_M
    } else {
        half - 1.0
    };
    let count = random_pole_count(params)?;
    let starts = if params.co_located {
        co_located_starts(start_half, &fence, &mut rng)?
    } else {
        dispersed_starts(start_half, &fence, &mut rng)?
    };
    let mut poles = fence;
    for _ in 0..count {
        poles.push(random_pole(pole_half, &starts, &mut rng)?);
    }
    Ok(World {
        name: name_of(params),
        bounds_m: Bounds {
            x: [-half, half],
            y: [-half, half],
        },
        pole_radius_m: POLE_RADIUS_M,
        pole_height_m: 5.0,
        poles_xy_m: poles,
        starts_xy_yaw: START_COUNTS
            .iter()
            .map(|&n| (n.to_string(), starts.iter().take(n).copied().collect()))
            .collect::<BTreeMap<_, _>>(),
        cylinders: Vec::new(),
        boxes: Vec::new(),
        sensor: SensorConfig::multiranger(),
        geodetic_origin: None,
    })
}

/// Half side of the square the random poles are spread over (m): the fence's inside for a
/// fence world.
fn random_pole_half_m(params: &WorldGenParams) -> f64 {
    let half = params.size_m / 2.0;
    if params.fence {
        half - FENCE_INSET_M
    } else {
        half
    }
}

/// How many random poles `params` asks for.
fn random_pole_count(params: &WorldGenParams) -> Result<usize, WorldGenError> {
    let count = match params.poles {
        PoleCount::Exactly(n) => n,
        PoleCount::PerM2(d) if d.is_finite() && d >= 0.0 => {
            let n = (d * (2.0 * random_pole_half_m(params)).powi(2)).round();
            if n > MAX_POLES as f64 {
                return Err(WorldGenError::TooManyPoles(MAX_POLES + 1));
            }
            n as usize
        }
        PoleCount::PerM2(d) => return Err(WorldGenError::Density(d)),
    };
    if count > MAX_POLES {
        return Err(WorldGenError::TooManyPoles(count));
    }
    Ok(count)
}

/// A world file in the thesis layout, fields in its order.
#[derive(Serialize)]
struct WorldFile<'a> {
    name: &'a str,
    source: &'a str,
    bounds_m: &'a Bounds,
    pole_radius_m: f64,
    pole_height_m: f64,
    /// Every pole, fence included.
    pole_count: usize,
    /// Random poles per m^2 of the area they are spread over.
    poles_per_m2: f64,
    #[serde(skip_serializing_if = "Option::is_none")]
    fence_pole_count: Option<usize>,
    poles_xy_m: &'a [[f64; 2]],
    starts_xy_yaw: &'a BTreeMap<String, Vec<[f64; 3]>>,
}

/// `world` (made by [`generate`] from `params`) as JSON in the thesis layout (`name`,
/// `source`, `bounds_m`, `pole_radius_m`, `pole_count`, `poles_per_m2`, `poles_xy_m`,
/// `starts_xy_yaw`; fence worlds add `fence_pole_count`), which [`World::load`] reads.
pub fn world_file_json(
    world: &World,
    params: &WorldGenParams,
    source: &str,
) -> Result<String, WorldGenError> {
    let random = random_pole_count(params)?;
    let side_m = 2.0 * random_pole_half_m(params);
    let density = random as f64 / (side_m * side_m);
    let file = WorldFile {
        name: &world.name,
        source,
        bounds_m: &world.bounds_m,
        pole_radius_m: world.pole_radius_m,
        pole_height_m: world.pole_height_m,
        pole_count: world.poles_xy_m.len(),
        poles_per_m2: (density * 10_000.0).round() / 10_000.0,
        fence_pole_count: params
            .fence
            .then(|| world.poles_xy_m.len().saturating_sub(random)),
        poles_xy_m: &world.poles_xy_m,
        starts_xy_yaw: &world.starts_xy_yaw,
    };
    serde_json::to_string_pretty(&file).map_err(|e| WorldGenError::Json(e.to_string()))
}

/// A stable name: `pole20_d010_s1`, `fence20_n50_s3_co` (density in hundredths per m^2).
pub fn name_of(params: &WorldGenParams) -> String {
    let kind = if params.fence { "fence" } else { "pole" };
    let poles = match params.poles {
        PoleCount::Exactly(n) => format!("n{n}"),
        PoleCount::PerM2(d) => format!("d{:03}", (d * 100.0).round() as i64),
    };
    let co = if params.co_located { "_co" } else { "" };
    format!(
        "{kind}{}_{poles}_s{}{co}",
        params.size_m.round() as i64,
        params.seed
    )
}

fn round_cm(v: f64) -> f64 {
    (v * 100.0).round() / 100.0
}

fn distance_m(a: [f64; 2], b: [f64; 2]) -> f64 {
    (a[0] - b[0]).hypot(a[1] - b[1])
}

/// Whether a start at `p` keeps its distance to every pole centre in `poles`.
fn clear_of_poles(p: [f64; 2], poles: &[[f64; 2]]) -> bool {
    poles
        .iter()
        .all(|&q| distance_m(p, q) >= START_POLE_CLEARANCE_M + POLE_RADIUS_M)
}

fn dispersed_starts(
    half: f64,
    fence: &[[f64; 2]],
    rng: &mut ChaCha8Rng,
) -> Result<Vec<[f64; 3]>, WorldGenError> {
    let mut starts: Vec<[f64; 3]> = Vec::with_capacity(MAX_STARTS);
    while starts.len() < MAX_STARTS {
        let found = (0..MAX_DRAWS).find_map(|_| {
            let p = [
                round_cm(rng.gen_range(-half..=half)),
                round_cm(rng.gen_range(-half..=half)),
            ];
            let yaw = round_cm(rng.gen_range(0.0..TAU));
            let apart = starts
                .iter()
                .all(|s| distance_m(p, [s[0], s[1]]) >= START_SEPARATION_M);
            (apart && clear_of_poles(p, fence)).then_some([p[0], p[1], yaw])
        });
        starts.push(found.ok_or(WorldGenError::Crowded { what: "the starts" })?);
    }
    Ok(starts)
}

/// Seven starts in a 3 m disc: the centre and a ring of six 1.35 m out, turned by a seeded angle,
/// each nudged by up to 3.5 cm, in a seeded order. Uniform draws would rarely fit seven starts
/// 1.2 m apart into a disc this small, so the pattern is hexagonal and only its pose is random.
fn co_located_starts(
    half: f64,
    fence: &[[f64; 2]],
    rng: &mut ChaCha8Rng,
) -> Result<Vec<[f64; 3]>, WorldGenError> {
    const RING_M: f64 = 1.35;
    const JITTER_M: f64 = 0.07;
    let centre_half = half - CO_LOCATED_RADIUS_M;
    let centre = (0..MAX_DRAWS)
        .map(|_| {
            [
                rng.gen_range(-centre_half..=centre_half),
                rng.gen_range(-centre_half..=centre_half),
            ]
        })
        .find(|&c| clear_of_poles(c, fence))
        .ok_or(WorldGenError::Crowded {
            what: "the start disc",
        })?;
    let turn = rng.gen_range(0.0..TAU);
    let mut spots: Vec<[f64; 2]> = std::iter::once([0.0, 0.0])
        .chain((0..6).map(|k| {
            let a = turn + f64::from(k) * TAU / 6.0;
            [RING_M * a.cos(), RING_M * a.sin()]
        }))
        .collect();
    // Seeded Fisher-Yates, so the nested subsets are not always the centre and its neighbours.
    for i in (1..spots.len()).rev() {
        spots.swap(i, rng.gen_range(0..=i));
    }
    let starts: Vec<[f64; 3]> = spots
        .iter()
        .map(|s| {
            let (a, r) = (rng.gen_range(0.0..TAU), rng.gen_range(0.0..JITTER_M / 2.0));
            let x = round_cm(centre[0] + s[0] + r * a.cos());
            let y = round_cm(centre[1] + s[1] + r * a.sin());
            [x, y, round_cm(rng.gen_range(0.0..TAU))]
        })
        .collect();
    if starts.iter().all(|s| clear_of_poles([s[0], s[1]], fence)) {
        Ok(starts)
    } else {
        Err(WorldGenError::Crowded {
            what: "the start disc",
        })
    }
}

/// One pole centre uniform over the square of half side `half`, redrawn while it is too close
/// to a start.
fn random_pole(
    half: f64,
    starts: &[[f64; 3]],
    rng: &mut ChaCha8Rng,
) -> Result<[f64; 2], WorldGenError> {
    let starts_xy: Vec<[f64; 2]> = starts.iter().map(|s| [s[0], s[1]]).collect();
    (0..MAX_DRAWS)
        .map(|_| {
            [
                round_cm(rng.gen_range(-half..=half)),
                round_cm(rng.gen_range(-half..=half)),
            ]
        })
        .find(|&p| clear_of_poles(p, &starts_xy))
        .ok_or(WorldGenError::Crowded { what: "a pole" })
}

/// Poles every [`FENCE_SPACING_M`] along the square of half side `half - FENCE_INSET_M`, minus
/// those that would narrow the seeded opening below [`FENCE_OPENING_M`].
fn fence_poles(half: f64, rng: &mut ChaCha8Rng) -> Vec<[f64; 2]> {
    let h = half - FENCE_INSET_M;
    let side = 2.0 * h;
    // The small epsilon keeps a side that is a whole number of spacings from getting a pole
    // on the next side's corner.
    let per_side = (side / FENCE_SPACING_M - 1e-9).ceil() as usize;
    let opening_side = rng.gen_range(0..4usize);
    let keep_out = FENCE_OPENING_M / 2.0 + POLE_RADIUS_M;
    let opening_at = rng.gen_range(keep_out + FENCE_SPACING_M..=side - keep_out - FENCE_SPACING_M);
    let mut poles = Vec::with_capacity(4 * per_side);
    for s in 0..4usize {
        for k in 0..per_side {
            let u = k as f64 * FENCE_SPACING_M;
            if s == opening_side && (u - opening_at).abs() < keep_out {
                continue;
            }
            // Counter-clockwise from the south-west corner; each side starts at its corner.
            let p = match s {
                0 => [-h + u, -h],
                1 => [h, -h + u],
                2 => [h - u, h],
                _ => [-h, h - u],
            };
            poles.push([round_cm(p[0]), round_cm(p[1])]);
        }
    }
    poles
}

#[cfg(test)]
mod tests {
    use super::*;

    fn params(seed: u64) -> WorldGenParams {
        WorldGenParams {
            size_m: 20.0,
            poles: PoleCount::PerM2(0.25),
            seed,
            fence: false,
            co_located: false,
        }
    }

    fn starts7(w: &World) -> Vec<[f64; 3]> {
        w.starts_xy_yaw.get("7").cloned().unwrap_or_default()
    }

    /// Every start clear of every pole surface by 2 m, inside the bounds shrunk by 1 m, and
    /// at least `apart_m` from the other starts.
    fn check_starts(w: &World, apart_m: f64) {
        let starts = starts7(w);
        assert_eq!(starts.len(), 7);
        let half = w.bounds_m.x[1];
        for (i, s) in starts.iter().enumerate() {
            assert!(
                s[0].abs() <= half - 1.0 && s[1].abs() <= half - 1.0,
                "{s:?}"
            );
            assert!((0.0..TAU).contains(&s[2]), "yaw {}", s[2]);
            for p in &w.poles_xy_m {
                let d = distance_m([s[0], s[1]], *p) - w.pole_radius_m;
                assert!(d >= START_POLE_CLEARANCE_M - 1e-9, "start {s:?} pole {p:?}");
            }
            for t in starts.iter().skip(i + 1) {
                assert!(distance_m([s[0], s[1]], [t[0], t[1]]) >= apart_m - 1e-9);
            }
        }
    }

    #[test]
    fn same_seed_same_world_other_seed_other_world() {
        let a = generate(&params(1)).unwrap();
        assert_eq!(a, generate(&params(1)).unwrap());
        assert_ne!(a.poles_xy_m, generate(&params(2)).unwrap().poles_xy_m);
        let fenced = WorldGenParams {
            fence: true,
            co_located: true,
            ..params(4)
        };
        assert_eq!(generate(&fenced).unwrap(), generate(&fenced).unwrap());
    }

    #[test]
    fn counts_bounds_rounding_and_nested_starts() {
        let w = generate(&params(3)).unwrap();
        assert_eq!(w.poles_xy_m.len(), 100, "0.25 poles/m^2 over 400 m^2");
        assert_eq!(w.pole_radius_m, 0.25);
        for p in &w.poles_xy_m {
            assert!(p[0].abs() <= 10.0 && p[1].abs() <= 10.0);
            assert!(
                ((p[0] * 100.0).round() - p[0] * 100.0).abs() < 1e-6,
                "{p:?}"
            );
        }
        let seven = starts7(&w);
        for n in START_COUNTS {
            let list = w.starts_xy_yaw.get(&n.to_string()).unwrap();
            assert_eq!(list.as_slice(), &seven[..n]);
        }
        check_starts(&w, START_SEPARATION_M);
        let exact = WorldGenParams {
            poles: PoleCount::Exactly(37),
            ..params(3)
        };
        assert_eq!(generate(&exact).unwrap().poles_xy_m.len(), 37);
    }

    #[test]
    fn starts_keep_clear_even_in_crowded_worlds() {
        for seed in 0..20 {
            let crowded = WorldGenParams {
                poles: PoleCount::PerM2(1.0),
                ..params(seed)
            };
            check_starts(&generate(&crowded).unwrap(), START_SEPARATION_M);
        }
    }

    #[test]
    fn co_located_starts_share_a_3_m_disc() {
        for seed in 0..20 {
            let w = generate(&WorldGenParams {
                co_located: true,
                ..params(seed)
            })
            .unwrap();
            check_starts(&w, CO_LOCATED_SEPARATION_M);
            let starts = starts7(&w);
            for a in &starts {
                for b in &starts {
                    assert!(distance_m([a[0], a[1]], [b[0], b[1]]) <= 2.0 * CO_LOCATED_RADIUS_M);
                }
            }
        }
    }

    #[test]
    fn fence_rings_the_area_with_one_opening() {
        let w = generate(&WorldGenParams {
            fence: true,
            poles: PoleCount::Exactly(0),
            ..params(5)
        })
        .unwrap();
        check_starts(&w, START_SEPARATION_M);
        let h = 10.0 - FENCE_INSET_M;
        let mut gaps = Vec::new();
        // Walk each side in order and measure the clear gaps between neighbouring poles.
        for side in 0..4 {
            let mut along: Vec<f64> = w
                .poles_xy_m
                .iter()
                .filter_map(|p| match side {
                    0 => (p[1] == -h).then_some(p[0]),
                    1 => (p[0] == h).then_some(p[1]),
                    2 => (p[1] == h).then_some(p[0]),
                    _ => (p[0] == -h).then_some(p[1]),
                })
                .collect();
            along.sort_by(f64::total_cmp);
            assert_eq!(
                along.first().copied(),
                Some(-h),
                "corner pole on side {side}"
            );
            assert!(along.last().unwrap() + FENCE_SPACING_M >= h - 1e-9);
            gaps.extend(along.windows(2).map(|p| p[1] - p[0] - 2.0 * POLE_RADIUS_M));
        }
        let wide: Vec<f64> = gaps.iter().copied().filter(|g| *g > 0.2).collect();
        assert_eq!(wide.len(), 1, "one opening: {wide:?}");
        assert!(wide[0] >= FENCE_OPENING_M - 1e-9 && wide[0] < FENCE_OPENING_M + 0.7);
        let with_inside = generate(&WorldGenParams {
            fence: true,
            ..params(5)
        })
        .unwrap();
        assert_eq!(
            with_inside.poles_xy_m.len() - w.poles_xy_m.len(),
            90,
            "0.25 poles/m^2 over the 19 m x 19 m inside"
        );
    }

    #[test]
    fn bad_parameters_are_refused_and_the_file_loads_back() {
        let bad = |p: WorldGenParams| generate(&p).unwrap_err();
        assert_eq!(
            bad(WorldGenParams {
                size_m: 4.0,
                ..params(1)
            }),
            WorldGenError::Size(4.0)
        );
        assert!(matches!(
            bad(WorldGenParams {
                poles: PoleCount::PerM2(-1.0),
                ..params(1)
            }),
            WorldGenError::Density(_)
        ));
        let w = generate(&params(1)).unwrap();
        let text = world_file_json(&w, &params(1), "test").unwrap();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("w.json");
        std::fs::write(&path, text).unwrap();
        let back = World::load(&path).unwrap();
        assert_eq!(back.poles_xy_m, w.poles_xy_m);
        assert_eq!(back.starts(3), w.starts(3));
        assert_eq!(name_of(&params(1)), "pole20_d025_s1");
    }

    #[test]
    fn the_shipped_worlds_are_what_the_generator_makes() {
        let shipped = [
            ("pole20_d010_s1", 0.1, false),
            ("pole20_d025_s1", 0.25, false),
            ("fence20_s1", 0.1, true),
        ];
        for (file, density, fence) in shipped {
            let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("sitl/worlds")
                .join(format!("{file}.json"));
            let loaded = World::load(&path).unwrap();
            let made = generate(&WorldGenParams {
                poles: PoleCount::PerM2(density),
                fence,
                ..params(1)
            })
            .unwrap();
            assert_eq!(loaded.poles_xy_m, made.poles_xy_m, "{file}");
            assert_eq!(loaded.starts_xy_yaw, made.starts_xy_yaw, "{file}");
        }
    }
}
