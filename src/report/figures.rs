//! The report's figures, drawn once for any plotters backend and rendered as SVG text or PNG.
//!
//! In: a [`Figure`] (what to draw, borrowing the read log) and a size in pixels. Out: an SVG
//! document or PNG bytes. The font is DejaVu Sans, embedded (assets/fonts, Bitstream Vera
//! licence), so nothing depends on the system's fonts.
//!
//! What the SVG carries, for readers that check it: in a timeline every bar is one filled
//! `<rect>` in its behavior's colour (`palette::behavior`) and nothing else there has that
//! fill; in the trajectory and altitude figures the tracks are `<polyline>`s stroked in the
//! active behavior's colour, and the legend's samples are filled rectangles.

use super::palette;
use super::read::{DroneLog, Flight};
use super::runs::{Group, ThesisRow};
use super::ReportError;
use super::{runs_figure, tracks};
use crate::exploration::offline::evaluate::{CurvePoint, KnownMap};
use crate::sim::world::World;
use plotters::coord::Shift;
use plotters::prelude::*;
use plotters::style::text_anchor::{HPos, Pos, VPos};
use std::sync::OnceLock;

/// DejaVu Sans cut to Latin, Greek and the usual symbols (`assets/fonts/README.md`).
const FONT: &[u8] = include_bytes!("../../assets/fonts/DejaVuSans-subset.ttf");
pub const FAMILY: &str = "sans-serif";

/// What to draw.
pub enum Figure<'a> {
    /// Behavior bars of one drone (thesis Figures 5.4, 5.12).
    Timeline { drone: &'a str, log: &'a DroneLog },
    /// Tracks seen from above, coloured by the active motion behavior (Figures 5.3, 5.13).
    Trajectory(&'a Flight),
    /// Altitude over distance flown, coloured the same way.
    Altitude(&'a Flight),
    /// The area known, the obstacles, the tracks and the starts (Figure 5.22): at the end, or
    /// with the tracks cut at `until_s` (a snapshot's map).
    Explored {
        flight: &'a Flight,
        map: &'a KnownMap,
        world: &'a World,
        until_s: Option<f64>,
    },
    /// Known area over time (Figure 5.24).
    AreaCurve(&'a [CurvePoint]),
    /// Time and area against the number of drones over several runs (Figure 5.23), the
    /// thesis's rows beside when given.
    Runs {
        groups: &'a [Group],
        thesis: &'a [ThesisRow],
    },
}

pub(super) fn plot_err(e: impl std::fmt::Display) -> ReportError {
    ReportError::Plot(e.to_string())
}

fn font() -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = REGISTERED
        .get_or_init(|| plotters::style::register_font(FAMILY, FontStyle::Normal, FONT).is_ok());
    if *ok {
        Ok(())
    } else {
        Err(ReportError::Plot("the embedded font does not load".into()))
    }
}

impl Figure<'_> {
    fn draw<DB: DrawingBackend>(&self, root: &DrawingArea<DB, Shift>) -> Result<(), ReportError> {
        root.fill(&WHITE).map_err(plot_err)?;
        match self {
            Figure::Timeline { drone, log } => timeline(root, drone, log),
            Figure::Trajectory(flight) => tracks::trajectory(root, flight),
            Figure::Altitude(flight) => tracks::altitude(root, flight),
            Figure::Explored {
                flight,
                map,
                world,
                until_s,
            } => tracks::explored(root, flight, map, world, *until_s),
            Figure::AreaCurve(curve) => area_curve(root, curve),
            Figure::Runs { groups, thesis } => runs_figure::draw(root, groups, thesis),
        }?;
        root.present().map_err(plot_err)
    }

    pub fn svg(&self, size_px: (u32, u32)) -> Result<String, ReportError> {
        font()?;
        let mut out = String::new();
        {
            let root = SVGBackend::with_string(&mut out, size_px).into_drawing_area();
            self.draw(&root)?;
        }
        Ok(out)
    }

    pub fn png(&self, size_px: (u32, u32)) -> Result<Vec<u8>, ReportError> {
        font()?;
        let (w, h) = size_px;
        let mut rgb = vec![0u8; w as usize * h as usize * 3];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, size_px).into_drawing_area();
            self.draw(&root)?;
        }
        let mut out = Vec::new();
        {
            let mut encoder = png::Encoder::new(&mut out, w, h);
            encoder.set_color(png::ColorType::Rgb);
            encoder.set_depth(png::BitDepth::Eight);
            let mut writer = encoder.write_header().map_err(plot_err)?;
            writer.write_image_data(&rgb).map_err(plot_err)?;
        }
        Ok(out)
    }
}

