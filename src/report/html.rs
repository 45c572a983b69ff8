//! The report page.
//!
//! In: a [`Report`] and its figures, each as an HTML fragment (an `<img>` of the files beside
//! the page, or an inline `<svg>`). Out: one HTML document: what the log is, the figures, the
//! per-drone table with the definitions of its columns, and the exploration metrics or why
//! there are none.

use super::{Exploration, Report};
use std::fmt::Write;

pub fn escape(s: &str) -> String {
    s.replace('&', "&amp;")
        .replace('<', "&lt;")
        .replace('>', "&gt;")
        .replace('"', "&quot;")
}

/// An `<img>` of `STEM.svg` linking its PNG.
pub fn linked(stem: &str, size_px: (u32, u32)) -> String {
    format!(
        "<a href=\"{stem}.png\"><img src=\"{stem}.svg\" width=\"{}\" height=\"{}\" alt=\"{stem}\"></a>",
        size_px.0, size_px.1
    )
}

pub const STYLE: &str = "body{font-family:sans-serif;margin:2em;max-width:1000px}\
table{border-collapse:collapse}td,th{border:1px solid #bbb;padding:3px 8px;text-align:right}\
th{background:#eee}td:first-child{text-align:left}figure{margin:1.5em 0}\
.note{background:#fff4d6;padding:.5em 1em}svg{max-width:100%;height:auto}";

fn opt(v: Option<f64>, digits: usize) -> String {
    v.map_or("–".into(), |v| format!("{v:.digits$}"))
}

pub fn page(report: &Report, figures: &[(String, String)], files: bool) -> String {
    let f = &report.flight;
    let header = |k: &str| {
        f.header
            .as_ref()
            .and_then(|h| h.get(k))
            .and_then(|v| v.as_str())
            .map_or("–".to_string(), escape)
    };
    let mut h = String::new();
    let _ = write!(
        h,
        "<!DOCTYPE html>\n<html lang=\"en\"><head><meta charset=\"utf-8\">\
         <title>Flight report: {name}</title><style>{STYLE}</style></head><body>\n\
         <h1>Flight report: {name}</h1>\n<p>Command <b>{cmd}</b>, started {start} (UTC), \
         {drones} drone(s), {poses} pose records, log time {end:.1} s.</p>\n",
        name = escape(&report.name),
        cmd = header("command"),
        start = header("start_time"),
        drones = f.drones.len(),
        poses = f.pose_count(),
        end = f.end_s,
    );
    if f.skipped_lines > 0 {
        let lines: Vec<String> = f.skipped_examples.iter().map(usize::to_string).collect();
        let _ = writeln!(
            h,
            "<p class=\"note\">{} malformed line(s) skipped (lines {}{}).</p>",
            f.skipped_lines,
            lines.join(", "),
            if f.skipped_lines > lines.len() {
                ", …"
            } else {
                ""
            }
        );
    }
    table(&mut h, report);
    exploration(&mut h, report);
    for (title, body) in figures {
        let _ = writeln!(
            h,
            "<figure>{body}<figcaption>{}</figcaption></figure>",
            escape(title)
        );
    }
    if files {
        h.push_str(
            "<p>Data: <a href=\"poses.csv\">poses.csv</a> (every pose record: t, drone, x, y, \
             z, yaw, vx, vy, vz, behavior, battery_fraction)",
        );
        if matches!(report.exploration, Exploration::Evaluated { .. }) {
            h.push_str(", <a href=\"area.csv\">area.csv</a> (the area curve)");
        }
        h.push_str(". Click a figure for its PNG.</p>\n");
    }
    h.push_str("</body></html>\n");
    h
}

fn table(h: &mut String, report: &Report) {
    h.push_str(
        "<h2>Drones</h2>\n<table><tr><th>drone</th><th>distance flown (m)</th>\
         <th>flight time (s)</th><th>battery used (%)</th><th>position error mean / max (m)</th>\
         <th>velocity error mean / max (m/s)</th><th>explored area (%)</th>\
         <th>time per behavior (s)</th></tr>\n",
    );
    let explored = |drone: &str| match &report.exploration {
        Exploration::Evaluated { metrics, .. } => metrics
            .drones
            .iter()
            .find(|d| d.drone == drone)
            .map(|d| d.area_pct),
        _ => None,
    };
    for (drone, s) in &report.stats {
        let err = |e: Option<super::stats::ErrorStats>| {
            e.map_or("–".into(), |e| {
                format!("{:.2} / {:.2} ({} samples)", e.mean, e.max, e.samples)
            })
        };
        let behaviors: Vec<String> = s
            .behavior_time_s
            .iter()
            .map(|(b, t)| format!("{} {t:.1}", escape(b)))
            .collect();
        let _ = writeln!(
            h,
            "<tr><td>{}</td><td>{:.1}</td><td>{:.1}</td><td>{}</td><td>{}</td><td>{}</td>\
             <td>{}</td><td>{}</td></tr>",
            escape(drone),
            s.distance_m,
            s.flight_time_s,
            opt(s.battery_used_fraction.map(|b| 100.0 * b), 1),
            err(s.position_error_m),
            err(s.velocity_error_mps),
            opt(explored(drone), 2),
            behaviors.join(", "),
        );
    }
    h.push_str(
        "</table>\n<p><small>Distance flown: the 3-D distance between consecutive pose records. \
         Flight time: the time after pose records whose flight status is taking off, flying or \
         landing. Battery used: the first minus the last known battery fraction. Position \
         error: |position setpoint − logged position| over the records where the controller \
         sent a position setpoint. Velocity error: |velocity setpoint − logged velocity| over \
         the airborne records where it sent a velocity setpoint (the velocity asked for in \
         that tick against the one the vehicle had then, so it includes the vehicle's \
         response lag). Explored area: the cells this drone's beams crossed / all cells of the \
         evaluation grid (exploration logs). Time per behavior: from each behavior's <code>started</code> event to \
         its <code>finished</code> (or the end of the log), summed.</small></p>\n",
    );
}

fn exploration(h: &mut String, report: &Report) {
    match &report.exploration {
        Exploration::None => {}
        Exploration::NoWorld(reason) => {
            let _ = writeln!(
                h,
                "<h2>Exploration</h2>\n<p class=\"note\">No explored-area map or area curve: \
                 {}. The trajectories are drawn without it.</p>",
                escape(reason)
            );
        }
        Exploration::Evaluated {
            world_path,
            metrics: m,
            ..
        } => {
            let _ = writeln!(
                h,
                "<h2>Exploration</h2>\n<p>Judged against the world {} by the evaluator of \
                 <code>kestrel evaluate</code> (four 4 m beams, 0.1 m grid): area known \
                 <b>{:.2} %</b> of the world ({:.2} % of what is observable), time {:.1} s \
                 (take-off {:.1} s to landing {:.1} s), path {:.1} m, overlap {:.2} %, \
                 collisions {}, least clearance {} m, least separation {} m.</p>",
                escape(&world_path.display().to_string()),
                m.area_pct,
                m.observable_pct,
                m.time_s,
                m.first_takeoff_s,
                m.last_landing_s,
                m.path_m,
                m.overlap_pct,
                m.collisions,
                opt(m.min_obstacle_clearance_m, 2),
                opt(m.min_separation_m, 2),
            );
        }
    }
}
