//! The figure and page of several runs (`kestrel report --runs DIR`, thesis Fig. 5.23).
//!
//! In: the [`Group`]s of the runs, optionally the thesis's rows. Out: two panels side by side,
//! time and area known against the number of drones; per series a line through the means,
//! filled dots, and a bar from the least to the largest run; the thesis's rows of the same world
//! beside in the same colour, hollow dots, bars of ± one standard deviation, shifted right a
//! little. And the page: the figure, the table of groups and the files read.

use super::figures::{plot_err, FAMILY};
use super::html::{escape, linked, STYLE};
use super::palette;
use super::runs::{Group, Run, ThesisRow};
use super::ReportError;
use plotters::coord::Shift;
use plotters::prelude::*;
use std::fmt::Write;
use std::path::Path;

/// Size of the figure (px).
pub const SIZE_PX: (u32, u32) = (1200, 480);
/// How far right the thesis's dots sit from ours (drones).
const THESIS_SHIFT: f64 = 0.12;
/// Half the width of a bar's caps (px).
const CAP_PX: i32 = 4;

/// Series names in first-seen order (the groups come sorted by series).
fn series(groups: &[Group]) -> Vec<&str> {
    let mut out: Vec<&str> = Vec::new();
    for g in groups {
        if !out.contains(&g.series.as_str()) {
            out.push(&g.series);
        }
    }
    out
}

/// One mark: x, mean, low and high end of its bar.
type Mark = (f64, f64, f64, f64);

pub fn draw<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    groups: &[Group],
    thesis: &[ThesisRow],
) -> Result<(), ReportError> {
    let panels = root.split_evenly((1, 2));
    let names = series(groups);
    let ours = |pick: fn(&Group) -> super::runs::Spread| {
        names
            .iter()
            .map(|s| {
                groups
                    .iter()
                    .filter(|g| g.series == *s)
                    .map(|g| {
                        let v = pick(g);
                        (g.drones as f64, v.mean, v.min, v.max)
                    })
                    .collect::<Vec<Mark>>()
            })
            .collect::<Vec<_>>()
    };
    let theirs = |pick: fn(&ThesisRow) -> (f64, f64)| {
        names
            .iter()
            .map(|s| {
                thesis
                    .iter()
                    .filter(|r| r.world == *s)
                    .map(|r| {
                        let (mean, sd) = pick(r);
                        (r.drones as f64 + THESIS_SHIFT, mean, mean - sd, mean + sd)
                    })
                    .collect::<Vec<Mark>>()
            })
            .collect::<Vec<_>>()
    };
    let [time_panel, area_panel] = panels.as_slice() else {
        return Err(ReportError::Plot("splitting the runs figure".into()));
    };
    panel(
        time_panel,
        "Time to explore against drones",
        "time, first take-off to last landing (s)",
        &names,
        &ours(|g| g.time_s),
        &theirs(|r| (r.time_s, r.time_sd)),
    )?;
    panel(
        area_panel,
        "Area known against drones",
        "area known (% of the world)",
        &names,
        &ours(|g| g.area_pct),
        &theirs(|r| (r.area_pct, r.area_sd)),
    )
}

