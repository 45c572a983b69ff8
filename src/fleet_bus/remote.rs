//! The drones other Kestrels fly, as this one last heard them over the fleet bus, and what this
//! Kestrel may assume about the ones that fell silent.
//!
//! In: checked [`StateMsg`]s with the host time they arrived, and this host's own drone ids.
//! Out: fleet-view entries (`local: false`), the exploration claims they hold, and a status per
//! remote drone for the API. Only the roster's members are heard, each for the drones the roster
//! gives it: a state from any other node, or naming a drone that is not its node's (one of this
//! host's own included), is refused. The roster holds at most [`MAX_REMOTE_DRONES`] drones.
//!
//! Silence, and why it is safe. A peer's drone not heard for `peer_timeout` is `silent`. While a
//! silent drone was flying and is not accounted for, nobody knows where it goes, so every Kestrel
//! holds its flying drones where they are (`unaccounted`: the safety stage holds) — and a peer
//! that is alive but cut off does the same, since it hears us fall silent too: nothing moves
//! toward anything. A silent drone is accounted for once it has been silent for `lost_after` and
//! this Kestrel still hears more than half of the roster's nodes (itself included): the
//! majority. It is counted over the roster, never over the names heard, so made-up nodes can
//! neither join the count nor hold anything. Either the peer is dead (its autopilot's failsafe has landed or held the drone where
//! it was) or it is cut off in a minority, where it keeps holding (it never hears a majority).
//! Both leave the drone where it was last heard: from then on the majority flies again and keeps
//! `[safety] min_separation_m` plus `keepout_m` from that point. An isolated Kestrel (no
//! majority) never presumes anything and holds until the bus is back.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::wire::{DroneState, StateMsg};
use crate::types::DroneView;
use crate::types::{LinkHealth, Vec3};

/// Most drones a roster may give the other nodes (each has a map layer on every node).
pub const MAX_REMOTE_DRONES: usize = 128;

/// How the host treats silence on the bus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SilencePolicy {
    /// Not heard for this long: silent.
    pub peer_timeout: Duration,
    /// Silent this long while the majority is heard: accounted for, where it was last heard.
    pub lost_after: Duration,
    /// Kept from a drone accounted for, on top of the separation (m): how far its autopilot's
    /// failsafe may carry it while it stops or lands.
    pub keepout_m: f64,
}

/// One remote drone, as last heard.
#[derive(Debug, Clone, PartialEq)]
struct Heard {
    node: String,
    state: DroneState,
    at: Duration,
}

/// A remote drone as the API shows it.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize, utoipa::ToSchema)]
pub struct RemoteDroneStatus {
    pub id: String,
    /// The Kestrel that flies it.
    pub node: String,
    /// `null` until its autopilot has given a position (all three).
    pub position_enu_m: Option<[f64; 3]>,
    pub velocity_enu_mps: Option<[f64; 3]>,
    pub yaw_rad: Option<f64>,
    pub flying: bool,
    /// Its node's link to its autopilot.
    #[schema(value_type = String)]
    pub link: LinkHealth,
    pub battery_pct: Option<f64>,
    pub behavior: Option<String>,
    pub mission: Option<String>,
    /// Seconds since its node was last heard.
    pub age_s: f64,
    /// Not heard for longer than `[fleet] peer_timeout_s`.
    pub silent: bool,
    /// Silent while flying and not accounted for yet: this Kestrel's flying drones hold.
    pub unaccounted: bool,
}

/// The other members of the fleet: node name → the drones it flies.
pub type Roster = BTreeMap<String, Vec<String>>;

#[derive(Debug, Clone)]
pub struct RemoteFleet {
    drones: BTreeMap<String, Heard>,
    /// The roster's other nodes, and when each was last heard: the fleet's size for the
    /// majority.
    nodes: BTreeMap<String, Option<Duration>>,
    roster: Roster,
    policy: SilencePolicy,
}

impl RemoteFleet {
    /// `roster`: the other members (this node left out).
    pub fn new(policy: SilencePolicy, roster: Roster) -> Self {
        Self {
            drones: BTreeMap::new(),
            nodes: roster.keys().map(|n| (n.clone(), None)).collect(),
            roster,
            policy,
        }
    }

