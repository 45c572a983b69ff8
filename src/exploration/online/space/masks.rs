//! Cell masks of one grid (`w` x `h` cells, row-major): growing them by a square, the squared
//! distance from every cell to the nearest set cell (growing by a disc of any radius at once),
//! closing one-cell gaps, and their 8-connected components. The space's reading of a grid is
//! built from these.

/// `mask` grown by `r` cells in every direction (a (2r+1)^2 square), by two sliding-window
/// passes over running counts.
pub(super) fn dilate(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let rows = dilate_rows(mask, w, h, r);
    // Columns: a running count per column over the window of rows y - r ..= y + r, walked row
    // by row (cache-friendly).
    let mut counts = vec![0u32; w];
    let add = |counts: &mut [u32], y: usize, sign: i64| {
        for (c, &m) in counts.iter_mut().zip(&rows[y * w..(y + 1) * w]) {
            if m {
                *c = (i64::from(*c) + sign) as u32;
            }
        }
    };
    for y in 0..r.min(h) {
        add(&mut counts, y, 1);
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        if y + r < h {
            add(&mut counts, y + r, 1);
        }
        if y > r {
            add(&mut counts, y - r - 1, -1);
        }
        for (o, &c) in out[y * w..(y + 1) * w].iter_mut().zip(&counts) {
            *o = c > 0;
        }
    }
    out
}

/// Squared Euclidean distance (in cells², centre to centre) from each cell to the nearest set
/// cell of `mask`, `u32::MAX` where none is set: exact, in two passes of lower envelopes of
/// parabolas (Felzenszwalb and Huttenlocher, "Distance Transforms of Sampled Functions"), O(w h).
/// `mask` grown by a disc of radius `r` is the cells at `r * r` or less, for every `r` at once.
pub(super) fn squared_distance(mask: &[bool], w: usize, h: usize) -> Vec<u32> {
    const FAR: u64 = u64::MAX / 4;
    // Columns first: the vertical distance to the nearest set cell, swept down then up, row by
    // row (cache-friendly), with the last set row seen per column.
    let mut column = vec![FAR; w * h];
    let mut seen: Vec<Option<usize>> = vec![None; w];
    for y in 0..h {
        for x in 0..w {
            if mask[y * w + x] {
                seen[x] = Some(y);
            }
            if let Some(l) = seen[x] {
                column[y * w + x] = ((y - l) * (y - l)) as u64;
            }
        }
    }
    seen.fill(None);
    for y in (0..h).rev() {
        for x in 0..w {
            if mask[y * w + x] {
                seen[x] = Some(y);
            }
            if let Some(n) = seen[x] {
                let c = &mut column[y * w + x];
                *c = (*c).min(((n - y) * (n - y)) as u64);
            }
        }
    }
    // Then each row: the lower envelope of the parabolas (x - q)^2 + column[q].
    let mut out = vec![u32::MAX; w * h];
    let mut hull: Vec<usize> = Vec::with_capacity(w);
    let mut starts: Vec<f64> = Vec::with_capacity(w + 1);
    for y in 0..h {
        let f = &column[y * w..(y + 1) * w];
        hull.clear();
        starts.clear();
        for q in (0..w).filter(|&q| f[q] < FAR) {
            let meet = |p: usize| {
                let (fq, fp) = (f[q] as f64, f[p] as f64);
                let (q2, p2) = ((q * q) as f64, (p * p) as f64);
                ((fq + q2) - (fp + p2)) / (2.0 * (q as f64 - p as f64))
            };
            while let Some(&p) = hull.last() {
                let s = meet(p);
                if s <= *starts.last().unwrap_or(&f64::NEG_INFINITY) {
                    hull.pop();
                    starts.pop();
                } else {
                    starts.push(s);
                    break;
                }
            }
            if hull.is_empty() {
                starts.clear();
                starts.push(f64::NEG_INFINITY);
            }
            hull.push(q);
        }
        if hull.is_empty() {
            continue;
        }
        let mut k = 0;
        for x in 0..w {
            while k + 1 < hull.len() && starts[k + 1] < x as f64 {
                k += 1;
            }
            let q = hull[k];
            let dx = x.abs_diff(q) as u64;
            out[y * w + x] = (dx * dx + f[q]).min(u64::from(u32::MAX - 1)) as u32;
        }
    }
    out
}

