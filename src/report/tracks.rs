//! The figures drawn from the drones' tracks: top-down trajectories, altitude over distance
//! flown, and the explored map.
//!
//! In: the read [`Flight`] (and for the map the evaluator's [`KnownMap`] and the [`World`]).
//! Out: drawings on a plotters area. Tracks are thinned to at most [`MAX_TRACK_POINTS`] per
//! drone (every behavior change kept); the map is drawn in blocks of at most
//! [`MAX_MAP_BLOCKS`] a side, merged into one rectangle per run of known blocks in a row.

use super::figures::{plot_err, FAMILY};
use super::palette;
use super::read::{Flight, Pose};
use super::ReportError;
use crate::exploration::offline::evaluate::KnownMap;
use crate::sim::world::World;
use plotters::coord::types::RangedCoordf64;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::collections::BTreeSet;

pub const MAX_TRACK_POINTS: usize = 4000;
pub const MAX_MAP_BLOCKS: usize = 250;

/// A drone's poses thinned, then cut where the active behavior changes: the indices of each
/// run, which ends on the next run's first pose so the line stays joined.
fn runs(poses: &[Pose]) -> Vec<(Option<&str>, Vec<usize>)> {
    let stride = poses.len().div_ceil(MAX_TRACK_POINTS).max(1);
    let mut out: Vec<(Option<&str>, Vec<usize>)> = Vec::new();
    for (i, p) in poses.iter().enumerate() {
        let behavior = p.behavior.as_deref();
        match out.last_mut() {
            Some((b, run)) if *b == behavior => {
                if i % stride == 0 || i + 1 == poses.len() {
                    run.push(i);
                }
            }
            last => {
                if let Some((_, run)) = last {
                    run.push(i);
                }
                out.push((behavior, vec![i]));
            }
        }
    }
    out
}

fn behaviors(flight: &Flight) -> BTreeSet<Option<&str>> {
    flight
        .drones
        .values()
        .flat_map(|d| d.poses.iter().map(|p| p.behavior.as_deref()))
        .collect()
}

/// Axis ranges around `points` with a margin, widened so one metre is as long on both axes.
fn square_ranges(
    points: impl Iterator<Item = (f64, f64)>,
    plot_px: (f64, f64),
) -> ((f64, f64), (f64, f64)) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for (x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return ((-1.0, 1.0), (-1.0, 1.0));
    }
    let pad = 0.05 * (x1 - x0).max(y1 - y0) + 1.0;
    let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
    let (mut hw, mut hh) = ((x1 - x0) / 2.0 + pad, (y1 - y0) / 2.0 + pad);
    let per_px = (2.0 * hw / plot_px.0).max(2.0 * hh / plot_px.1);
    hw = per_px * plot_px.0 / 2.0;
    hh = per_px * plot_px.1 / 2.0;
    ((cx - hw, cx + hw), (cy - hh, cy + hh))
}

fn plot_px<DB: DrawingBackend>(root: &DrawingArea<DB, Shift>) -> (f64, f64) {
    let (w, h) = root.dim_in_pixel();
    (
        (f64::from(w) - 90.0).max(10.0),
        (f64::from(h) - 100.0).max(10.0),
    )
}

type Chart<'a, DB> = ChartContext<'a, DB, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

fn legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    entries: impl Iterator<Item = (String, RGBColor)>,
) -> Result<(), ReportError> {
    for (name, colour) in entries {
        chart
            .draw_series(std::iter::empty::<Circle<(f64, f64), i32>>())
            .map_err(plot_err)?
            .label(name)
            .legend(move |(x, y)| Rectangle::new([(x, y - 5), (x + 15, y + 5)], colour.filled()));
    }
    chart
        .configure_series_labels()
        .label_font((FAMILY, 13))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .position(SeriesLabelPosition::UpperRight)
        .draw()
        .map_err(plot_err)
}

fn behavior_legend<'a, DB: DrawingBackend + 'a>(
    chart: &mut Chart<'a, DB>,
    flight: &Flight,
) -> Result<(), ReportError> {
    legend(
        chart,
        behaviors(flight)
            .into_iter()
            .map(|b| (b.unwrap_or("(none)").to_string(), palette::behavior(b))),
    )
}