    /// Whether this Kestrel hears more than half of the roster's nodes, itself included.
    pub fn in_majority(&self, now: Duration) -> bool {
        let heard = self
            .nodes
            .values()
            .flatten()
            .filter(|&&at| now.saturating_sub(at) <= self.policy.peer_timeout)
            .count();
        2 * (1 + heard) > 1 + self.nodes.len()
    }

    /// The member that flies `drone`, by the roster.
    pub fn owner_of(&self, drone: &str) -> Option<&str> {
        self.roster
            .iter()
            .find(|(_, drones)| drones.iter().any(|d| d == drone))
            .map(|(node, _)| node.as_str())
    }

    /// Takes in one node's state. Returns why drones were refused, if any were.
    pub fn apply(&mut self, msg: StateMsg, now: Duration, local: &[String]) -> Vec<String> {
        let Some(heard) = self.nodes.get_mut(&msg.node) else {
            return vec![format!(
                "node `{}` is not in the roster: its state is ignored",
                msg.node
            )];
        };
        *heard = Some(now);
        let mut refused = Vec::new();
        // A node decides which drones it flies: one it no longer announces is gone.
        let announced: Vec<&str> = msg.drones.iter().map(|d| d.id.as_str()).collect();
        self.drones
            .retain(|id, h| h.node != msg.node || announced.contains(&id.as_str()));
        for state in msg.drones {
            if local.contains(&state.id) || self.owner_of(&state.id) != Some(msg.node.as_str()) {
                refused.push(format!(
                    "node `{}` announces `{}`, which the roster does not give it: ignored",
                    msg.node, state.id
                ));
                continue;
            }
            self.drones.insert(
                state.id.clone(),
                Heard {
                    node: msg.node.clone(),
                    state,
                    at: now,
                },
            );
        }
        refused
    }

    pub fn is_empty(&self) -> bool {
        self.drones.is_empty()
    }

    /// Remote drones kept.
    pub fn len(&self) -> usize {
        self.drones.len()
    }

    /// Whether `id` is a remote drone, and which node flies it.
    pub fn node_of(&self, id: &str) -> Option<&str> {
        self.drones.get(id).map(|h| h.node.as_str())
    }

    fn age(&self, h: &Heard, now: Duration) -> Duration {
        now.saturating_sub(h.at)
    }

    /// How far a drone heard `age` ago may be from where it was heard: as far as its own speed
    /// takes it while it is heard; once accounted for, the keep-out.
    fn uncertainty_m(&self, state: &DroneState, age: Duration, accounted: bool) -> f64 {
        if accounted {
            return self.policy.keepout_m;
        }
        state
            .velocity_enu_mps
            .map_or(0.0, |v| Vec3::from(v).norm() * age.as_secs_f64())
    }

    /// How `h` stands at host time `now`: silent, and whether the majority accounts for it.
    fn silence(&self, h: &Heard, now: Duration, majority: bool) -> Silence {
        let age = self.age(h, now);
        let silent = age > self.policy.peer_timeout;
        let accounted = silent && majority && age >= self.policy.lost_after;
        Silence {
            age,
            silent,
            accounted,
            unaccounted: silent && !accounted && h.state.flying,
        }
    }

    /// The fleet-view entries of the remote drones at host time `now`. A drone whose autopilot
    /// has not given a position yet is not among them: there is nowhere to keep apart from.
    pub fn views(&self, now: Duration) -> impl Iterator<Item = DroneView> + '_ {
        let majority = self.in_majority(now);
        self.drones.values().filter_map(move |h| {
            let s = &h.state;
            let q = self.silence(h, now, majority);
            Some(DroneView {
                id: s.id.as_str().into(),
                position_enu_m: Vec3::from(s.position_enu_m?),
                velocity_enu_mps: Vec3::from(s.velocity_enu_mps?),
                yaw_rad: s.yaw_rad?,
                flying: s.flying,
                link: s.link,
                motion_behavior: s.behavior.as_deref().map(Arc::from),
                goal_enu_m: s.goal_enu_m.map(Vec3::from),
                stamp: h.at,
                local: false,
                uncertainty_m: self.uncertainty_m(s, q.age, q.accounted),
                silent: q.silent,
                unaccounted: q.unaccounted,
            })
        })
    }

    /// The exploration goals remote drones hold, with when they were last heard.
    pub fn claims(&self) -> Vec<(Arc<str>, [f64; 2], Duration)> {
        self.drones
            .values()
            .filter_map(|h| Some((Arc::from(h.state.id.as_str()), h.state.claim_enu_m?, h.at)))
            .collect()
    }

    pub fn statuses(&self, now: Duration) -> Vec<RemoteDroneStatus> {
        let majority = self.in_majority(now);
        self.drones
            .values()
            .map(|h| {
                let s = &h.state;
                let q = self.silence(h, now, majority);
                RemoteDroneStatus {
                    id: s.id.clone(),
                    node: h.node.clone(),
                    position_enu_m: s.position_enu_m,
                    velocity_enu_mps: s.velocity_enu_mps,
                    yaw_rad: s.yaw_rad,
                    flying: s.flying,
                    link: s.link,
                    battery_pct: s.battery_pct,
                    behavior: s.behavior.clone(),
                    mission: s.mission.clone(),
                    age_s: q.age.as_secs_f64(),
                    silent: q.silent,
                    unaccounted: q.unaccounted,
                }
            })
            .collect()
    }
}

