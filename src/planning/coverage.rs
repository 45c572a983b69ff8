//! Coverage planning: a back-and-forth (boustrophedon) sweep of a polygon split among drones.
//!
//! In: a polygon (ENU, metres, any orientation, may be non-convex), a street spacing, an optional
//! street angle, the drones' start positions and the flight height. Out: a [`CoveragePlan`] with
//! one waypoint list per drone (same order as the starts), balanced in length.
//!
//! Method:
//! 1. Angle: the given one, or the direction of the convex-hull edge across which the polygon is
//!    narrowest (fewest streets, hence fewest turns). Aerostack2's web GUI instead picks the angle
//!    maximising the rotated x-width, tried in one-degree steps.
//! 2. In the frame rotated so streets run along x, the height `H` is split into
//!    `n = ceil(H / spacing)` bands of equal width `H / n <= spacing`; each band's street runs at
//!    its centre line over the band's full x-extent (the polygon clipped to the band). Every
//!    point of the polygon is then within half a spacing of a street.
//! 3. Streets are joined end to end in alternating directions. Of the four orderings (start at
//!    the first or last street, first street left-to-right or not), the one whose split gives the
//!    smallest total distance from the drones' starts to their pieces is kept.
//! 4. The single sweep path is cut into `N` pieces of equal length (cuts may fall mid-street),
//!    and pieces are assigned to drones minimising the summed start-to-piece distance (exhaustive
//!    for up to 8 drones, greedy beyond); each piece is flown from its end nearer the drone.
//!    Aerostack2 bin-packs whole tracks instead, so its balance is limited by track length.
//!
//! Over a concave notch a street spans the gap (the drone flies over it); waypoints are only the
//! street ends and cuts (no intermediate points).

use nalgebra::{Rotation2, Vector2, Vector3};
use serde::{Deserialize, Serialize};
use std::sync::atomic::{AtomicBool, Ordering};

/// Most streets a plan may have (guards against a tiny spacing on a huge polygon).
pub const MAX_STREETS: usize = 100_000;
/// Largest drone count solved exactly in the assignment.
const EXACT_ASSIGNMENT_MAX: usize = 8;

/// Per-drone sweep paths.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct CoveragePlan {
    /// One waypoint list per drone, in the order of `drone_starts`, at the flight height.
    pub per_drone: Vec<Vec<Vector3<f64>>>,
    /// Street direction (ENU, radians CCW from east, in `(-pi/2, pi/2]`).
    pub angle_rad: f64,
    /// Length of each drone's sweep path, metres (without the transit from its start).
    pub lengths_m: Vec<f64>,
    /// Distance from each drone's start to its first waypoint, metres.
    pub transit_m: Vec<f64>,
    /// Spacing actually used (`<=` the requested one), metres.
    pub street_spacing_m: f64,
}

#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CoverageError {
    #[error("polygon needs at least 3 vertices with finite coordinates")]
    InvalidPolygon,
    #[error("polygon has no area across the street direction")]
    DegeneratePolygon,
    #[error("street spacing must be > 0 metres, got {0}")]
    InvalidSpacing(f64),
    #[error("angle and height must be finite")]
    NotFinite,
    #[error("at least one drone start is needed, all finite")]
    NoDrones,
    #[error("{0} streets exceed the limit of {MAX_STREETS}")]
    TooManyStreets(usize),
    #[error("the coverage plan was cancelled")]
    Cancelled,
}

/// Plans a balanced multi-drone sweep (see the module docs).
pub fn plan_coverage(
    polygon_enu: &[Vector2<f64>],
    street_spacing_m: f64,
    angle: Option<f64>,
    drone_starts: &[Vector2<f64>],
    height_m: f64,
) -> Result<CoveragePlan, CoverageError> {
    let never = AtomicBool::new(false);
    plan_coverage_until(
        polygon_enu,
        street_spacing_m,
        angle,
        drone_starts,
        height_m,
        &never,
    )
}

