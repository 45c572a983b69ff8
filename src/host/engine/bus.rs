//! The host's side of the fleet bus: what it tells other Kestrels and what it takes from them.
//!
//! In: checked [`StateMsg`]s and slices of peers' coalesced map regions ([`Slice`]). Out: this
//! host's drones as a [`StateMsg`] (state, behavior, mission, exploration claim) and its
//! drones' changed map regions (or, for keyframes, everything they know) as [`MapMsg`]s. Remote
//! drones join the fleet view, their map layers the merged map and their claims the frontier
//! allocator; a peer's message that names one of this host's drones, or a map of a drone it does
//! not fly, is refused and counted. Remote layers exist only for the drones the roster gives the
//! other members, so the fleet's configuration bounds them.

use std::time::Duration;

use super::{Host, HostError};
use crate::fleet_bus::inbox::Slice;
use crate::fleet_bus::remote::{Roster, SilencePolicy};
use crate::fleet_bus::wire::{DroneState, MapHeader, MapMsg, StateMsg, WIRE_VERSION};
use crate::mapping::merged::LayerRegion;
use crate::mapping::MapError;
use crate::mission::ExecState;

/// Why a peer's map region was not taken in.
#[derive(Debug, thiserror::Error)]
pub enum BusMapError {
    /// The roster does not give that drone to that node.
    #[error("map of `{drone}` from node `{node}`, which does not fly it")]
    NotItsDrone { drone: String, node: String },
    /// The region does not fit this Kestrel's merged map.
    #[error(transparent)]
    Map(#[from] MapError),
}

impl Host {
    /// Joins a fleet bus: from now on remote drones are heard and this host's map regions kept
    /// for sending.
    /// `roster`: the other members of the fleet and their drones.
    pub fn enable_fleet_bus(&mut self, policy: SilencePolicy, roster: Roster) {
        self.peers.enable(policy, roster);
        if let Some(map) = self.map.as_mut() {
            map.enable_bus();
        }
    }

    /// Refuses to start drone `i` moving while this Kestrel has not joined the peers its
    /// `[fleet] connect` lists (`require_join`): refused by them, or not reaching them, it would
    /// fly unseen by their separation and allocation. A drone already in the air is not held.
    pub(super) fn refuse_before_joining(&self, i: usize) -> Result<(), HostError> {
        let Some(refusal) = self.peers.join_refusal() else {
            return Ok(());
        };
        let airborne = self
            .cores
            .get(i)
            .is_some_and(|c| c.platform_status().flight.is_airborne());
        if airborne {
            return Ok(());
        }
        Err(refusal)
    }

    /// Which node flies `drone`, when another Kestrel does.
    pub fn remote_node_of(&self, drone: &str) -> Option<&str> {
        self.peers.node_of(drone)
    }

    /// Cells of the merged map's grid (bounds a peer's map region); 0 without a map.
    pub fn map_cells(&self) -> usize {
        self.map
            .as_ref()
            .map_or(0, |m| m.merged().spec().cell_count())
    }

    /// Takes in a peer's drones. Returns why some were refused, if any were.
    pub fn apply_bus_state(&mut self, msg: StateMsg) -> Vec<String> {
        let local = self.drone_ids();
        let Some((refused, claims)) = self.peers.apply(msg, self.now, &local) else {
            return Vec::new();
        };
        self.exploration.set_remote_claims(claims);
        refused
    }

    /// Writes a slice of a peer's drone's waiting map regions into its layer (a drone the
    /// roster gives that node: its map may come before its first state).
    pub fn apply_bus_region(&mut self, slice: Slice) -> Result<(), BusMapError> {
        if !self.peers.flies(&slice.node, &slice.drone) {
            return Err(BusMapError::NotItsDrone {
                drone: slice.drone,
                node: slice.node,
            });
        }
        let Some(map) = self.map.as_mut() else {
            return Ok(());
        };
        let region = LayerRegion {
            drone: slice.drone,
            grid: slice.grid,
            region: slice.region,
            cells: slice.cells,
        };
        Ok(map.apply_remote(&region)?)
    }

    /// Layers of the merged map (a re-fused cell visits each).
    pub fn map_layers(&self) -> usize {
        self.map.as_ref().map_or(0, |m| m.layer_count())
    }

    /// This host's drones as the bus carries them.
    pub fn bus_state(&self, node: &str, seq: u64, sent_unix_us: u64) -> StateMsg {
        let drones = self
            .cores
            .iter()
            .zip(self.executors.list())
            .map(|(core, ex)| {
                let view = core.fleet_entry(self.now);
                let status = core.platform_status();
                // Nothing is made up before the autopilot's first position.
                let placed = core.position_age().is_some();
                DroneState {
                    id: core.drone_id().to_string(),
                    position_enu_m: placed.then(|| view.position_enu_m.into()),
                    velocity_enu_mps: placed.then(|| view.velocity_enu_mps.into()),
                    yaw_rad: placed.then_some(view.yaw_rad),
                    flying: view.flying,
                    link: view.link,
                    battery_pct: status
                        .battery
                        .and_then(|b| b.remaining_fraction)
                        .filter(|f| f.is_finite())
                        .map(|f| (f * 100.0).clamp(0.0, 100.0)),
                    behavior: view.motion_behavior.map(|b| b.to_string()),
                    goal_enu_m: view.goal_enu_m.map(Into::into),
                    mission: Some(
                        match ex.status(core).state {
                            ExecState::Idle => "idle",
                            ExecState::Running => "running",
                            ExecState::Paused => "paused",
                        }
                        .to_string(),
                    ),
                    claim_enu_m: self.exploration.claim_of(core.drone_id()),
                }
            })
            .collect();
        StateMsg {
            v: WIRE_VERSION,
            node: node.to_string(),
            seq,
            sent_unix_us,
            drones,
        }
    }

    /// This host's drones' map regions to send: those changed since the last call, or with
    /// `keyframe` everything each drone knows.
    pub fn take_bus_maps(&mut self, node: &str, seq: &mut u64, keyframe: bool) -> Vec<MapMsg> {
        let ids = self.drone_ids();
        let Some(map) = self.map.as_mut() else {
            return Vec::new();
        };
        let changed = map.take_bus_regions();
        let regions: Vec<LayerRegion> = if keyframe {
            ids.iter().filter_map(|d| map.keyframe(d)).collect()
        } else {
            changed
        };
        regions
            .into_iter()
            .map(|r| {
                *seq += 1;
                MapMsg {
                    header: MapHeader {
                        v: WIRE_VERSION,
                        node: node.to_string(),
                        drone: r.drone,
                        seq: *seq,
                        keyframe,
                        grid: r.grid,
                        region: r.region,
                    },
                    cells: r.cells,
                }
            })
            .collect()
    }

    /// The bus's traffic and latency, shown in the snapshot.
    pub fn set_bus_report(&mut self, report: crate::host::status::BusReport) {
        self.peers.set_report(report);
    }

    /// Whether a fleet bus is joined.
    pub fn on_fleet_bus(&self) -> bool {
        self.peers.is_on()
    }

    /// Host time now (for the bus's timers).
    pub fn bus_now(&self) -> Duration {
        self.now
    }
}