/// How long a remote drone has not been heard, and what that means for the fleet.
struct Silence {
    age: Duration,
    silent: bool,
    accounted: bool,
    unaccounted: bool,
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::fleet_bus::wire::WIRE_VERSION;

    fn policy() -> SilencePolicy {
        SilencePolicy {
            peer_timeout: Duration::from_millis(1500),
            lost_after: Duration::from_secs(10),
            keepout_m: 1.5,
        }
    }

    fn drone(id: &str, x: f64) -> DroneState {
        DroneState {
            velocity_enu_mps: Some([0.5, 0.0, 0.0]),
            claim_enu_m: Some([x + 1.0, 0.0]),
            ..DroneState::at_rest(id, [x, 0.0, 1.0], true)
        }
    }

    fn roster(members: &[(&str, &[&str])]) -> Roster {
        members
            .iter()
            .map(|(n, ds)| (n.to_string(), ds.iter().map(|d| d.to_string()).collect()))
            .collect()
    }

    fn msg(node: &str, drones: Vec<DroneState>) -> StateMsg {
        StateMsg {
            v: WIRE_VERSION,
            node: node.into(),
            seq: 0,
            sent_unix_us: 0,
            drones,
        }
    }

    #[test]
    fn a_silent_flying_drone_holds_the_fleet_until_the_majority_accounts_for_it() {
        let mut r = RemoteFleet::new(
            policy(),
            roster(&[("b", &["drone_1"]), ("c", &["drone_2", "drone_3"])]),
        );
        let t0 = Duration::from_secs(10);
        let s = Duration::from_secs_f64;
        assert!(r
            .apply(msg("b", vec![drone("drone_1", 2.0)]), t0, &[])
            .is_empty());
        r.apply(msg("c", vec![drone("drone_2", 9.0)]), t0, &[]);
        let view =
            |r: &RemoteFleet, t: f64, id: &str| r.views(t0 + s(t)).find(|v| &*v.id == id).unwrap();
        // Heard regularly: as far as its own speed (0.5 m/s) took it since.
        let fresh = view(&r, 0.1, "drone_1");
        assert!(!fresh.local && !fresh.silent && !fresh.unaccounted);
        assert!((fresh.uncertainty_m - 0.05).abs() < 1e-9);
        // `b` falls silent while `c` is still heard: its drone holds everyone until `lost_after`.
        for k in 1..=12 {
            r.apply(
                msg("c", vec![drone("drone_2", 9.0)]),
                t0 + s(f64::from(k)),
                &[],
            );
        }
        let quiet = view(&r, 5.0, "drone_1");
        assert!(quiet.silent && quiet.unaccounted);
        // Then, with `c` (two of the roster's three nodes heard: the majority), it is where it
        // was heard.
        assert!(r.in_majority(t0 + s(12.0)));
        let accounted = view(&r, 12.0, "drone_1");
        assert!(accounted.silent && !accounted.unaccounted);
        assert!((accounted.uncertainty_m - 1.5).abs() < 1e-9);
        assert_eq!(accounted.position_enu_m, Vec3::new(2.0, 0.0, 1.0));
        // Cut off from both (a minority of one), nothing is ever presumed: hold until heard.
        assert!(!r.in_majority(t0 + s(60.0)));
        assert!(view(&r, 60.0, "drone_1").unaccounted && view(&r, 60.0, "drone_2").unaccounted);
        // A drone on the ground that falls silent holds nobody.
        let mut landed = drone("drone_3", 0.0);
        landed.flying = false;
        r.apply(msg("c", vec![landed]), t0 + s(60.0), &[]);
        assert!(!view(&r, 65.0, "drone_3").unaccounted);
        assert_eq!(r.claims().len(), 2);
    }

