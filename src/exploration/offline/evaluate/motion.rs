//! How the drones moved: tracks per drone, the airborne window, paths, clearance to obstacles
//! and separation between drones.
//!
//! In: pose samples in any order, the indexed obstacles, the evaluation parameters. Out:
//! [`Tracks`] (samples per drone, sorted by time), path lengths, [`Clearance`] and
//! [`Separation`] (least distances and collision counts).

use super::{EvalParams, PoseSample};
use crate::sim::shape::Shape;
use crate::sim::spatial::ShapeIndex;
use crate::types::Vec3;
use std::collections::BTreeMap;

/// The samples of one drone, sorted by time.
#[derive(Debug, Clone)]
pub struct Track {
    pub id: String,
    pub samples: Vec<PoseSample>,
    airborne_z_m: f64,
}

impl Track {
    fn airborne(&self, s: &PoseSample) -> bool {
        s.z_m > self.airborne_z_m
    }

    /// Horizontal Euclidean length over all samples (m).
    pub fn path_m(&self) -> f64 {
        self.samples
            .windows(2)
            .map(|w| (w[1].x_m - w[0].x_m).hypot(w[1].y_m - w[0].y_m))
            .sum()
    }

    /// Horizontal L1 length over all samples (m).
    pub fn path_l1_m(&self) -> f64 {
        self.samples
            .windows(2)
            .map(|w| (w[1].x_m - w[0].x_m).abs() + (w[1].y_m - w[0].y_m).abs())
            .sum()
    }

    /// The sample nearest in time to `t_s`, if within `tolerance_s`.
    fn at(&self, t_s: f64, tolerance_s: f64) -> Option<&PoseSample> {
        let i = self.samples.partition_point(|s| s.t_s < t_s);
        [i.checked_sub(1), Some(i)]
            .into_iter()
            .flatten()
            .filter_map(|j| self.samples.get(j))
            .filter(|s| (s.t_s - t_s).abs() <= tolerance_s)
            .min_by(|a, b| (a.t_s - t_s).abs().total_cmp(&(b.t_s - t_s).abs()))
    }
}

/// Every drone's track, drones in the order of their id.
#[derive(Debug, Clone)]
pub struct Tracks {
    drones: Vec<Track>,
}

impl Tracks {
    pub fn new(samples: &[PoseSample], airborne_z_m: f64) -> Self {
        let mut by_id: BTreeMap<&str, Vec<PoseSample>> = BTreeMap::new();
        for s in samples {
            by_id.entry(s.drone.as_str()).or_default().push(s.clone());
        }
        let drones = by_id
            .into_iter()
            .map(|(id, mut samples)| {
                samples.sort_by(|a, b| a.t_s.total_cmp(&b.t_s));
                Track {
                    id: id.to_string(),
                    samples,
                    airborne_z_m,
                }
            })
            .collect();
        Self { drones }
    }

    pub fn drones(&self) -> &[Track] {
        &self.drones
    }

    /// All samples as (drone index, sample), by time (then drone).
    pub fn in_time_order(&self) -> Vec<(usize, &PoseSample)> {
        let mut all: Vec<(usize, &PoseSample)> = self
            .drones
            .iter()
            .enumerate()
            .flat_map(|(i, d)| d.samples.iter().map(move |s| (i, s)))
            .collect();
        all.sort_by(|a, b| a.1.t_s.total_cmp(&b.1.t_s).then(a.0.cmp(&b.0)));
        all
    }

    /// Log times of the first and the last airborne sample of any drone.
    pub fn airborne_window(&self) -> Option<(f64, f64)> {
        self.drones
            .iter()
            .flat_map(|d| d.samples.iter().filter(|s| d.airborne(s)).map(|s| s.t_s))
            .fold(None, |acc, t| match acc {
                None => Some((t, t)),
                Some((a, b)) => Some((f64::min(a, t), f64::max(b, t))),
            })
    }

    pub fn drones_flown(&self) -> usize {
        self.drones
            .iter()
            .filter(|d| d.samples.iter().any(|s| d.airborne(s)))
            .count()
    }

    /// Where each drone was at its first sample (m).
    pub fn start_points(&self) -> Vec<(f64, f64)> {
        self.drones
            .iter()
            .filter_map(|d| d.samples.first().map(|s| (s.x_m, s.y_m)))
            .collect()
    }
}

/// Least distance from the airborne flight to obstacles, and the contacts with one.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Clearance {
    pub min_m: Option<f64>,
    /// Airborne samples closer than the body radius, plus flights between two samples that
    /// came that close with neither sample doing so (a contact between samples).
    pub collisions: usize,
}

