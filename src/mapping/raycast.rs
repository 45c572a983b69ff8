//! Grid traversal of a straight segment (Amanatides–Woo voxel walk).
//!
//! In: a [`GridSpec`] and two world points. Out: the flat indices of every cell the segment
//! passes through, in order, clipped to the grid. Used by scan insertion (misses along the ray,
//! hit at the end) and by the planners' line-of-sight checks.

use nalgebra::Vector2;

use super::grid::GridSpec;

/// `x.floor() as i64` without the libm call (`floor` is not inlined on baseline x86_64).
/// Values beyond the `i64` range saturate, as `as` does.
fn floor_i64(x: f64) -> i64 {
    let t = x as i64;
    if (t as f64) > x {
        t - 1
    } else {
        t
    }
}

/// How a traced segment ended.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum TraceEnd {
    /// The segment never touches the grid.
    Outside,
    /// Every cell was visited and the end point lies inside the grid (its cell was visited last).
    EndInside,
    /// Every in-grid cell was visited but the end point lies outside the grid.
    EndOutside,
    /// `visit` returned `false`.
    Stopped,
}

/// Calls `visit(index)` for every cell from `a` to `b` (both included when inside the grid).
/// `visit` returns `false` to stop early.
pub fn trace_segment(
    spec: &GridSpec,
    a: Vector2<f64>,
    b: Vector2<f64>,
    mut visit: impl FnMut(usize) -> bool,
) -> TraceEnd {
    let inv_res = 1.0 / spec.resolution_m;
    let w = f64::from(spec.width_cells);
    let h = f64::from(spec.height_cells);
    let p0 = (a - spec.origin_enu_m) * inv_res;
    let p1 = (b - spec.origin_enu_m) * inv_res;
    let d = p1 - p0;
    if !(p0.x.is_finite() && p0.y.is_finite() && p1.x.is_finite() && p1.y.is_finite()) {
        return TraceEnd::Outside;
    }
    let inside = |p: &Vector2<f64>| p.x >= 0.0 && p.y >= 0.0 && p.x < w && p.y < h;

    // Liang–Barsky clip of the parametric segment p0 + t d, t in [0, 1], to [0, w] x [0, h],
    // skipped in the common case of both ends inside.
    let mut t0 = 0.0_f64;
    let mut t1 = 1.0_f64;
    let end_inside = inside(&p1);
    if !(inside(&p0) && end_inside) {
        for (p, q) in [(-d.x, p0.x), (d.x, w - p0.x), (-d.y, p0.y), (d.y, h - p0.y)] {
            if p == 0.0 {
                if q < 0.0 {
                    return TraceEnd::Outside;
                }
            } else {
                let r = q / p;
                if p < 0.0 {
                    if r > t1 {
                        return TraceEnd::Outside;
                    }
                    t0 = t0.max(r);
                } else {
                    if r < t0 {
                        return TraceEnd::Outside;
                    }
                    t1 = t1.min(r);
                }
            }
        }
    }

    let wi = i64::from(spec.width_cells);
    let hi = i64::from(spec.height_cells);
    let cell = |t: f64| {
        let p = p0 + d * t;
        (
            floor_i64(p.x).clamp(0, wi - 1),
            floor_i64(p.y).clamp(0, hi - 1),
        )
    };
    let (mut cx, mut cy) = cell(t0);
    let (ex, ey) = cell(t1);
    let step_x = (ex - cx).signum();
    let step_y = (ey - cy).signum();
    let t_delta_x = if d.x != 0.0 {
        1.0 / d.x.abs()
    } else {
        f64::INFINITY
    };
    let t_delta_y = if d.y != 0.0 {
        1.0 / d.y.abs()
    } else {
        f64::INFINITY
    };
    let mut t_max_x = if d.x > 0.0 {
        ((cx + 1) as f64 - p0.x) * t_delta_x
    } else if d.x < 0.0 {
        (p0.x - cx as f64) * t_delta_x
    } else {
        f64::INFINITY
    };
    let mut t_max_y = if d.y > 0.0 {
        ((cy + 1) as f64 - p0.y) * t_delta_y
    } else if d.y < 0.0 {
        (p0.y - cy as f64) * t_delta_y
    } else {
        f64::INFINITY
    };

    // Each step moves one cell closer (Manhattan) to the end cell, so exactly `steps` steps are
    // taken and the walk ends on the end cell even when rounding makes the t comparisons
    // disagree with it. The flat index is stepped along with the coordinates.
    let steps = (ex - cx).abs() + (ey - cy).abs();
    let row_step = step_y * wi;
    let mut idx = cy * wi + cx;
    for _ in 0..steps {
        if !visit(idx as usize) {
            return TraceEnd::Stopped;
        }
        if cx != ex && (cy == ey || t_max_x < t_max_y) {
            cx += step_x;
            idx += step_x;
            t_max_x += t_delta_x;
        } else {
            cy += step_y;
            idx += row_step;
            t_max_y += t_delta_y;
        }
    }
    if !visit(idx as usize) {
        return TraceEnd::Stopped;
    }
    if end_inside {
        TraceEnd::EndInside
    } else {
        TraceEnd::EndOutside
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec10() -> GridSpec {
        GridSpec {
            resolution_m: 1.0,
            width_cells: 10,
            height_cells: 10,
            origin_enu_m: Vector2::zeros(),
        }
    }

    fn cells(spec: &GridSpec, a: (f64, f64), b: (f64, f64)) -> (Vec<(usize, usize)>, TraceEnd) {
        let mut out = Vec::new();
        let end = trace_segment(spec, Vector2::new(a.0, a.1), Vector2::new(b.0, b.1), |i| {
            out.push((i % 10, i / 10));
            true
        });
        (out, end)
    }

    #[test]
    fn shallow_line_matches_hand_walk() {
        // Line y = 0.5 + (x - 0.5) / 2 crosses x = 1 at y = 0.75, y = 1 at x = 1.5, x = 2 at
        // y = 1.25, x = 3 at y = 1.75, y = 2 at x = 3.5, x = 4 at y = 2.25.
        let (c, end) = cells(&spec10(), (0.5, 0.5), (4.5, 2.5));
        assert_eq!(
            c,
            vec![(0, 0), (1, 0), (1, 1), (2, 1), (3, 1), (3, 2), (4, 2)]
        );
        assert_eq!(end, TraceEnd::EndInside);
    }

    #[test]
    fn reverse_direction_visits_same_cells_backwards() {
        let (c, _) = cells(&spec10(), (4.5, 2.5), (0.5, 0.5));
        assert_eq!(
            c,
            vec![(4, 2), (3, 2), (3, 1), (2, 1), (1, 1), (1, 0), (0, 0)]
        );
    }

    #[test]
    fn segment_leaving_the_grid_is_clipped() {
        let (c, end) = cells(&spec10(), (7.5, 3.5), (14.0, 3.5));
        assert_eq!(c, vec![(7, 3), (8, 3), (9, 3)]);
        assert_eq!(end, TraceEnd::EndOutside);
    }

    #[test]
    fn segment_entering_from_outside_starts_at_the_border() {
        let (c, end) = cells(&spec10(), (-3.0, 0.5), (1.5, 0.5));
        assert_eq!(c, vec![(0, 0), (1, 0)]);
        assert_eq!(end, TraceEnd::EndInside);
    }

    #[test]
    fn segment_missing_the_grid_visits_nothing() {
        let (c, end) = cells(&spec10(), (-3.0, -1.0), (20.0, -1.0));
        assert!(c.is_empty());
        assert_eq!(end, TraceEnd::Outside);
    }

    #[test]
    fn floor_matches_std_for_negative_and_integral_values() {
        for x in [-2.5, -2.0, -0.1, 0.0, 0.7, 3.0, 1e10] {
            assert_eq!(floor_i64(x), x.floor() as i64, "{x}");
        }
    }

    #[test]
    fn zero_length_segment_visits_its_cell() {
        let (c, end) = cells(&spec10(), (2.2, 3.7), (2.2, 3.7));
        assert_eq!(c, vec![(2, 3)]);
        assert_eq!(end, TraceEnd::EndInside);
    }
}