    #[test]
    fn a_drone_without_a_position_is_listed_but_kept_out_of_the_fleet_view() {
        let mut r = RemoteFleet::new(policy(), roster(&[("b", &["drone_1", "drone_2"])]));
        let t0 = Duration::from_secs(1);
        let unplaced = DroneState {
            position_enu_m: None,
            velocity_enu_mps: None,
            yaw_rad: None,
            ..DroneState::at_rest("drone_2", [0.0; 3], false)
        };
        r.apply(msg("b", vec![drone("drone_1", 2.0), unplaced]), t0, &[]);
        let ids: Vec<_> = r.views(t0).map(|v| v.id.to_string()).collect();
        assert_eq!(ids, ["drone_1"]);
        let statuses = r.statuses(t0);
        assert_eq!(statuses.len(), 2);
        let listed = statuses.iter().find(|s| s.id == "drone_2").unwrap();
        assert_eq!(
            (listed.position_enu_m, listed.velocity_enu_mps, listed.yaw_rad),
            (None, None, None)
        );
        let json = serde_json::to_value(listed).unwrap();
        assert!(json["position_enu_m"].is_null(), "{json}");
    }

    #[test]
    fn a_node_speaks_only_for_the_drones_the_roster_gives_it() {
        let mut r = RemoteFleet::new(
            policy(),
            roster(&[("b", &["drone_1"]), ("c", &["drone_2"])]),
        );
        let t = Duration::from_secs(1);
        let refused = r.apply(
            msg("b", vec![drone("drone_0", 0.0)]),
            t,
            &["drone_0".into()],
        );
        assert_eq!(refused.len(), 1);
        assert!(r.is_empty());
        r.apply(msg("b", vec![drone("drone_1", 0.0)]), t, &[]);
        // Not even once `b` fell silent may `c` take `drone_1` over.
        let later = t + Duration::from_secs(30);
        let refused = r.apply(msg("c", vec![drone("drone_1", 5.0)]), later, &[]);
        assert_eq!(refused.len(), 1, "{refused:?}");
        assert_eq!(r.node_of("drone_1"), Some("b"));
        assert_eq!(r.owner_of("drone_2"), Some("c"));
        // A node that stops announcing a drone drops it.
        r.apply(msg("b", vec![]), later, &[]);
        assert!(r.is_empty());
    }

    /// Issue 29, item 2: names heard are not the fleet. 1 500 made-up nodes announcing flying
    /// drones are refused, hold nobody and never change the majority; a member's drone that
    /// fell silent in flight holds the fleet no longer than `lost_after`.
    #[test]
    fn made_up_nodes_never_hold_the_fleet_longer_than_lost_after() {
        let mut r = RemoteFleet::new(
            policy(),
            roster(&[("b", &["drone_1"]), ("c", &["drone_2"])]),
        );
        let t0 = Duration::from_secs(1);
        let s = Duration::from_secs_f64;
        r.apply(msg("b", vec![drone("drone_1", 0.0)]), t0, &[]);
        for n in 0..1500 {
            let refused = r.apply(
                msg(&format!("made-up-{n}"), vec![drone(&format!("x{n}"), 1.0)]),
                t0,
                &[],
            );
            assert_eq!(refused.len(), 1);
        }
        assert_eq!(r.len(), 1);
        assert_eq!(r.nodes.len(), 2);
        // `b` falls silent in flight; `c` is heard all along.
        let mut t = 0.0;
        while t < 20.0 {
            t += 0.5;
            r.apply(msg("c", vec![drone("drone_2", 5.0)]), t0 + s(t), &[]);
            let holds = r.views(t0 + s(t)).any(|v| v.unaccounted);
            let lost_after = policy().lost_after.as_secs_f64();
            assert_eq!(holds, t > 1.5 && t < lost_after, "at {t} s");
        }
    }
}
