//! Exploration metrics recomputed from a flight log and the true world, as an outside judge
//! would: nothing here reads Kestrel's own maps.
//!
//! In: the [`World`] flown and the pose samples of a flight log ([`poses_from_log`]), plus
//! [`EvalParams`] (thesis defaults: 0.1 m grid over `bounds_m`, four body-fixed beams of 4 m).
//! Out: [`ExplorationMetrics`]: time from first take-off to last landing, area known (thesis
//! definition, after a 3x3 closing, and as a share of what is observable), paths (Euclidean and
//! the thesis's L1), overlap, per-drone shares, clearances, collisions, the area curve, the
//! rotation-independent lower bound on time (exploration-research §3.2) and the times to reach
//! 90/95/99 % of the final area; [`evaluate_with_map`] adds the final known cells ([`KnownMap`], for
//! plots).
//!
//! Collisions are airborne samples within the body radius of an obstacle, flights between
//! two samples that came that close, drones closer than the collision separation, and flights
//! the simulator ended in a crash.
//!
//! Each airborne sample casts the four beams at the true obstacles (exact ray-shape hits, found
//! through [`ShapeIndex`]); every grid cell a beam crosses up to its hit or its range, and the
//! hit cell, becomes known to that drone.

mod coverage;
pub mod limits;
mod log;
mod motion;
mod observable;
mod raster;

pub use log::{poses_from_log, poses_from_logs, start_unix_s, MergeError};

use crate::sim::spatial::ShapeIndex;
use crate::sim::world::World;
use limits::{FlightLimits, Flown};
use raster::Raster;
use serde::Serialize;

/// The true world a run is judged against (a world file's obstacles and bounds), as those who
/// only hand it to the evaluator name it.
pub type TrueWorld = World;

/// One pose of one drone, as logged (ENU m, rad, log seconds).
#[derive(Debug, Clone, PartialEq)]
pub struct PoseSample {
    pub t_s: f64,
    pub drone: String,
    pub x_m: f64,
    pub y_m: f64,
    pub z_m: f64,
    pub yaw_rad: f64,
    /// The vehicle reported a crash (`flight: crashed`: the simulator ended a flight that
    /// touched something).
    pub crashed: bool,
}

/// How the evaluation senses and judges; defaults are the thesis's (exploration-research §4.2).
#[derive(Debug, Clone, PartialEq)]
pub struct EvalParams {
    /// Grid cell side over the world's `bounds_m` (m).
    pub cell_m: f64,
    /// Beam range (m); a beam with no return marks cells up to here.
    pub beam_range_m: f64,
    /// Returns nearer than this are not reported by the sensor (m).
    pub min_range_m: f64,
    /// A drone senses, and counts as flying, only above this height (m).
    pub airborne_z_m: f64,
    /// Cruise speed of the lower bound on time (m/s).
    pub speed_mps: f64,
    /// Clearance of the free space the observable set is seen from (m), the planners' 0.4 m.
    pub free_clearance_m: f64,
    /// Height the observable set is computed at (m); obstacles lower than this do not block.
    pub altitude_m: f64,
    /// Angle between the rays of the observable-set test (deg).
    pub view_step_deg: f64,
    /// Drone body radius: an airborne sample closer than this to an obstacle is a collision (m).
    pub body_radius_m: f64,
    /// Two airborne drones closer than this are a collision (m).
    pub collision_separation_m: f64,
    /// Samples of two drones at most this far apart in time are compared for separation (s).
    pub pair_tolerance_s: f64,
    /// Spacing of the points of the area curve (s of log time).
    pub curve_step_s: f64,
    /// What the run is judged against (the thesis's limits by default).
    pub limits: FlightLimits,
}