/// One panel: per series, our marks and the thesis's.
fn panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    caption: &str,
    y_desc: &str,
    names: &[&str],
    ours: &[Vec<Mark>],
    theirs: &[Vec<Mark>],
) -> Result<(), ReportError> {
    let all = ours.iter().chain(theirs).flatten();
    let max_x = all.clone().map(|m| m.0).fold(1.0, f64::max);
    let (lo, hi) = all.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), m| {
        (lo.min(m.2), hi.max(m.3))
    });
    let (lo, hi) = if lo <= hi { (lo, hi) } else { (0.0, 1.0) };
    let pad = 0.08 * (hi - lo).max(1e-3 * hi.abs()).max(1e-6);
    let mut chart = ChartBuilder::on(area)
        .caption(caption, (FAMILY, 18))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(0.5..max_x.floor() + 0.5, (lo - pad)..(hi + pad))
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("drones")
        .y_desc(y_desc)
        .x_labels(max_x as usize + 1)
        .x_label_formatter(&|x| format!("{x:.0}"))
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    for (i, name) in names.iter().enumerate() {
        let colour = palette::drone(i);
        let empty: Vec<Mark> = Vec::new();
        for (marks, thesis) in [
            (ours.get(i).unwrap_or(&empty), false),
            (theirs.get(i).unwrap_or(&empty), true),
        ] {
            if marks.is_empty() {
                continue;
            }
            let width = if thesis { 1 } else { 2 };
            let line = chart
                .draw_series(LineSeries::new(
                    marks.iter().map(|m| (m.0, m.1)),
                    colour.stroke_width(width),
                ))
                .map_err(plot_err)?;
            let label = if thesis {
                format!("{name} (thesis, ± sd)")
            } else {
                format!("{name} (min–max)")
            };
            line.label(label).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], colour.stroke_width(width))
            });
            // Each mark's bar: a vertical line from its low to its high end, with caps.
            let style = colour.stroke_width(1);
            chart
                .draw_series(
                    marks
                        .iter()
                        .map(|m| PathElement::new(vec![(m.0, m.2), (m.0, m.3)], style)),
                )
                .map_err(plot_err)?;
            let caps = marks.iter().flat_map(|m| [(m.0, m.2), (m.0, m.3)]);
            chart
                .draw_series(caps.map(|at| {
                    EmptyElement::at(at) + PathElement::new(vec![(-CAP_PX, 0), (CAP_PX, 0)], style)
                }))
                .map_err(plot_err)?;
            let dot = if thesis {
                colour.stroke_width(2)
            } else {
                colour.filled()
            };
            chart
                .draw_series(marks.iter().map(|m| Circle::new((m.0, m.1), 4, dot)))
                .map_err(plot_err)?;
        }
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

/// The page of the runs: figure, table of groups, files read.
pub fn page(dir: &Path, runs: &[Run], groups: &[Group], with_thesis: bool) -> String {
    let mut h = String::new();
    let title = format!("Exploration runs: {}", escape(&dir.display().to_string()));
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\"><title>{title}</title>\
         <style>{STYLE}</style></head><body>\n<h1>{title}</h1>\n<p>{} run(s) in {} group(s) \
         (world, and allocator when not Kestrel's, by number of drones).</p>\n<figure>{}\
         <figcaption>Time and area known against the number of drones: mean (dot and line) and \
         range over the runs (bar){}. Click for the PNG.</figcaption></figure>\n",
        runs.len(),
        groups.len(),
        linked("runs", SIZE_PX),
        if with_thesis {
            "; the thesis's means with ± one standard deviation beside (hollow dots)"
        } else {
            ""
        },
    );
    h.push_str(
        "<table><tr><th>series</th><th>drones</th><th>runs</th><th>time mean ± sd (s)</th>\
         <th>time min–max (s)</th><th>area mean ± sd (%)</th><th>area min–max (%)</th></tr>\n",
    );
    for g in groups {
        let (t, a) = (g.time_s, g.area_pct);
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{}</td><td>{}</td><td>{:.1} ± {:.1}</td><td>{:.1}–{:.1}</td>\
             <td>{:.2} ± {:.2}</td><td>{:.2}–{:.2}</td></tr>",
            escape(&g.series),
            g.drones,
            g.runs,
            t.mean,
            t.sd,
            t.min,
            t.max,
            a.mean,
            a.sd,
            a.min,
            a.max
        );
    }
    h.push_str(
        "</table>\n<p><small>Time: first take-off to last landing. Area: known cells / all \
         cells of the 0.1 m evaluation grid, judged by the evaluator of <code>kestrel \
         evaluate</code>. Data: <a href=\"runs.csv\">runs.csv</a>.</small></p>\n<h2>Runs</h2>\n<ul>\n",
    );
    for r in runs {
        let _ = writeln!(
            h,
            "<li>{}: {}, {} drone(s), {:.1} s, {:.2} %</li>",
            escape(&r.file.display().to_string()),
            escape(&r.series),
            r.drones,
            r.time_s,
            r.area_pct
        );
    }
    h.push_str("</ul>\n</body></html>\n");
    h
}