fn timeline<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    drone: &str,
    log: &DroneLog,
) -> Result<(), ReportError> {
    let mut rows: Vec<&str> = Vec::new();
    for a in &log.activations {
        if !rows.contains(&a.behavior.as_str()) {
            rows.push(&a.behavior);
        }
    }
    let end_s = log
        .activations
        .iter()
        .map(|a| a.end_s)
        .chain(log.poses.last().map(|p| p.t_s))
        .fold(1.0, f64::max);
    let n = rows.len().max(1) as f64;
    let mut chart = ChartBuilder::on(root)
        .caption(format!("Behaviors of {drone}"), (FAMILY, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(110)
        .build_cartesian_2d(0f64..end_s, 0f64..n)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .disable_y_mesh()
        .y_labels(0)
        .x_desc("time (s)")
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    // Row names right-aligned just left of the plot, at each row's middle.
    let name_style =
        TextStyle::from((FAMILY, 13).into_font()).pos(Pos::new(HPos::Right, VPos::Center));
    chart
        .draw_series(rows.iter().enumerate().map(|(i, name)| {
            Text::new(
                name.to_string(),
                (-end_s * 0.015, i as f64 + 0.5),
                name_style.clone(),
            )
        }))
        .map_err(plot_err)?;
    chart
        .draw_series(log.activations.iter().filter_map(|a| {
            let row = rows.iter().position(|r| *r == a.behavior)? as f64;
            let colour = palette::behavior(Some(&a.behavior));
            let mut bar = Rectangle::new([(a.start_s, row), (a.end_s, row + 1.0)], colour.filled());
            bar.set_margin(4, 4, 0, 0);
            Some(bar)
        }))
        .map_err(plot_err)?;
    Ok(())
}

fn area_curve<DB: DrawingBackend>(
    root: &DrawingArea<DB, Shift>,
    curve: &[CurvePoint],
) -> Result<(), ReportError> {
    let end_s = curve.iter().map(|p| p.t_s).fold(1.0, f64::max);
    let mut chart = ChartBuilder::on(root)
        .caption("Known area over time", (FAMILY, 20))
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(50)
        .build_cartesian_2d(0f64..end_s, 0f64..100.0)
        .map_err(plot_err)?;
    chart
        .configure_mesh()
        .x_desc("time (s)")
        .y_desc("known area (% of the world)")
        .label_style((FAMILY, 13))
        .draw()
        .map_err(plot_err)?;
    chart
        .draw_series(LineSeries::new(
            curve.iter().map(|p| (p.t_s, p.area_pct)),
            palette::drone(1).stroke_width(2),
        ))
        .map_err(plot_err)?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use ab_glyph::{Font, FontRef};

    /// The cut font has a glyph for what the figures write: ASCII, the symbols of their
    /// labels, and the accented and Greek letters a name or a unit may hold.
    #[test]
    fn the_embedded_font_has_the_characters_of_the_figures() {
        let font = FontRef::try_from_slice(FONT).unwrap();
        let symbols = "±–—…°²³µ·×÷≤≥≈→←↑↓ΔσπéèüöñçÅØ€";
        let missing: Vec<char> = (' '..='~')
            .chain(symbols.chars())
            .filter(|c| font.glyph_id(*c).0 == 0)
            .collect();
        assert!(missing.is_empty(), "no glyph for {missing:?}");
        assert_eq!(font.glyph_id('ж').0, 0, "Cyrillic was cut out");
    }
}