impl Default for EvalParams {
    fn default() -> Self {
        Self {
            cell_m: 0.1,
            beam_range_m: 4.0,
            min_range_m: 0.04,
            airborne_z_m: 0.3,
            speed_mps: 0.75,
            free_clearance_m: 0.4,
            altitude_m: 1.0,
            view_step_deg: 1.0,
            body_radius_m: 0.1,
            collision_separation_m: 0.2,
            pair_tolerance_s: 0.06,
            curve_step_s: 10.0,
            limits: FlightLimits::default(),
        }
    }
}

#[derive(Debug, thiserror::Error)]
pub enum EvalError {
    #[error("log line {line} is longer than {max_bytes} bytes")]
    LineTooLong { line: usize, max_bytes: usize },
    #[error("log line {line} is not valid JSON: {source}")]
    Json {
        line: usize,
        source: serde_json::Error,
    },
    #[error("log line {line} is a pose record without numeric {field}")]
    PoseField { line: usize, field: &'static str },
    #[error("no drone is ever above {0} m in the log")]
    NeverAirborne(f64),
    #[error("evaluation parameter {0} is out of range")]
    Param(&'static str),
    #[error("the grid over the world's bounds would have {0} cells, more than 100 million")]
    GridTooLarge(u64),
}

/// Metrics of one drone.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DroneMetrics {
    pub drone: String,
    /// Cells this drone knows / all grid cells x 100.
    pub area_pct: f64,
    /// Horizontal Euclidean path over all its samples (m).
    pub path_m: f64,
    /// Horizontal L1 path, sum of |dx| + |dy| (m), as the thesis measured it.
    pub path_l1_m: f64,
    pub samples: usize,
}

/// One point of the area curve.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct CurvePoint {
    /// Log time (s).
    pub t_s: f64,
    pub area_pct: f64,
}

/// Time from the first take-off to reaching a share of the final area.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct TimeToPct {
    /// Share of the final `area_pct` (%).
    pub pct_of_final: f64,
    /// Seconds after the first take-off.
    pub time_s: f64,
}

#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ExplorationMetrics {
    /// From the first airborne sample of any drone to the last one (s).
    pub time_s: f64,
    pub first_takeoff_s: f64,
    pub last_landing_s: f64,
    /// Drones with at least one airborne sample.
    pub drones_flown: usize,
    pub grid_cells: usize,
    pub known_cells: usize,
    /// Known cells / all grid cells x 100 (thesis definition; pole interiors count as unknown).
    pub area_pct: f64,
    /// The same after a 3x3 morphological closing of the known mask (the thesis's map filter).
    pub area_closed_pct: f64,
    /// Known observable cells / observable cells x 100.
    pub observable_pct: f64,
    pub observable_cells: usize,
    /// Observable cells / all grid cells x 100: the ceiling of `area_pct`.
    pub observable_share_pct: f64,
    /// Sum over drones of the horizontal Euclidean path (m).
    pub path_m: f64,
    /// Sum over drones of the horizontal L1 path (m).
    pub path_l1_m: f64,
    /// Cells known by exactly two drones / all grid cells x 100 (thesis definition).
    pub overlap_pct: f64,
    /// Cells known by two drones or more / known cells x 100.
    pub multi_observed_pct: f64,
    pub drones: Vec<DroneMetrics>,
    /// Least distance from an airborne sample to an obstacle surface (m); none without obstacles.
    pub min_obstacle_clearance_m: Option<f64>,
    /// Least 3-D distance between two airborne drones at the same time (m); none for one drone.
    pub min_separation_m: Option<f64>,
    /// `obstacle_collision_samples + drone_collision_pairs + crashes`.
    pub collisions: usize,
    /// Airborne samples closer than the body radius to an obstacle, plus flights between two
    /// samples that came that close (a contact between samples).
    pub obstacle_collision_samples: usize,
    /// Drones whose flight ended in a crash (`flight: crashed` in the log).
    pub crashes: usize,
    /// Time-matched pairs of airborne drones closer than the collision separation.
    pub drone_collision_pairs: usize,
    pub area_curve: Vec<CurvePoint>,
    /// (A - N pi R^2) / (2 R v N) with A the area known (m^2); exploration-research §3.2.
    pub lower_bound_s: f64,
    /// `time_s / lower_bound_s`, when the bound is positive.
    pub time_over_bound: Option<f64>,
    /// Times to 90, 95 and 99 % of the final `area_pct`.
    pub time_to_pct: Vec<TimeToPct>,
    /// Speed, yaw rate, height, clearance and separation flown against the limits; a run that
    /// broke one failed, whatever it explored.
    pub flown: Flown,
}