/// `mask` grown by a disc of radius `r` cells (centre to centre): a row dilation for each
/// half-width the disc has, then the rows above and below combined (O((2r+1) cells)). Round,
/// so a diagonal gap between two poles is as open as a straight one.
#[cfg(test)]
fn dilate_disc(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let half_width = |dy: usize| ((r * r - dy * dy) as f64).sqrt().floor() as usize;
    let mut by_half_width: Vec<Option<Vec<bool>>> = vec![None; r + 1];
    for dy in 0..=r {
        let hw = half_width(dy);
        if by_half_width[hw].is_none() {
            by_half_width[hw] = Some(dilate_rows(mask, w, h, hw));
        }
    }
    let mut out = vec![false; w * h];
    for y in 0..h {
        let row = &mut out[y * w..(y + 1) * w];
        for dy in -(r as i64)..=(r as i64) {
            let yy = y as i64 + dy;
            if yy < 0 || yy >= h as i64 {
                continue;
            }
            let Some(Some(rows)) = by_half_width.get(half_width(dy.unsigned_abs() as usize)) else {
                continue;
            };
            let src = &rows[yy as usize * w..(yy as usize + 1) * w];
            for (o, &m) in row.iter_mut().zip(src) {
                *o |= m;
            }
        }
    }
    out
}

/// Each row of `mask` grown by `r` cells left and right.
fn dilate_rows(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
    let mut out = vec![false; w * h];
    let mut prefix = vec![0u32; w + 1];
    for y in 0..h {
        let row = &mask[y * w..(y + 1) * w];
        for (x, &m) in row.iter().enumerate() {
            prefix[x + 1] = prefix[x] + u32::from(m);
        }
        for x in 0..w {
            let lo = x.saturating_sub(r);
            let hi = (x + r + 1).min(w);
            out[y * w + x] = prefix[hi] > prefix[lo];
        }
    }
    out
}

/// 3 x 3 closing of the free cells (dilate, then erode), never across an obstacle: one-cell
/// gaps between observed rays become free.
pub(super) fn close3(free: &[bool], occupied: &[bool], w: usize, h: usize) -> Vec<bool> {
    let grown = dilate(free, w, h, 1);
    let not_grown: Vec<bool> = grown.iter().map(|g| !g).collect();
    let shrunk = dilate(&not_grown, w, h, 1);
    (0..w * h)
        .map(|i| free[i] || (!shrunk[i] && !occupied[i]))
        .collect()
}

/// 8-connected components of the set cells, each as its cell indices.
pub(super) fn components(mask: &[bool], w: usize, h: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; w * h];
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for start in 0..w * h {
        if !mask[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        stack.push(start);
        let mut cells = Vec::new();
        while let Some(i) = stack.pop() {
            cells.push(i);
            let (x, y) = ((i % w) as i64, (i / w) as i64);
            for dy in -1..=1i64 {
                for dx in -1..=1i64 {
                    let (nx, ny) = (x + dx, y + dy);
                    if nx < 0 || ny < 0 || nx >= w as i64 || ny >= h as i64 {
                        continue;
                    }
                    let j = ny as usize * w + nx as usize;
                    if mask[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                }
            }
        }
        out.push(cells);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A seeded mask with about one cell in `one_in` set.
    fn mask(w: usize, h: usize, one_in: u64, seed: u64) -> Vec<bool> {
        let mut x = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (0..w * h)
            .map(|_| {
                x = x
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                (x >> 33).is_multiple_of(one_in)
            })
            .collect()
    }

    #[test]
    fn the_distance_transform_grows_a_mask_by_every_disc_as_the_disc_dilation_does() {
        for (w, h, one_in, seed) in [
            (37, 23, 50, 1),
            (64, 64, 400, 2),
            (1, 40, 7, 3),
            (40, 1, 7, 4),
            (50, 30, 3, 5),
            (20, 20, u64::MAX, 6),
        ] {
            let m = mask(w, h, one_in, seed);
            let d2 = squared_distance(&m, w, h);
            for r in 0..=12 {
                let disc = dilate_disc(&m, w, h, r);
                let from_d2: Vec<bool> = d2.iter().map(|&d| d <= (r * r) as u32).collect();
                assert_eq!(disc, from_d2, "{w} x {h}, one in {one_in}, r {r}");
            }
        }
    }

    #[test]
    fn the_squared_distance_is_exact_to_a_lone_cell_and_unset_without_any() {
        let (w, h) = (9, 7);
        let mut m = vec![false; w * h];
        assert!(squared_distance(&m, w, h).iter().all(|&d| d == u32::MAX));
        m[3 * w + 4] = true;
        let d2 = squared_distance(&m, w, h);
        for y in 0..h {
            for x in 0..w {
                let (dx, dy) = (x.abs_diff(4), y.abs_diff(3));
                assert_eq!(d2[y * w + x] as usize, dx * dx + dy * dy, "({x}, {y})");
            }
        }
    }
}
