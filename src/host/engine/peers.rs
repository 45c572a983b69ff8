//! The host's fleet-bus link: the drones other Kestrels fly, as last heard, and the bus's last
//! report. Without a bus it hears nothing and holds nothing back.
//!
//! In: peers' checked states, the bus's reports. Out: the remote drones for the fleet view and
//! the API, their exploration claims, which node flies a drone, and the refusal to start a
//! drone while this Kestrel has not joined its fleet.

use super::HostError;
use crate::exploration::online::service::RemoteClaim;
use crate::fleet_bus::remote::{RemoteDroneStatus, RemoteFleet, Roster, SilencePolicy};
use crate::fleet_bus::wire::StateMsg;
use crate::host::status::BusReport;
use crate::types::{DroneView, Vec3};
use std::time::Duration;

#[derive(Default)]
pub(super) struct Peers {
    /// The drones other Kestrels fly (`None`: no bus).
    remote: Option<RemoteFleet>,
    /// The bus's last report, for the snapshot and the join check.
    report: Option<BusReport>,
}

impl Peers {
    /// Joins a bus: `roster` names the other members and their drones.
    pub(super) fn enable(&mut self, policy: SilencePolicy, roster: Roster) {
        self.remote = Some(RemoteFleet::new(policy, roster));
    }

    pub(super) fn is_on(&self) -> bool {
        self.remote.is_some()
    }

    /// Which node flies `drone`, once it was heard.
    pub(super) fn node_of(&self, drone: &str) -> Option<&str> {
        self.remote.as_ref()?.node_of(drone)
    }

    /// Whether the roster gives `drone` to `node`.
    pub(super) fn flies(&self, node: &str, drone: &str) -> bool {
        self.remote.as_ref().and_then(|r| r.owner_of(drone)) == Some(node)
    }

    /// Takes in a peer's drones (`local`: this host's own, which no peer may announce). Returns
    /// why some were refused and the claims the remote drones now hold; `None` without a bus.
    pub(super) fn apply(
        &mut self,
        msg: StateMsg,
        now: Duration,
        local: &[String],
    ) -> Option<(Vec<String>, Vec<RemoteClaim>)> {
        let remote = self.remote.as_mut()?;
        let refused = remote.apply(msg, now, local);
        let claims = remote
            .claims()
            .into_iter()
            .map(|(drone, goal, heard)| (drone, Vec3::new(goal[0], goal[1], 0.0), heard))
            .collect();
        Some((refused, claims))
    }

