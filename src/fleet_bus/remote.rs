//! The drones other Kestrels fly, as this one last heard them over the fleet bus.
//!
//! In: checked [`StateMsg`]s with the host time they arrived, and this host's own drone ids.
//! Out: fleet-view entries (`local: false`) whose position uncertainty grows while their node is
//! silent (at the fastest this fleet flies, up to `[fleet] silent_keepout_m`), the exploration
//! claims they hold, and a status per remote drone for the API. A state that names one of this
//! host's own drones is refused (a peer cannot move our drones in our view), and at most
//! [`MAX_REMOTE_DRONES`] are kept.

use std::collections::BTreeMap;
use std::sync::Arc;
use std::time::Duration;

use serde::{Deserialize, Serialize};

use super::wire::{DroneState, StateMsg};
use crate::behavior::fleet::DroneView;
use crate::types::{LinkHealth, Vec3};

/// Most remote drones kept (a flood of made-up ids cannot grow the host's memory).
pub const MAX_REMOTE_DRONES: usize = 128;

/// How the host treats silence on the bus.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SilencePolicy {
    /// Not heard for this long: silent.
    pub peer_timeout: Duration,
    /// A silent drone may have flown this fast since (m/s).
    pub max_speed_mps: f64,
    /// At most this far (m): its autopilot's failsafe (PX4 and ArduPilot land or hold when
    /// their companion falls silent) stops it within about this distance.
    pub keepout_cap_m: f64,
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
    pub position_enu_m: [f64; 3],
    pub velocity_enu_mps: [f64; 3],
    pub yaw_rad: f64,
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
}

#[derive(Debug, Clone)]
pub struct RemoteFleet {
    drones: BTreeMap<String, Heard>,
    policy: SilencePolicy,
}

impl RemoteFleet {
    pub fn new(policy: SilencePolicy) -> Self {
        Self {
            drones: BTreeMap::new(),
            policy,
        }
    }