/// Shares of the final area `time_to_pct` reports (%).
const TIME_TO_PCTS: [f64; 3] = [90.0, 95.0, 99.0];

/// The cells known by any drone at the end, on the evaluation grid (for plots).
#[derive(Debug, Clone, PartialEq)]
pub struct KnownMap {
    /// South-west corner of cell (0, 0) (ENU m).
    pub min_x_m: f64,
    pub min_y_m: f64,
    pub cell_m: f64,
    pub nx: usize,
    pub ny: usize,
    /// Row-major from the south-west corner: `known[iy * nx + ix]`.
    pub known: Vec<bool>,
    /// Indices into `known` in the order the cells became known (to any drone).
    pub order: Vec<u32>,
    /// (log time, cells known) after every sample that added a cell: `order[..n]` were the
    /// cells known from that time on (until the next entry).
    pub growth: Vec<(f64, usize)>,
}

/// Evaluates a flight against the true world. `samples` may come in any order.
pub fn evaluate(
    world: &World,
    samples: &[PoseSample],
    params: &EvalParams,
) -> Result<ExplorationMetrics, EvalError> {
    evaluate_with_map(world, samples, params).map(|(metrics, _)| metrics)
}

/// [`evaluate`], plus the final known cells.
pub fn evaluate_with_map(
    world: &World,
    samples: &[PoseSample],
    params: &EvalParams,
) -> Result<(ExplorationMetrics, KnownMap), EvalError> {
    check(params)?;
    let raster = Raster::over(&world.bounds_m, params.cell_m)?;
    let index = ShapeIndex::new(world.shapes());
    let tracks = motion::Tracks::new(samples, params.airborne_z_m);
    let (first_takeoff_s, last_landing_s) = tracks
        .airborne_window()
        .ok_or(EvalError::NeverAirborne(params.airborne_z_m))?;
    let known = coverage::cast(&raster, &index, &tracks, params);
    let cells = raster.cells();
    let pct = |n: usize| 100.0 * n as f64 / cells as f64;
    let union = known.union();
    let observable = observable::observable(&raster, &index, &tracks.start_points(), params);
    let observable_cells = observable.count();
    let counts = known.counts_per_cell();
    let exactly_two = counts.iter().filter(|&&c| c == 2).count();
    let several = counts.iter().filter(|&&c| c >= 2).count();
    let known_cells = union.count();
    let area_pct = pct(known_cells);
    let separation = motion::separation(&tracks, params);
    let clearance = motion::clearance(&index, &tracks, params);
    let crashes = motion::crashes(&tracks);
    let drones: Vec<DroneMetrics> = tracks
        .drones()
        .iter()
        .zip(known.per_drone())
        .map(|(track, set)| DroneMetrics {
            drone: track.id.clone(),
            area_pct: pct(set.count()),
            path_m: track.path_m(),
            path_l1_m: track.path_l1_m(),
            samples: track.samples.len(),
        })
        .collect();
    let drones_flown = tracks.drones_flown();
    let time_s = last_landing_s - first_takeoff_s;
    let lower_bound_s = lower_bound_s(
        area_pct / 100.0 * raster.area_m2(),
        drones_flown,
        params.beam_range_m,
        params.speed_mps,
    );
    let final_cells = known_cells as f64;
    let map = KnownMap {
        min_x_m: raster.min_x,
        min_y_m: raster.min_y,
        cell_m: raster.cell_m,
        nx: raster.nx,
        ny: raster.ny,
        known: (0..cells).map(|i| union.contains(i)).collect(),
        order: known.order().to_vec(),
        growth: known.growth().to_vec(),
    };
    let metrics = ExplorationMetrics {
        time_s,
        first_takeoff_s,
        last_landing_s,
        drones_flown,
        grid_cells: cells,
        known_cells,
        area_pct,
        area_closed_pct: pct(raster.closed(&union).count()),
        observable_pct: 100.0 * union.intersection_count(&observable) as f64
            / observable_cells.max(1) as f64,
        observable_cells,
        observable_share_pct: pct(observable_cells),
        path_m: drones.iter().map(|d| d.path_m).sum(),
        path_l1_m: drones.iter().map(|d| d.path_l1_m).sum(),
        overlap_pct: pct(exactly_two),
        multi_observed_pct: 100.0 * several as f64 / known_cells.max(1) as f64,
        drones,
        min_obstacle_clearance_m: clearance.min_m,
        min_separation_m: separation.min_m,
        collisions: clearance.collisions + separation.collisions + crashes,
        obstacle_collision_samples: clearance.collisions,
        crashes,
        drone_collision_pairs: separation.collisions,
        area_curve: known
            .curve(params.curve_step_s)
            .into_iter()
            .map(|(t_s, n)| CurvePoint {
                t_s,
                area_pct: pct(n),
            })
            .collect(),
        flown: limits::judge(
            &tracks,
            params.airborne_z_m,
            clearance.min_m,
            separation.min_m,
            &params.limits,
        ),
        lower_bound_s,
        time_over_bound: (lower_bound_s > 0.0).then(|| time_s / lower_bound_s),
        time_to_pct: TIME_TO_PCTS
            .iter()
            .filter_map(|&p| {
                known
                    .first_time_reaching((p / 100.0 * final_cells).ceil() as usize)
                    .map(|t| TimeToPct {
                        pct_of_final: p,
                        time_s: t - first_takeoff_s,
                    })
            })
            .collect(),
    };
    Ok((metrics, map))
}