    /// The remote drones' fleet-view entries at host time `now`.
    pub(super) fn views(&self, now: Duration) -> impl Iterator<Item = DroneView> + '_ {
        self.remote.iter().flat_map(move |r| r.views(now))
    }

    /// The remote drones as the API shows them at host time `now`.
    pub(super) fn statuses(&self, now: Duration) -> Vec<RemoteDroneStatus> {
        self.remote
            .as_ref()
            .map(|r| r.statuses(now))
            .unwrap_or_default()
    }

    pub(super) fn set_report(&mut self, report: BusReport) {
        self.report = Some(report);
    }

    pub(super) fn report(&self) -> Option<&BusReport> {
        self.report.as_ref()
    }

    /// Why a drone on the ground may not start moving: this Kestrel must join its fleet first
    /// (`require_join`) and has not yet; `None` when it may.
    pub(super) fn join_refusal(&self) -> Option<HostError> {
        let report = self
            .report
            .as_ref()
            .filter(|r| r.join_required && !r.joined)?;
        Some(HostError::FleetNotJoined {
            fleet: report.fleet.clone(),
            waiting_for: report.waiting_for.join(", "),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fleet_bus::wire::{DroneState, WIRE_VERSION};

    fn s(t: u64) -> Duration {
        Duration::from_secs(t)
    }

    fn enabled() -> Peers {
        let policy = SilencePolicy {
            peer_timeout: s(2),
            lost_after: s(10),
            keepout_m: 3.0,
        };
        let roster = [("node_b".to_string(), vec!["drone_9".to_string()])].into();
        let mut peers = Peers::default();
        peers.enable(policy, roster);
        peers
    }

    fn state(node: &str, drones: Vec<DroneState>) -> StateMsg {
        StateMsg {
            v: WIRE_VERSION,
            node: node.into(),
            seq: 1,
            sent_unix_us: 0,
            drones,
        }
    }

    fn report(join_required: bool, joined: bool) -> BusReport {
        BusReport {
            fleet: "survey".into(),
            node: "node_a".into(),
            state_sent: 0,
            state_sent_bytes: 0,
            map_sent: 0,
            map_sent_bytes: 0,
            received: 0,
            received_bytes: 0,
            refused: 0,
            dropped: 0,
            latency_samples: 0,
            latency_p50_ms: None,
            latency_p99_ms: None,
            joined,
            join_required,
            refused_joins: 0,
            waiting_for: vec!["node_b (no answer)".into(), "node_c (refused)".into()],
        }
    }

    /// Without a bus nothing is heard, nothing is taken in and nothing is held back.
    #[test]
    fn without_a_bus_it_hears_nothing() {
        let mut peers = Peers::default();
        assert!(!peers.is_on());
        let msg = state(
            "node_b",
            vec![DroneState::at_rest("drone_9", [0.0; 3], true)],
        );
        assert!(peers.apply(msg, s(1), &[]).is_none());
        assert_eq!(peers.views(s(1)).count(), 0);
        assert!(peers.statuses(s(1)).is_empty());
        assert_eq!(peers.node_of("drone_9"), None);
        assert!(!peers.flies("node_b", "drone_9"));
        assert!(peers.join_refusal().is_none());
    }

    /// A peer's drone is heard with its claim (on the ground plane); one that the roster does
    /// not give it is refused, and this host's own drone can never be announced.
    #[test]
    fn a_peer_is_heard_for_its_own_drones_only() {
        let mut peers = enabled();
        assert!(peers.is_on());
        assert!(peers.flies("node_b", "drone_9"));
        assert!(!peers.flies("node_c", "drone_9"));
        let claiming = DroneState {
            claim_enu_m: Some([4.0, 5.0]),
            ..DroneState::at_rest("drone_9", [1.0, 2.0, 3.0], true)
        };
        let own = DroneState::at_rest("drone_0", [0.0; 3], false);
        let (refused, claims) = peers
            .apply(
                state("node_b", vec![claiming, own]),
                s(1),
                &["drone_0".into()],
            )
            .unwrap();
        assert_eq!(refused.len(), 1, "{refused:?}");
        assert!(refused[0].contains("drone_0"), "{refused:?}");
        assert_eq!(claims.len(), 1);
        assert_eq!(
            (&*claims[0].0, claims[0].1, claims[0].2),
            ("drone_9", Vec3::new(4.0, 5.0, 0.0), s(1))
        );
        assert_eq!(peers.node_of("drone_9"), Some("node_b"));
        assert_eq!(peers.node_of("drone_0"), None);
        assert_eq!(peers.views(s(1)).count(), 1);
        assert_eq!(peers.statuses(s(1)).len(), 1);
    }

    /// Starting is refused only while a join is required and not done; the refusal names the
    /// fleet and every peer waited for.
    #[test]
    fn starting_waits_for_a_required_join() {
        let mut peers = enabled();
        assert!(peers.join_refusal().is_none());
        peers.set_report(report(false, false));
        assert!(peers.join_refusal().is_none());
        peers.set_report(report(true, true));
        assert!(peers.join_refusal().is_none());
        peers.set_report(report(true, false));
        assert_eq!(
            peers.join_refusal(),
            Some(HostError::FleetNotJoined {
                fleet: "survey".into(),
                waiting_for: "node_b (no answer), node_c (refused)".into(),
            })
        );
        assert_eq!(peers.report().map(|r| r.node.as_str()), Some("node_a"));
    }
}