    /// Takes in one node's state. Returns why drones were refused, if any were.
    pub fn apply(&mut self, msg: StateMsg, now: Duration, local: &[String]) -> Vec<String> {
        let mut refused = Vec::new();
        // A node decides which drones it flies: one it no longer announces is gone.
        let announced: Vec<&str> = msg.drones.iter().map(|d| d.id.as_str()).collect();
        self.drones
            .retain(|id, h| h.node != msg.node || announced.contains(&id.as_str()));
        for state in msg.drones {
            if local.contains(&state.id) {
                refused.push(format!(
                    "node `{}` announces `{}`, which this Kestrel flies: ignored",
                    msg.node, state.id
                ));
                continue;
            }
            if let Some(h) = self.drones.get(&state.id) {
                if h.node != msg.node && now.saturating_sub(h.at) < self.policy.peer_timeout {
                    refused.push(format!(
                        "node `{}` announces `{}`, which node `{}` flies: ignored",
                        msg.node, state.id, h.node
                    ));
                    continue;
                }
            } else if self.drones.len() >= MAX_REMOTE_DRONES {
                refused.push(format!(
                    "more than {MAX_REMOTE_DRONES} remote drones: `{}` ignored",
                    state.id
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

    /// Whether `id` is a remote drone, and which node flies it.
    pub fn node_of(&self, id: &str) -> Option<&str> {
        self.drones.get(id).map(|h| h.node.as_str())
    }

    fn age(&self, h: &Heard, now: Duration) -> Duration {
        now.saturating_sub(h.at)
    }

    /// How far a drone heard `age` ago may have gone: at its own speed while its node is heard
    /// regularly, at the fleet's fastest once it is silent, never assumed beyond the cap.
    fn uncertainty_m(&self, state: &DroneState, age: Duration) -> f64 {
        let speed = Vec3::from(state.velocity_enu_mps).norm();
        let timeout = self.policy.peer_timeout.as_secs_f64();
        let age = age.as_secs_f64();
        let gone = if age <= timeout {
            speed * age
        } else {
            speed * timeout + self.policy.max_speed_mps * (age - timeout)
        };
        gone.min(self.policy.keepout_cap_m)
    }

    /// The fleet-view entries of the remote drones at host time `now`.
    pub fn views(&self, now: Duration) -> impl Iterator<Item = DroneView> + '_ {
        self.drones.values().map(move |h| {
            let s = &h.state;
            let age = self.age(h, now);
            DroneView {
                id: s.id.as_str().into(),
                position_enu_m: Vec3::from(s.position_enu_m),
                velocity_enu_mps: Vec3::from(s.velocity_enu_mps),
                yaw_rad: s.yaw_rad,
                flying: s.flying,
                link: s.link,
                motion_behavior: s.behavior.as_deref().map(Arc::from),
                goal_enu_m: s.goal_enu_m.map(Vec3::from),
                stamp: h.at,
                local: false,
                uncertainty_m: self.uncertainty_m(s, age),
                silent: age > self.policy.peer_timeout,
            }
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
        self.drones
            .values()
            .map(|h| {
                let s = &h.state;
                let age = self.age(h, now);
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
                    age_s: age.as_secs_f64(),
                    silent: age > self.policy.peer_timeout,
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    #![allow(clippy::unwrap_used)]
    use super::*;
    use crate::fleet_bus::wire::WIRE_VERSION;

    fn policy() -> SilencePolicy {
        SilencePolicy {
            peer_timeout: Duration::from_millis(1500),
            max_speed_mps: 0.75,
            keepout_cap_m: 1.5,
        }
    }

    fn drone(id: &str, x: f64) -> DroneState {
        DroneState {
            id: id.into(),
            position_enu_m: [x, 0.0, 1.0],
            velocity_enu_mps: [0.5, 0.0, 0.0],
            yaw_rad: 0.0,
            flying: true,
            link: LinkHealth::Ok,
            battery_pct: None,
            behavior: None,
            goal_enu_m: None,
            mission: None,
            claim_enu_m: Some([x + 1.0, 0.0]),
        }
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
    fn a_silent_drone_may_be_anywhere_it_could_have_flown_up_to_the_cap() {
        let mut r = RemoteFleet::new(policy());
        let t0 = Duration::from_secs(10);
        assert!(r
            .apply(msg("b", vec![drone("drone_1", 2.0)]), t0, &[])
            .is_empty());
        let at = |t: f64| r.views(t0 + Duration::from_secs_f64(t)).next().unwrap();
        // Heard regularly: as far as its own speed (0.5 m/s) took it since.
        let fresh = at(0.1);
        assert!(!fresh.local && !fresh.silent);
        assert!((fresh.uncertainty_m - 0.05).abs() < 1e-9);
        // Silent: from then on at the fleet's fastest (0.75 m/s).
        let quiet = at(1.6);
        assert!(quiet.silent);
        assert!((quiet.uncertainty_m - (0.75 + 0.075)).abs() < 1e-9);
        assert!((at(60.0).uncertainty_m - 1.5).abs() < 1e-9, "capped");
        assert_eq!(r.claims(), vec![(Arc::from("drone_1"), [3.0, 0.0], t0)]);
    }

    #[test]
    fn a_peer_cannot_announce_our_drones_or_steal_anothers() {
        let mut r = RemoteFleet::new(policy());
        let t = Duration::from_secs(1);
        let refused = r.apply(
            msg("b", vec![drone("drone_0", 0.0)]),
            t,
            &["drone_0".into()],
        );
        assert_eq!(refused.len(), 1);
        assert!(r.is_empty());
        r.apply(msg("b", vec![drone("drone_1", 0.0)]), t, &[]);
        let refused = r.apply(msg("c", vec![drone("drone_1", 5.0)]), t, &[]);
        assert_eq!(refused.len(), 1);
        assert_eq!(r.node_of("drone_1"), Some("b"));
        // Once `b` fell silent, `c` may take the id over (a drone moved to another computer).
        r.apply(
            msg("c", vec![drone("drone_1", 5.0)]),
            t + Duration::from_secs(5),
            &[],
        );
        assert_eq!(r.node_of("drone_1"), Some("c"));
        // A node that stops announcing a drone drops it.
        r.apply(msg("c", vec![]), t + Duration::from_secs(6), &[]);
        assert!(r.is_empty());
    }

    #[test]
    fn the_number_of_remote_drones_is_bounded() {
        let mut r = RemoteFleet::new(policy());
        for n in 0..(MAX_REMOTE_DRONES / 16 + 2) {
            let drones = (0..16).map(|i| drone(&format!("d{n}_{i}"), 0.0)).collect();
            r.apply(msg(&format!("n{n}"), drones), Duration::ZERO, &[]);
        }
        assert_eq!(r.statuses(Duration::ZERO).len(), MAX_REMOTE_DRONES);
    }
}