/// [`plan_coverage`] that gives up with [`CoverageError::Cancelled`] soon after `cancel` is
/// set (checked for every street and every candidate sweep).
pub fn plan_coverage_until(
    polygon_enu: &[Vector2<f64>],
    street_spacing_m: f64,
    angle: Option<f64>,
    drone_starts: &[Vector2<f64>],
    height_m: f64,
    cancel: &AtomicBool,
) -> Result<CoveragePlan, CoverageError> {
    let cancelled = || cancel.load(Ordering::Relaxed);
    let finite = |p: &Vector2<f64>| p.x.is_finite() && p.y.is_finite();
    if polygon_enu.len() < 3 || !polygon_enu.iter().all(finite) {
        return Err(CoverageError::InvalidPolygon);
    }
    if !(street_spacing_m.is_finite() && street_spacing_m > 0.0) {
        return Err(CoverageError::InvalidSpacing(street_spacing_m));
    }
    if drone_starts.is_empty() || !drone_starts.iter().all(finite) {
        return Err(CoverageError::NoDrones);
    }
    if !height_m.is_finite() || angle.is_some_and(|a| !a.is_finite()) {
        return Err(CoverageError::NotFinite);
    }
    let angle_rad = normalize_angle(match angle {
        Some(a) => a,
        None => narrowest_direction(polygon_enu).ok_or(CoverageError::DegeneratePolygon)?,
    });

    // Work in the street frame: streets along +x.
    let to_street = Rotation2::new(-angle_rad);
    let to_world = Rotation2::new(angle_rad);
    let poly: Vec<Vector2<f64>> = polygon_enu.iter().map(|p| to_street * p).collect();
    let (y_min, y_max) = poly
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
            (lo.min(p.y), hi.max(p.y))
        });
    let height = y_max - y_min;
    if height.is_nan() || height <= 1e-9 {
        return Err(CoverageError::DegeneratePolygon);
    }
    let n_streets = ((height / street_spacing_m) - 1e-9).ceil().max(1.0);
    if n_streets > MAX_STREETS as f64 {
        return Err(CoverageError::TooManyStreets(n_streets as usize));
    }
    let n_streets = n_streets as usize;
    let spacing = height / n_streets as f64;
    let mut streets: Vec<(f64, f64, f64)> = Vec::new();
    for k in 0..n_streets {
        if cancelled() {
            return Err(CoverageError::Cancelled);
        }
        let lo = y_min + spacing * k as f64;
        if let Some((x0, x1)) = band_x_extent(&poly, lo, lo + spacing) {
            streets.push((x0, x1, lo + spacing / 2.0));
        }
    }

    let starts_street: Vec<Vector2<f64>> = drone_starts.iter().map(|p| to_street * p).collect();
    let mut best: Option<(f64, Vec<Vec<Vector2<f64>>>)> = None;
    for (bottom_first, left_first) in [(true, true), (true, false), (false, true), (false, false)] {
        if cancelled() {
            return Err(CoverageError::Cancelled);
        }
        let sweep = boustrophedon(&streets, bottom_first, left_first);
        let pieces = split_equal(&sweep, drone_starts.len());
        let (cost, assigned) = assign(pieces, &starts_street);
        if best.as_ref().is_none_or(|(c, _)| cost < *c - 1e-9) {
            best = Some((cost, assigned));
        }
    }
    let assigned = best.map(|(_, a)| a).unwrap_or_default();

    let per_drone: Vec<Vec<Vector3<f64>>> = assigned
        .iter()
        .map(|piece| {
            piece
                .iter()
                .map(|p| {
                    let w = to_world * p;
                    Vector3::new(w.x, w.y, height_m)
                })
                .collect()
        })
        .collect();
    let lengths_m = assigned.iter().map(|p| path_length(p)).collect();
    let transit_m = assigned
        .iter()
        .zip(&starts_street)
        .map(|(p, s)| p.first().map_or(0.0, |f| (f - s).norm()))
        .collect();
    Ok(CoveragePlan {
        per_drone,
        angle_rad,
        lengths_m,
        transit_m,
        street_spacing_m: spacing,
    })
}

/// Maps an angle to `(-pi/2, pi/2]` (a street direction and its opposite are the same).
fn normalize_angle(a: f64) -> f64 {
    use std::f64::consts::{FRAC_PI_2, PI};
    let mut a = a.rem_euclid(PI);
    if a > FRAC_PI_2 {
        a -= PI;
    }
    a
}

