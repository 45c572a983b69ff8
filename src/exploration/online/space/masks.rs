//! Cell masks of one grid (`w` x `h` cells, row-major): growing them by a square or a disc,
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

/// `mask` grown by a disc of radius `r` cells (centre to centre): a row dilation for each
/// half-width the disc has, then the rows above and below combined (O((2r+1) cells)). Round,
/// so a diagonal gap between two poles is as open as a straight one.
pub(super) fn dilate_disc(mask: &[bool], w: usize, h: usize, r: usize) -> Vec<bool> {
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