pub fn trajectory<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    flight: &Flight,
) -> Result<(), ReportError> {
    let all = flight
        .drones
        .values()
        .flat_map(|d| d.poses.iter().map(|p| (p.x_m, p.y_m)));
    let ((x0, x1), (y0, y1)) = square_ranges(all, plot_px(root));
    let mut chart = ChartBuilder::on(root)
        .caption("Trajectories (top view, by motion behavior)", (FAMILY, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("east (m)")
        .y_desc("north (m)")
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    for (drone, log) in &flight.drones {
        for (behavior, run) in runs(&log.poses) {
            let style = palette::behavior(behavior).stroke_width(2);
            chart
                .draw_series(LineSeries::new(
                    run.iter()
                        .filter_map(|&i| log.poses.get(i))
                        .map(|p| (p.x_m, p.y_m)),
                    style,
                ))
                .map_err(plot_err)?;
        }
        if let Some(p) = log.poses.first() {
            chart
                .draw_series(std::iter::once(Text::new(
                    drone.clone(),
                    (p.x_m, p.y_m),
                    (FAMILY, 12),
                )))
                .map_err(plot_err)?;
        }
    }
    behavior_legend(&mut chart, flight)
}

pub fn altitude<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    flight: &Flight,
) -> Result<(), ReportError> {
    // Distance flown (3-D, as in the table) at every pose, per drone.
    let distances: Vec<Vec<f64>> = flight
        .drones
        .values()
        .map(|d| {
            let mut s = 0.0;
            let mut out = Vec::with_capacity(d.poses.len());
            let mut prev: Option<&Pose> = None;
            for p in &d.poses {
                if let Some(a) = prev {
                    let v = [p.x_m - a.x_m, p.y_m - a.y_m, p.z_m - a.z_m];
                    s += v.iter().map(|c| c * c).sum::<f64>().sqrt();
                }
                out.push(s);
                prev = Some(p);
            }
            out
        })
        .collect();
    let max_d = distances
        .iter()
        .filter_map(|d| d.last())
        .fold(1.0, |a: f64, b| a.max(*b));
    let zs = flight
        .drones
        .values()
        .flat_map(|d| d.poses.iter().map(|p| p.z_m));
    let (z0, z1) = zs.fold((0.0f64, 1.0f64), |(lo, hi), z| (lo.min(z), hi.max(z)));
    let mut chart = ChartBuilder::on(root)
        .caption("Altitude over distance flown", (FAMILY, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0.0..max_d, z0..(z1 + 0.1 * (z1 - z0)))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("distance flown (m)")
        .y_desc("altitude, ENU z (m)")
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    for (log, dist) in flight.drones.values().zip(&distances) {
        for (behavior, run) in runs(&log.poses) {
            let points = run
                .iter()
                .filter_map(|&i| Some((*dist.get(i)?, log.poses.get(i)?.z_m)));
            chart
                .draw_series(LineSeries::new(
                    points,
                    palette::behavior(behavior).stroke_width(2),
                ))
                .map_err(plot_err)?;
        }
    }
    behavior_legend(&mut chart, flight)
}

/// The known cells, the obstacles, the tracks up to `until_s` (all of them when `None`) and
/// each drone's start as a diamond of its colour.
pub fn explored<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    flight: &Flight,
    map: &KnownMap,
    world: &World,
    until_s: Option<f64>,
) -> Result<(), ReportError> {
    let b = &world.bounds_m;
    let corners = [(b.x[0], b.y[0]), (b.x[1], b.y[1])];
    let ((x0, x1), (y0, y1)) = square_ranges(corners.into_iter(), plot_px(root));
    let caption = match until_s {
        Some(t) => format!("Explored by t = {t:.0} s, obstacles and tracks"),
        None => "Explored area, obstacles and tracks".to_string(),
    };
    let mut chart = ChartBuilder::on(root)
        .caption(caption, (FAMILY, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .disable_mesh()
        .x_desc("east (m)")
        .y_desc("north (m)")
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(std::iter::once(Rectangle::new(
            [(b.x[0], b.y[0]), (b.x[1], b.y[1])],
            RGBColor(0xE0, 0xE0, 0xE0).filled(),
        )))
        .map_err(plot_err)?;
    chart.draw_series(known_blocks(map)).map_err(plot_err)?;
    let obstacle = BLACK.filled();
    chart
        .draw_series(
            world
                .poles_xy_m
                .iter()
                .map(|p| (p[0], p[1], world.pole_radius_m))
                .chain(
                    world
                        .cylinders
                        .iter()
                        .map(|c| (c.xy_m[0], c.xy_m[1], c.radius_m)),
                )
                .map(|(x, y, r)| {
                    Polygon::new(
                        (0..16)
                            .map(|k| {
                                let a = f64::from(k) * std::f64::consts::TAU / 16.0;
                                (x + r * a.cos(), y + r * a.sin())
                            })
                            .collect::<Vec<_>>(),
                        obstacle,
                    )
                }),
        )
        .map_err(plot_err)?;
    chart
        .draw_series(world.boxes.iter().map(|bx| {
            let (c, s) = (bx.yaw_rad.cos(), bx.yaw_rad.sin());
            let (hx, hy) = (bx.size_xy_m[0] / 2.0, bx.size_xy_m[1] / 2.0);
            let corners = [(-hx, -hy), (hx, -hy), (hx, hy), (-hx, hy)].map(|(u, v)| {
                (
                    bx.center_xy_m[0] + c * u - s * v,
                    bx.center_xy_m[1] + s * u + c * v,
                )
            });
            Polygon::new(corners.to_vec(), obstacle)
        }))
        .map_err(plot_err)?;
    let end_s = until_s.unwrap_or(f64::INFINITY);
    for (i, log) in flight.drones.values().enumerate() {
        let flown = log.poses.partition_point(|p| p.t_s <= end_s);
        let poses = log.poses.get(..flown).unwrap_or_default();
        let stride = poses.len().div_ceil(MAX_TRACK_POINTS).max(1);
        chart
            .draw_series(LineSeries::new(
                poses.iter().step_by(stride).map(|p| (p.x_m, p.y_m)),
                palette::drone(i).stroke_width(2),
            ))
            .map_err(plot_err)?;
    }
    // Each drone's start: a diamond of its colour, outlined in black.
    let r = START_PX;
    let corners = vec![(0, -r), (r, 0), (0, r), (-r, 0), (0, -r)];
    let starts = flight.drones.values().enumerate().filter_map(|(i, log)| {
        let start = log.poses.first()?;
        Some(((start.x_m, start.y_m), palette::drone(i)))
    });
    chart
        .draw_series(starts.map(|(at, colour)| {
            EmptyElement::at(at)
                + Polygon::new(corners.clone(), colour.filled())
                + PathElement::new(corners.clone(), BLACK.stroke_width(1))
        }))
        .map_err(plot_err)?;
    let mut entries = vec![("known".to_string(), KNOWN)];
    entries.extend(
        flight
            .drones
            .keys()
            .enumerate()
            .map(|(i, d)| (d.clone(), palette::drone(i))),
    );
    legend(&mut chart, entries.into_iter())
}

/// Half the diagonal of a start diamond (px).
const START_PX: i32 = 7;

const KNOWN: RGBColor = RGBColor(0xB8, 0xDC, 0xF5);

/// One rectangle per run of known blocks in a row; a block is known when half its cells are.
fn known_blocks(map: &KnownMap) -> Vec<Rectangle<(f64, f64)>> {
    let side = map.nx.max(map.ny).div_ceil(MAX_MAP_BLOCKS).max(1);
    let (bx, by) = (map.nx.div_ceil(side), map.ny.div_ceil(side));
    let block_known = |i: usize, j: usize| {
        let (mut n, mut k) = (0usize, 0usize);
        for iy in j * side..((j + 1) * side).min(map.ny) {
            for ix in i * side..((i + 1) * side).min(map.nx) {
                n += 1;
                if map.known.get(iy * map.nx + ix).copied().unwrap_or(false) {
                    k += 1;
                }
            }
        }
        2 * k >= n.max(1)
    };
    let step = side as f64 * map.cell_m;
    let mut out = Vec::new();
    for j in 0..by {
        let mut start: Option<usize> = None;
        for i in 0..=bx {
            let known = i < bx && block_known(i, j);
            match (known, start) {
                (true, None) => start = Some(i),
                (false, Some(s)) => {
                    let x = |k: usize| {
                        (map.min_x_m + k as f64 * step)
                            .min(map.min_x_m + map.nx as f64 * map.cell_m)
                    };
                    let y = |k: usize| {
                        (map.min_y_m + k as f64 * step)
                            .min(map.min_y_m + map.ny as f64 * map.cell_m)
                    };
                    out.push(Rectangle::new(
                        [(x(s), y(j)), (x(i), y(j + 1))],
                        KNOWN.filled(),
                    ));
                    start = None;
                }
                _ => {}
            }
        }
    }
    out
}