/// The rotation-independent bound T >= (A - N pi R^2) / (2 R v N), never below zero.
pub fn lower_bound_s(area_m2: f64, drones: usize, range_m: f64, speed_mps: f64) -> f64 {
    if drones == 0 {
        return 0.0;
    }
    let n = drones as f64;
    ((area_m2 - n * std::f64::consts::PI * range_m * range_m) / (2.0 * range_m * speed_mps * n))
        .max(0.0)
}

fn check(p: &EvalParams) -> Result<(), EvalError> {
    let positive = |v: f64| v.is_finite() && v > 0.0;
    let rules: [(bool, &'static str); 11] = [
        ((0.01..=10.0).contains(&p.cell_m), "cell_m"),
        ((0.1..=100.0).contains(&p.beam_range_m), "beam_range_m"),
        (
            p.min_range_m >= 0.0 && p.min_range_m < p.beam_range_m,
            "min_range_m",
        ),
        (p.airborne_z_m.is_finite(), "airborne_z_m"),
        (positive(p.speed_mps), "speed_mps"),
        (
            (0.0..=10.0).contains(&p.free_clearance_m),
            "free_clearance_m",
        ),
        (p.altitude_m.is_finite(), "altitude_m"),
        ((0.05..=45.0).contains(&p.view_step_deg), "view_step_deg"),
        (
            p.body_radius_m >= 0.0 && p.collision_separation_m >= 0.0,
            "body_radius_m / collision_separation_m",
        ),
        (
            (0.0..=10.0).contains(&p.pair_tolerance_s),
            "pair_tolerance_s",
        ),
        ((0.1..=3600.0).contains(&p.curve_step_s), "curve_step_s"),
    ];
    match rules.iter().find(|(ok, _)| !ok) {
        Some((_, name)) => Err(EvalError::Param(name)),
        None => p.limits.check().map_err(EvalError::Param),
    }
}

#[cfg(test)]
mod tests;
