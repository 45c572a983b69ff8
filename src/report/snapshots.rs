//! The explored map as it was when the area first reached a share of its final value (thesis
//! Fig. 5.22: 25, 50 and 75 %, and here 100 %).
//!
//! In: the evaluator's final [`KnownMap`] (its cells in the order they became known, and the
//! growth of their count over log time). Out: one [`Snapshot`] per share: the log time of the
//! first sample after which at least that share of the final cells was known, and the map of
//! every cell known then.

use crate::exploration::offline::evaluate::KnownMap;

/// Shares of the final area the report draws the map at (%).
pub const SNAPSHOT_PCTS: [f64; 4] = [25.0, 50.0, 75.0, 100.0];

#[derive(Debug, Clone, PartialEq)]
pub struct Snapshot {
    /// Share of the final known cells asked for (%).
    pub pct_of_final: f64,
    /// Log time the share was first reached (s).
    pub t_s: f64,
    /// The cells known at `t_s` (`order` and `growth` left empty).
    pub map: KnownMap,
}

/// The map when at least `pct_of_final` % of the final known cells were first known; `None`
/// when nothing was ever known.
pub fn snapshot(map: &KnownMap, pct_of_final: f64) -> Option<Snapshot> {
    let final_cells = map.order.len();
    if final_cells == 0 {
        return None;
    }
    let wanted =
        ((pct_of_final / 100.0 * final_cells as f64).ceil() as usize).clamp(1, final_cells);
    let &(t_s, count) = map.growth.iter().find(|(_, c)| *c >= wanted)?;
    let mut known = vec![false; map.known.len()];
    for &i in map.order.iter().take(count) {
        if let Some(k) = known.get_mut(i as usize) {
            *k = true;
        }
    }
    Some(Snapshot {
        pct_of_final,
        t_s,
        map: KnownMap {
            known,
            order: Vec::new(),
            growth: Vec::new(),
            ..*map
        },
    })
}

/// The snapshots at [`SNAPSHOT_PCTS`].
pub fn snapshots(map: &KnownMap) -> Vec<Snapshot> {
    SNAPSHOT_PCTS
        .iter()
        .filter_map(|&p| snapshot(map, p))
        .collect()
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used, clippy::expect_used)]
    use super::*;

    /// Ten cells in a row, known over time: cells 0-1 at 1 s, 2-4 at 2 s, 5-8 at 5 s, 9 at 9 s.
    fn growing() -> KnownMap {
        KnownMap {
            min_x_m: 0.0,
            min_y_m: 0.0,
            cell_m: 1.0,
            nx: 10,
            ny: 1,
            known: vec![true; 10],
            order: vec![3, 7, 0, 1, 2, 9, 8, 6, 5, 4],
            growth: vec![(1.0, 2), (2.0, 5), (5.0, 9), (9.0, 10)],
        }
    }

    fn known_cells(s: &Snapshot) -> Vec<usize> {
        (0..s.map.known.len()).filter(|&i| s.map.known[i]).collect()
    }

    #[test]
    fn each_share_is_the_first_time_it_is_reached_with_every_cell_known_then() {
        let shots = snapshots(&growing());
        let times: Vec<f64> = shots.iter().map(|s| s.t_s).collect();
        // 25 % = 3 cells (first at 2 s, when 5 are known), 50 % = 5 (2 s), 75 % = 8 (5 s), 100 % (9 s).
        assert_eq!(times, [2.0, 2.0, 5.0, 9.0]);
        assert_eq!(known_cells(&shots[0]), [0, 1, 2, 3, 7]);
        assert_eq!(known_cells(&shots[2]).len(), 9);
        assert!(!shots[2].map.known[4], "cell 4 is known only at 9 s");
        assert_eq!(shots[3].map.known, vec![true; 10]);
        assert_eq!(shots[3].pct_of_final, 100.0);
    }

    #[test]
    fn nothing_known_gives_no_snapshot() {
        let mut map = growing();
        map.order.clear();
        map.growth.clear();
        map.known = vec![false; 10];
        assert!(snapshots(&map).is_empty());
    }
}