/// Direction of the convex-hull edge with the smallest polygon extent across it.
fn narrowest_direction(poly: &[Vector2<f64>]) -> Option<f64> {
    let hull = convex_hull(poly);
    let mut best: Option<(f64, f64)> = None;
    for i in 0..hull.len() {
        let (Some(a), Some(b)) = (hull.get(i), hull.get((i + 1) % hull.len())) else {
            continue;
        };
        let e = b - a;
        let len = e.norm();
        if len < 1e-12 {
            continue;
        }
        let normal = Vector2::new(-e.y, e.x) / len;
        let (lo, hi) = hull
            .iter()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), p| {
                let d = normal.dot(p);
                (lo.min(d), hi.max(d))
            });
        let width = hi - lo;
        if best.is_none_or(|(w, _)| width < w - 1e-9) {
            best = Some((width, e.y.atan2(e.x)));
        }
    }
    best.filter(|(w, _)| *w > 1e-9).map(|(_, a)| a)
}

/// Andrew's monotone chain, counter-clockwise, without collinear points.
fn convex_hull(points: &[Vector2<f64>]) -> Vec<Vector2<f64>> {
    let mut pts = points.to_vec();
    pts.sort_by(|a, b| a.x.total_cmp(&b.x).then(a.y.total_cmp(&b.y)));
    pts.dedup();
    if pts.len() < 3 {
        return pts;
    }
    let cross = |o: &Vector2<f64>, a: &Vector2<f64>, b: &Vector2<f64>| {
        (a.x - o.x) * (b.y - o.y) - (a.y - o.y) * (b.x - o.x)
    };
    let mut hull: Vec<Vector2<f64>> = Vec::with_capacity(2 * pts.len());
    for pass in [pts.clone(), pts.iter().rev().copied().collect()] {
        let base = hull.len();
        for p in pass {
            while hull.len() >= base + 2 {
                let (Some(a), Some(b)) = (hull.get(hull.len() - 2), hull.last()) else {
                    break;
                };
                if cross(a, b, &p) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// x-extent of the polygon clipped to the band `lo <= y <= hi` (Sutherland–Hodgman).
fn band_x_extent(poly: &[Vector2<f64>], lo: f64, hi: f64) -> Option<(f64, f64)> {
    let clip = |pts: &[Vector2<f64>], inside: &dyn Fn(&Vector2<f64>) -> bool, y: f64| {
        let mut out = Vec::with_capacity(pts.len() + 2);
        for (i, cur) in pts.iter().enumerate() {
            let Some(prev) = pts.get((i + pts.len() - 1) % pts.len()) else {
                continue;
            };
            let cross_at = |a: &Vector2<f64>, b: &Vector2<f64>| {
                let t = (y - a.y) / (b.y - a.y);
                Vector2::new(a.x + t * (b.x - a.x), y)
            };
            match (inside(prev), inside(cur)) {
                (true, true) => out.push(*cur),
                (true, false) => out.push(cross_at(prev, cur)),
                (false, true) => {
                    out.push(cross_at(prev, cur));
                    out.push(*cur);
                }
                (false, false) => {}
            }
        }
        out
    };
    let above = clip(poly, &|p| p.y >= lo, lo);
    let band = clip(&above, &|p| p.y <= hi, hi);
    band.iter()
        .fold(None, |acc: Option<(f64, f64)>, p| match acc {
            None => Some((p.x, p.x)),
            Some((a, b)) => Some((a.min(p.x), b.max(p.x))),
        })
}

/// Street ends in sweep order.
fn boustrophedon(
    streets: &[(f64, f64, f64)],
    bottom_first: bool,
    left_first: bool,
) -> Vec<Vector2<f64>> {
    let ordered: Vec<&(f64, f64, f64)> = if bottom_first {
        streets.iter().collect()
    } else {
        streets.iter().rev().collect()
    };
    let mut path = Vec::with_capacity(2 * ordered.len());
    for (k, &&(x0, x1, y)) in ordered.iter().enumerate() {
        let left_to_right = (k % 2 == 0) == left_first;
        let (a, b) = if left_to_right { (x0, x1) } else { (x1, x0) };
        path.push(Vector2::new(a, y));
        path.push(Vector2::new(b, y));
    }
    path
}

fn path_length(p: &[Vector2<f64>]) -> f64 {
    p.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Cuts a polyline into `n` consecutive pieces of equal length.
fn split_equal(path: &[Vector2<f64>], n: usize) -> Vec<Vec<Vector2<f64>>> {
    let total = path_length(path);
    let n = n.max(1);
    let share = total / n as f64;
    let mut pieces: Vec<Vec<Vector2<f64>>> = Vec::with_capacity(n);
    let mut current: Vec<Vector2<f64>> = path.first().copied().into_iter().collect();
    let mut done = 0.0; // length consumed before `current`'s last point
    let mut next_cut = share;
    for w in path.windows(2) {
        let (a, b) = (w[0], w[1]);
        let seg = (b - a).norm();
        while pieces.len() + 1 < n && done + seg >= next_cut && seg > 0.0 {
            let t = (next_cut - done) / seg;
            let cut = a + (b - a) * t;
            current.push(cut);
            pieces.push(std::mem::replace(&mut current, vec![cut]));
            next_cut += share;
        }
        current.push(b);
        done += seg;
    }
    pieces.push(current);
    for piece in &mut pieces {
        piece.dedup_by(|a, b| (*a - *b).norm() < 1e-9);
    }
    while pieces.len() < n {
        pieces.push(path.last().copied().into_iter().collect());
    }
    pieces
}

/// Assigns pieces to starts (minimising summed distance to the nearer piece end) and orients
/// each piece to begin at that end. Returns the total cost and the pieces in start order.
fn assign(
    pieces: Vec<Vec<Vector2<f64>>>,
    starts: &[Vector2<f64>],
) -> (f64, Vec<Vec<Vector2<f64>>>) {
    let n = starts.len();
    let cost = |d: usize, p: usize| -> (f64, bool) {
        let (Some(s), Some(piece)) = (starts.get(d), pieces.get(p)) else {
            return (f64::INFINITY, false);
        };
        let (Some(first), Some(last)) = (piece.first(), piece.last()) else {
            return (0.0, false);
        };
        let (df, dl) = ((first - s).norm(), (last - s).norm());
        if dl < df {
            (dl, true)
        } else {
            (df, false)
        }
    };
    let matrix: Vec<Vec<f64>> = (0..n)
        .map(|d| (0..n).map(|p| cost(d, p).0).collect())
        .collect();
    let order: Vec<usize> = if n <= EXACT_ASSIGNMENT_MAX {
        let mut perm: Vec<usize> = (0..n).collect();
        let mut best = (f64::INFINITY, perm.clone());
        permute(&mut perm, 0, &mut |p| {
            let c: f64 = p
                .iter()
                .enumerate()
                .map(|(d, &i)| {
                    matrix
                        .get(d)
                        .and_then(|row| row.get(i))
                        .copied()
                        .unwrap_or(f64::INFINITY)
                })
                .sum();
            if c < best.0 - 1e-9 {
                best = (c, p.to_vec());
            }
        });
        best.1
    } else {
        let mut order = vec![usize::MAX; n];
        let mut taken = vec![false; n];
        let mut pairs: Vec<(f64, usize, usize)> = (0..n)
            .flat_map(|d| (0..n).map(move |p| (d, p)))
            .map(|(d, p)| {
                let c = matrix.get(d).and_then(|row| row.get(p)).copied();
                (c.unwrap_or(f64::INFINITY), d, p)
            })
            .collect();
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        for (_, d, p) in pairs {
            if let (Some(o), Some(t)) = (order.get_mut(d), taken.get_mut(p)) {
                if *o == usize::MAX && !*t {
                    *o = p;
                    *t = true;
                }
            }
        }
        order
    };
    let mut total = 0.0;
    let mut out = Vec::with_capacity(n);
    for (d, &p) in order.iter().enumerate() {
        let (c, reverse) = cost(d, p);
        total += c;
        let mut piece = pieces.get(p).cloned().unwrap_or_default();
        if reverse {
            piece.reverse();
        }
        out.push(piece);
    }
    (total, out)
}

/// Calls `visit` with every permutation of `items[k..]` (Heap-free recursive swap).
fn permute(items: &mut Vec<usize>, k: usize, visit: &mut dyn FnMut(&[usize])) {
    if k + 1 >= items.len() {
        visit(items);
        return;
    }
    for i in k..items.len() {
        items.swap(k, i);
        permute(items, k + 1, visit);
        items.swap(k, i);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    fn v(x: f64, y: f64) -> Vector2<f64> {
        Vector2::new(x, y)
    }

    fn inside(poly: &[Vector2<f64>], p: &Vector2<f64>) -> bool {
        let mut c = false;
        for i in 0..poly.len() {
            let (a, b) = (poly[i], poly[(i + 1) % poly.len()]);
            if (a.y > p.y) != (b.y > p.y) && p.x < a.x + (p.y - a.y) / (b.y - a.y) * (b.x - a.x) {
                c = !c;
            }
        }
        c
    }

    fn dist_to_segment(p: &Vector2<f64>, a: &Vector2<f64>, b: &Vector2<f64>) -> f64 {
        let ab = b - a;
        let t = if ab.norm_squared() > 0.0 {
            ((p - a).dot(&ab) / ab.norm_squared()).clamp(0.0, 1.0)
        } else {
            0.0
        };
        (a + ab * t - p).norm()
    }

    /// Every sampled interior point within half a spacing (+1 mm) of some drone's path.
    fn assert_covered(poly: &[Vector2<f64>], plan: &CoveragePlan, spacing: f64) {
        let (lo, hi) = poly
            .iter()
            .fold((v(1e9, 1e9), v(-1e9, -1e9)), |(lo, hi), p| {
                (
                    v(lo.x.min(p.x), lo.y.min(p.y)),
                    v(hi.x.max(p.x), hi.y.max(p.y)),
                )
            });
        let steps = 90;
        let mut checked = 0;
        for i in 0..=steps {
            for j in 0..=steps {
                let p = v(
                    lo.x + (hi.x - lo.x) * i as f64 / steps as f64,
                    lo.y + (hi.y - lo.y) * j as f64 / steps as f64,
                );
                if !inside(poly, &p) {
                    continue;
                }
                checked += 1;
                let d = plan
                    .per_drone
                    .iter()
                    .flat_map(|path| {
                        path.windows(2)
                            .map(|w| dist_to_segment(&p, &w[0].xy(), &w[1].xy()))
                    })
                    .fold(f64::INFINITY, f64::min);
                assert!(
                    d <= spacing / 2.0 + 1e-3,
                    "point {p:?} is {d} m from every path"
                );
            }
        }
        assert!(checked > 600);
    }

    fn balance(plan: &CoveragePlan) -> f64 {
        let max = plan.lengths_m.iter().copied().fold(0.0, f64::max);
        let min = plan.lengths_m.iter().copied().fold(f64::INFINITY, f64::min);
        max / min
    }

    #[test]
    fn rectangle_single_drone_has_expected_streets() {
        let poly = [v(0.0, 0.0), v(40.0, 0.0), v(40.0, 20.0), v(0.0, 20.0)];
        let plan =
            plan_coverage(&poly, 5.0, Some(0.0), &[v(-1.0, -1.0)], 10.0).map_err(|e| e.to_string());
        let plan = plan.unwrap();
        // Four streets at y = 2.5, 7.5, 12.5, 17.5, 40 m each, three 5 m connections.
        assert_eq!(plan.per_drone[0].len(), 8);
        assert_eq!(plan.per_drone[0][0], Vector3::new(0.0, 2.5, 10.0));
        assert!((plan.lengths_m[0] - 175.0).abs() < 1e-9);
        assert_eq!(plan.street_spacing_m, 5.0);
    }

    #[test]
    fn auto_angle_follows_the_long_side_of_a_rotated_strip() {
        let a = PI / 6.0;
        let r = Rotation2::new(a);
        let poly: Vec<Vector2<f64>> = [v(0.0, 0.0), v(100.0, 0.0), v(100.0, 10.0), v(0.0, 10.0)]
            .iter()
            .map(|p| r * p)
            .collect();
        let plan = plan_coverage(&poly, 4.0, None, &[v(0.0, 0.0)], 5.0).unwrap();
        assert!((plan.angle_rad - a).abs() < 1e-9, "{}", plan.angle_rad);
        // ceil(10 / 4) = 3 streets of spacing 10/3.
        assert!((plan.street_spacing_m - 10.0 / 3.0).abs() < 1e-9);
        assert_covered(&poly, &plan, 4.0);
    }

    #[test]
    fn concave_polygon_is_covered_and_split_evenly_among_three_drones() {
        // An L-shaped solar park with a slanted edge.
        let poly = [
            v(0.0, 0.0),
            v(80.0, 0.0),
            v(80.0, 30.0),
            v(35.0, 30.0),
            v(25.0, 70.0),
            v(0.0, 70.0),
        ];
        let starts = [v(-5.0, -5.0), v(90.0, 0.0), v(0.0, 80.0)];
        let plan = plan_coverage(&poly, 6.0, None, &starts, 12.0).unwrap();
        assert_eq!(plan.per_drone.len(), 3);
        assert_covered(&poly, &plan, 6.0);
        assert!(balance(&plan) < 1.2, "{:?}", plan.lengths_m);
        assert!(plan.per_drone.iter().flatten().all(|p| p.z == 12.0));
        // Each drone starts nearer its own start than the sweep's far end is.
        for (i, path) in plan.per_drone.iter().enumerate() {
            let first = path[0].xy();
            assert!((first - starts[i]).norm() <= plan.transit_m[i] + 1e-9);
            assert!(
                plan.transit_m[i] < 60.0,
                "drone {i} transit {}",
                plan.transit_m[i]
            );
        }
    }

    #[test]
    fn balance_holds_for_many_drones_and_rotations() {
        let poly = [v(0.0, 0.0), v(120.0, 10.0), v(110.0, 90.0), v(-10.0, 60.0)];
        for n in [2usize, 4, 9] {
            let starts: Vec<Vector2<f64>> = (0..n).map(|i| v(i as f64 * 10.0, -20.0)).collect();
            for angle in [None, Some(0.3), Some(-1.2)] {
                let plan = plan_coverage(&poly, 5.0, angle, &starts, 10.0).unwrap();
                assert!(
                    balance(&plan) < 1.2,
                    "n {n} angle {angle:?}: {:?}",
                    plan.lengths_m
                );
                assert_covered(&poly, &plan, 5.0);
            }
        }
    }

    #[test]
    fn single_drone_starts_at_the_nearest_corner() {
        let poly = [v(0.0, 0.0), v(40.0, 0.0), v(40.0, 20.0), v(0.0, 20.0)];
        let plan = plan_coverage(&poly, 5.0, Some(0.0), &[v(45.0, 25.0)], 10.0).unwrap();
        assert_eq!(plan.per_drone[0][0], Vector3::new(40.0, 17.5, 10.0));
    }

    #[test]
    fn invalid_inputs_are_typed_errors() {
        let poly = [v(0.0, 0.0), v(4.0, 0.0), v(4.0, 2.0)];
        let s = [v(0.0, 0.0)];
        assert_eq!(
            plan_coverage(&poly[..2], 1.0, None, &s, 1.0),
            Err(CoverageError::InvalidPolygon)
        );
        assert_eq!(
            plan_coverage(&poly, 0.0, None, &s, 1.0),
            Err(CoverageError::InvalidSpacing(0.0))
        );
        assert_eq!(
            plan_coverage(&poly, 1.0, None, &[], 1.0),
            Err(CoverageError::NoDrones)
        );
        assert_eq!(
            plan_coverage(&poly, 1.0, Some(f64::NAN), &s, 1.0),
            Err(CoverageError::NotFinite)
        );
        let line = [v(0.0, 0.0), v(4.0, 0.0), v(8.0, 0.0)];
        assert_eq!(
            plan_coverage(&line, 1.0, None, &s, 1.0),
            Err(CoverageError::DegeneratePolygon)
        );
        assert!(matches!(
            plan_coverage(&poly, 1e-6, Some(0.0), &s, 1.0),
            Err(CoverageError::TooManyStreets(_))
        ));
    }
}
