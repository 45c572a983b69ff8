//! Peers' map regions on their way to the control loop: coalesced per drone as they arrive (on
//! the bus's threads), taken by the loop a few rows at a time, so that however many regions
//! peers send, the loop's work per tick stays bounded.
//!
//! In: checked [`MapMsg`]s. Out: [`Slice`]s of at most the cells asked for, one drone's at a
//! time in turn. A region that arrives while an older one of the same drone waits is written
//! over it (the latest value of a cell wins; the box grows to the union of both, whose cells
//! neither set are [`KEEP`]), so a flood of regions costs the loop one grid per drone at most.
//! At most [`MAX_PENDING_DRONES`] drones wait; a region of one more is refused (the bus counts
//! it as dropped). The loop never waits for the lock: when the bus holds it, the loop takes
//! nothing this tick.

use std::collections::BTreeMap;
use std::sync::Mutex;

use super::remote::MAX_REMOTE_DRONES;
use super::wire::MapMsg;
use crate::mapping::grid::{Cell, CellBox, GridSpec};
use crate::mapping::layers::KEEP;

/// Most drones whose regions wait at once.
pub const MAX_PENDING_DRONES: usize = MAX_REMOTE_DRONES;

/// Part of a drone's waiting regions, for the loop to write into its layer.
#[derive(Debug, Clone, PartialEq)]
pub struct Slice {
    /// The node that sent them.
    pub node: String,
    pub drone: String,
    pub grid: GridSpec,
    pub region: CellBox,
    /// Row-major from `region.min`; [`KEEP`] for a cell no region set.
    pub cells: Vec<i8>,
    /// Messages coalesced into the drone's regions, counted on its first slice only (what is
    /// refused is counted once per message).
    pub messages: u64,
}

#[derive(Debug)]
struct Pending {
    node: String,
    grid: GridSpec,
    region: CellBox,
    cells: Vec<i8>,
    messages: u64,
}

#[derive(Debug, Default)]
struct Inbox {
    drones: BTreeMap<String, Pending>,
    /// The drone the last slice was taken from (the next one is the next drone).
    last: String,
}

/// Why a region was not taken in.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("regions of {MAX_PENDING_DRONES} drones wait already")]
pub struct InboxFull;

#[derive(Debug, Default)]
pub struct MapInbox(Mutex<Inbox>);

/// `region`'s cells copied into `into` (a buffer of `outer`, which contains `region`).
fn blit(into: &mut [i8], outer: CellBox, region: CellBox, cells: &[i8]) {
    let ow = outer.width_cells() as usize;
    let w = region.width_cells() as usize;
    let dx = (region.min.x - outer.min.x) as usize;
    for (row, src) in cells.chunks_exact(w).enumerate() {
        let y = (region.min.y - outer.min.y) as usize + row;
        if let Some(dst) = into.get_mut(y * ow + dx..y * ow + dx + w) {
            dst.copy_from_slice(src);
        }
    }
}

impl Pending {
    fn merge(&mut self, region: CellBox, cells: &[i8]) {
        let union = self.region.union(region);
        if union != self.region {
            let mut grown =
                vec![KEEP; union.width_cells() as usize * union.height_cells() as usize];
            blit(&mut grown, union, self.region, &self.cells);
            self.cells = grown;
            self.region = union;
        }
        blit(&mut self.cells, self.region, region, cells);
        self.messages += 1;
    }
}

