//! Keeps the pieces of a multi-drone coverage plan apart where they meet.
//!
//! Equal-length pieces of one sweep share their cut points, so two drones can finish (or start)
//! their pieces at the same spot. In: the per-drone paths and a separation (m). Out: the same
//! paths, each end that lies within the separation of another piece's end pulled back along its
//! own path by half the separation (never more than a third of the piece), so the two ends end
//! up about `separation_m` apart. Paths are only shortened, never moved sideways.

use nalgebra::Vector3;

/// Length of a polyline (m).
pub fn length_m(path: &[Vector3<f64>]) -> f64 {
    path.windows(2).map(|w| (w[1] - w[0]).norm()).sum()
}

/// Removes `d` metres from the start of `path`.
fn trim_start(path: &mut Vec<Vector3<f64>>, mut d: f64) {
    while path.len() >= 2 && d > 0.0 {
        let (a, b) = (path[0], path[1]);
        let seg = (b - a).norm();
        if seg > d {
            path[0] = a + (b - a) * (d / seg);
            return;
        }
        d -= seg;
        path.remove(0);
    }
}

fn trim_end(path: &mut Vec<Vector3<f64>>, d: f64) {
    path.reverse();
    trim_start(path, d);
    path.reverse();
}

/// Pulls apart piece ends closer than `separation_m` to another piece's end (see module docs).
pub fn separate_piece_ends(per_drone: &mut [Vec<Vector3<f64>>], separation_m: f64) {
    // Decide on the original ends first, then trim, so the order of drones does not matter.
    let ends: Vec<Option<(Vector3<f64>, Vector3<f64>)>> = per_drone
        .iter()
        .map(|p| Some((*p.first()?, *p.last()?)))
        .collect();
    let near_other = |i: usize, point: &Vector3<f64>| {
        ends.iter().enumerate().any(|(j, e)| {
            j != i
                && e.is_some_and(|(a, b)| {
                    (a - point).norm() < separation_m || (b - point).norm() < separation_m
                })
        })
    };
    let trims: Vec<(bool, bool)> = ends
        .iter()
        .enumerate()
        .map(|(i, e)| {
            e.map_or((false, false), |(a, b)| {
                (near_other(i, &a), near_other(i, &b))
            })
        })
        .collect();
    for (path, (start, end)) in per_drone.iter_mut().zip(trims) {
        let d = (separation_m / 2.0).min(length_m(path) / 3.0);
        if start {
            trim_start(path, d);
        }
        if end {
            trim_end(path, d);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn p(x: f64, y: f64) -> Vector3<f64> {
        Vector3::new(x, y, 4.0)
    }

    #[test]
    fn ends_at_a_shared_cut_are_pulled_apart_along_their_own_paths() {
        let mut pieces = vec![
            vec![p(6.0, 7.0), p(-6.0, 7.0), p(-6.0, 10.0), p(0.0, 10.0)],
            vec![p(-6.0, 13.0), p(6.0, 13.0), p(6.0, 10.0), p(0.0, 10.0)],
        ];
        separate_piece_ends(&mut pieces, 2.0);
        assert_eq!(pieces[0].last(), Some(&p(-1.0, 10.0)));
        assert_eq!(pieces[1].last(), Some(&p(1.0, 10.0)));
        assert_eq!(pieces[0][0], p(6.0, 7.0), "far ends stay");
        assert!((length_m(&pieces[0]) - 20.0).abs() < 1e-9);
    }

    #[test]
    fn separate_pieces_and_short_ones_are_left_or_trimmed_a_little() {
        let mut apart = vec![
            vec![p(0.0, 0.0), p(5.0, 0.0)],
            vec![p(0.0, 9.0), p(5.0, 9.0)],
        ];
        let before = apart.clone();
        separate_piece_ends(&mut apart, 2.0);
        assert_eq!(apart, before);
        let mut short = vec![
            vec![p(0.0, 0.0), p(0.3, 0.0)],
            vec![p(0.3, 0.0), p(0.6, 0.0)],
        ];
        separate_piece_ends(&mut short, 2.0);
        assert!(short.iter().all(|s| length_m(s) > 0.09), "{short:?}");
    }
}