pub fn clearance(index: &ShapeIndex, tracks: &Tracks, params: &EvalParams) -> Clearance {
    let shapes = index.shapes();
    let mut out = Clearance {
        min_m: None,
        collisions: 0,
    };
    // Obstacles farther than the beam range are looked up only when nothing nearer exists.
    let reach_m = params.beam_range_m;
    let body_m = params.body_radius_m;
    for d in tracks.drones() {
        let mut previous: Option<Vec3> = None;
        for s in &d.samples {
            if !d.airborne(s) {
                previous = None;
                continue;
            }
            let p = Vec3::new(s.x_m, s.y_m, s.z_m);
            let nearest = |ids: &mut dyn Iterator<Item = usize>| {
                ids.filter_map(|i| shapes.get(i).and_then(|sh| sh.distance_m(&p)))
                    .reduce(f64::min)
            };
            let near = index.near(s.x_m, s.y_m, reach_m);
            let dist = match nearest(&mut near.iter().copied()) {
                Some(v) => Some(v),
                None if out.min_m.is_some_and(|m| m < reach_m) => None,
                None => nearest(&mut (0..shapes.len())),
            };
            if let Some(v) = dist {
                out.min_m = Some(out.min_m.map_or(v, |m| m.min(v)));
                if v < body_m {
                    out.collisions += 1;
                }
            }
            if let Some(a) = previous {
                for sh in near.iter().filter_map(|&i| shapes.get(i)) {
                    let Some(between) = between_samples_m(sh, &a, &p, out.min_m, body_m) else {
                        continue;
                    };
                    out.min_m = Some(
                        out.min_m
                            .map_or(between.least_m, |m| m.min(between.least_m)),
                    );
                    if between.least_m < body_m && between.ends_m >= body_m {
                        out.collisions += 1;
                    }
                }
            }
            previous = Some(p);
        }
    }
    out
}

/// How near a straight flight between two samples came to a shape.
struct Between {
    least_m: f64,
    /// The nearer of the two samples' distances.
    ends_m: f64,
}

/// The least distance to `shape` on the segment from `a` to `b` (at the lower sample's height),
/// `None` when it cannot be below `below_m` nor `body_m` (each point of the segment is within
/// half its length of a sample) or the shape is below the flight. The distance to a convex
/// shape is convex along a segment, so a ternary search finds its least value.
fn between_samples_m(
    shape: &Shape,
    a: &Vec3,
    b: &Vec3,
    below_m: Option<f64>,
    body_m: f64,
) -> Option<Between> {
    let z = a.z.min(b.z);
    let at = |t: f64| shape.distance_m(&Vec3::new(a.x + t * (b.x - a.x), a.y + t * (b.y - a.y), z));
    let ends_m = at(0.0)?.min(at(1.0)?);
    let half_m = 0.5 * (b.xy() - a.xy()).norm();
    let bound_m = below_m.map_or(f64::INFINITY, |m| m.max(body_m));
    if ends_m - half_m >= bound_m {
        return None;
    }
    let (mut lo, mut hi) = (0.0, 1.0);
    // (2/3)^40 of a segment: far below a millimetre for any flight between two samples.
    for _ in 0..40 {
        let (m1, m2) = (lo + (hi - lo) / 3.0, hi - (hi - lo) / 3.0);
        if at(m1)? <= at(m2)? {
            hi = m2;
        } else {
            lo = m1;
        }
    }
    Some(Between {
        least_m: at(0.5 * (lo + hi))?.min(ends_m),
        ends_m,
    })
}

/// Drones whose flight ended in a crash (the simulator's `crashed` state in the log).
pub fn crashes(tracks: &Tracks) -> usize {
    tracks
        .drones()
        .iter()
        .filter(|d| d.samples.iter().any(|s| s.crashed))
        .count()
}

/// Least 3-D distance between airborne drones, and the time-matched pairs that touched.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Separation {
    pub min_m: Option<f64>,
    pub collisions: usize,
}

pub fn separation(tracks: &Tracks, params: &EvalParams) -> Separation {
    let mut out = Separation {
        min_m: None,
        collisions: 0,
    };
    let drones = tracks.drones();
    for (i, a) in drones.iter().enumerate() {
        for b in drones.iter().skip(i + 1) {
            for s in a.samples.iter().filter(|s| a.airborne(s)) {
                let Some(o) = b
                    .at(s.t_s, params.pair_tolerance_s)
                    .filter(|o| b.airborne(o))
                else {
                    continue;
                };
                let d = Vec3::new(s.x_m - o.x_m, s.y_m - o.y_m, s.z_m - o.z_m).norm();
                out.min_m = Some(out.min_m.map_or(d, |m| m.min(d)));
                if d < params.collision_separation_m {
                    out.collisions += 1;
                }
            }
        }
    }
    out
}