impl MapInbox {
    fn lock(&self) -> std::sync::MutexGuard<'_, Inbox> {
        self.0.lock().unwrap_or_else(|e| e.into_inner())
    }

    /// Takes in a peer's region (on the bus's side).
    pub fn offer(&self, msg: MapMsg) -> Result<(), InboxFull> {
        let MapMsg { header, cells } = msg;
        let mut inbox = self.lock();
        let full = inbox.drones.len() >= MAX_PENDING_DRONES;
        match inbox.drones.get_mut(&header.drone) {
            Some(p) if p.node == header.node && p.grid == header.grid => {
                p.merge(header.region, &cells);
            }
            Some(p) => {
                // Another node, or another grid: the latest replaces what waited.
                let messages = p.messages + 1;
                *p = Pending {
                    node: header.node,
                    grid: header.grid,
                    region: header.region,
                    cells,
                    messages,
                };
            }
            None if full => return Err(InboxFull),
            None => {
                inbox.drones.insert(
                    header.drone,
                    Pending {
                        node: header.node,
                        grid: header.grid,
                        region: header.region,
                        cells,
                        messages: 1,
                    },
                );
            }
        }
        Ok(())
    }

    /// Up to `max_cells` cells (whole rows, at least one) of the next drone's waiting regions;
    /// `None` when nothing waits or the bus holds the lock right now.
    pub fn take(&self, max_cells: usize) -> Option<Slice> {
        let mut inbox = self.0.try_lock().ok()?;
        let drone = inbox
            .drones
            .range::<String, _>((
                std::ops::Bound::Excluded(&inbox.last),
                std::ops::Bound::Unbounded,
            ))
            .next()
            .or_else(|| inbox.drones.iter().next())
            .map(|(d, _)| d.clone())?;
        inbox.last.clone_from(&drone);
        let p = inbox.drones.get_mut(&drone)?;
        let w = p.region.width_cells() as usize;
        let rows = (max_cells / w.max(1)).max(1);
        let messages = std::mem::take(&mut p.messages);
        if rows >= p.region.height_cells() as usize {
            let p = inbox.drones.remove(&drone)?;
            return Some(Slice {
                node: p.node,
                drone,
                grid: p.grid,
                region: p.region,
                cells: p.cells,
                messages,
            });
        }
        let top = p.region.min.y + rows as u32;
        let region = CellBox {
            min: p.region.min,
            max: Cell {
                x: p.region.max.x,
                y: top - 1,
            },
        };
        let cells: Vec<i8> = p.cells.drain(..rows * w).collect();
        p.region.min.y = top;
        Some(Slice {
            node: p.node.clone(),
            drone,
            grid: p.grid,
            region,
            cells,
            messages,
        })
    }

    /// Drones whose regions wait.
    pub fn waiting(&self) -> usize {
        self.lock().drones.len()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::fleet_bus::wire::{MapHeader, WIRE_VERSION};
    use nalgebra::Vector2;

    fn grid() -> GridSpec {
        GridSpec {
            resolution_m: 0.1,
            width_cells: 10,
            height_cells: 10,
            origin_enu_m: Vector2::new(0.0, 0.0),
        }
    }

    fn boxed(x0: u32, y0: u32, x1: u32, y1: u32) -> CellBox {
        CellBox {
            min: Cell { x: x0, y: y0 },
            max: Cell { x: x1, y: y1 },
        }
    }

    fn msg(drone: &str, region: CellBox, value: i8) -> MapMsg {
        let n = region.width_cells() as usize * region.height_cells() as usize;
        MapMsg {
            header: MapHeader {
                v: WIRE_VERSION,
                node: "b".into(),
                drone: drone.into(),
                seq: 0,
                keyframe: false,
                grid: grid(),
                region,
            },
            cells: vec![value; n],
        }
    }

    #[test]
    fn a_flood_of_regions_coalesces_into_one_grid_per_drone_latest_value_first() {
        let inbox = MapInbox::default();
        for k in 0..1000 {
            inbox
                .offer(msg("d1", grid().full_box(), (k % 100) as i8))
                .unwrap();
        }
        inbox.offer(msg("d1", boxed(0, 0, 1, 0), 7)).unwrap();
        inbox.offer(msg("d2", boxed(2, 2, 3, 3), 50)).unwrap();
        inbox.offer(msg("d2", boxed(5, 5, 5, 5), 60)).unwrap();
        assert_eq!(inbox.waiting(), 2);
        let whole = inbox.take(1000).unwrap();
        assert_eq!((whole.drone.as_str(), whole.messages), ("d1", 1001));
        assert_eq!(whole.cells.len(), 100);
        assert_eq!(&whole.cells[..3], &[7, 7, 99]);
        // d2's two boxes became their union; cells neither set are left as they are.
        let d2 = inbox.take(1000).unwrap();
        assert_eq!(d2.region, boxed(2, 2, 5, 5));
        assert_eq!(d2.cells[0], 50);
        assert_eq!(d2.cells[15], 60);
        assert_eq!(d2.cells.iter().filter(|&&c| c == KEEP).count(), 16 - 5);
        assert!(inbox.take(1000).is_none());
    }

    #[test]
    fn the_loop_takes_a_few_rows_at_a_time_drone_after_drone() {
        let inbox = MapInbox::default();
        inbox.offer(msg("a", grid().full_box(), 0)).unwrap();
        inbox.offer(msg("b", grid().full_box(), 100)).unwrap();
        let order: Vec<(String, u32, u64)> = (0..8)
            .map(|_| {
                let s = inbox.take(25).unwrap();
                assert_eq!(s.cells.len(), 20);
                (s.drone, s.region.min.y, s.messages)
            })
            .collect();
        assert_eq!(order[0], ("a".into(), 0, 1));
        assert_eq!(order[1], ("b".into(), 0, 1));
        assert_eq!(order[2], ("a".into(), 2, 0));
        assert_eq!(order[7], ("b".into(), 6, 0));
        assert_eq!(inbox.take(25).unwrap().region, boxed(0, 8, 9, 9));
    }

    #[test]
    fn the_drones_waiting_are_bounded() {
        let inbox = MapInbox::default();
        for i in 0..MAX_PENDING_DRONES {
            inbox
                .offer(msg(&format!("d{i}"), boxed(0, 0, 0, 0), 0))
                .unwrap();
        }
        assert_eq!(
            inbox.offer(msg("one-more", boxed(0, 0, 0, 0), 0)),
            Err(InboxFull)
        );
        inbox.offer(msg("d0", boxed(1, 1, 1, 1), 0)).unwrap();
    }
}
