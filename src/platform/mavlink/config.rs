//! The `[mavlink]` section of the config file: where the autopilot is and how to treat it.
//!
//! In: TOML (unknown keys refused). Out: the profile path, the connection and forwarding
//! strings, the `udpin` [`PeerPolicy`] and the [`SessionConfig`] (our ids, link policy, EKF
//! origin).

use super::peer::{PeerPattern, PeerPolicy, REPIN_AFTER};
use super::session::SessionConfig;
use crate::types::GeoPoint;
use serde::{Deserialize, Serialize};
use std::time::Duration;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MavlinkSection {
    /// Autopilot profile: a built-in name (`px4`, the default; `ardupilot-copter`; `sim`) or a
    /// file (`platforms/px4.toml`; a relative path not found from the working directory is
    /// looked up under /usr/share/kestrel, see `kestrel run --help`). `kestrel run --platform`
    /// overrides it.
    pub platform: String,
    /// `udpin:0.0.0.0:14540`, `udpout:HOST:PORT`, `tcpout:HOST:PORT`, `tcpin:ADDR:PORT`,
    /// `serial:/dev/ttyACM0:921600`. `kestrel run --connection` overrides it.
    pub connection: String,
    /// Our MAVLink system id; absent = the vehicle's (PX4 counts companion heartbeats only then).
    pub system_id: Option<u8>,
    /// Our component id (191 = onboard computer).
    pub component_id: u8,
    /// Follow only this autopilot system id; absent = the first autopilot heard, replaced by
    /// another only after it falls silent (heartbeat timeout).
    pub target_system: Option<u8>,
    /// Moved to `[mission] on_link_regained` (the mission executor decides for every platform);
    /// kept here only to refuse it with that advice.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub on_link_regained: Option<toml::Value>,
    /// EKF origin for flying without GPS (ArduPilot refuses GUIDED without one).
    pub ekf_origin: Option<GeoPoint>,
    /// Ground station endpoints that get the autopilot's stream, e.g. `udpout:127.0.0.1:14550`.
    pub forward: Vec<String>,
    /// `udpin` only: answer only the address the autopilot's HEARTBEAT came from, and ignore
    /// datagrams from any other (another may take its place only as `repin_after_s` says).
    /// `false` answers whoever sent last (any host that can reach the port can then take the
    /// link).
    pub pin_peer: bool,
    /// `udpin` only: how long the pinned address must be silent before another address may
    /// take its place (s, 5..=86 400; default 30), and then only for the same autopilot system,
    /// last heard disarmed and on the ground. Each change is logged and shown in the API.
    pub repin_after_s: f64,
    /// `udpin` only: the addresses that may be heard at all, `IP` (any port) or `IP:port`, e.g.
    /// a GCS router's `["127.0.0.1:14580"]`; empty = any.
    pub allowed_peers: Vec<String>,
}

impl Default for MavlinkSection {
    fn default() -> Self {
        Self {
            platform: "px4".into(),
            connection: "udpin:0.0.0.0:14540".into(),
            system_id: None,
            component_id: 191,
            target_system: None,
            on_link_regained: None,
            ekf_origin: None,
            forward: Vec::new(),
            pin_peer: true,
            repin_after_s: REPIN_AFTER.as_secs_f64(),
            allowed_peers: Vec::new(),
        }
    }
}

impl MavlinkSection {
    /// Checks the fields; `Err((field, message))`.
    pub fn validate(&self) -> Result<(), (String, String)> {
        let address = |field: &str, s: &str| {
            mavlink::ConnectionAddress::parse_address(s)
                .map(|_| ())
                .map_err(|e| (field.to_string(), format!("`{s}`: {e}")))
        };
        address("mavlink.connection", &self.connection)?;
        for f in &self.forward {
            address("mavlink.forward", f)?;
        }
        for p in &self.allowed_peers {
            PeerPattern::parse(p)
                .map_err(|e| ("mavlink.allowed_peers".to_string(), e.to_string()))?;
        }
        if self.on_link_regained.is_some() {
            return Err((
                "mavlink.on_link_regained".into(),
                "moved to [mission] on_link_regained (land, hold or resume)".into(),
            ));
        }
        if !(5.0..=86_400.0).contains(&self.repin_after_s) {
            return Err((
                "mavlink.repin_after_s".into(),
                format!("{} s: must be 5..=86400 s", self.repin_after_s),
            ));
        }
        if self.component_id == 0 {
            return Err(("mavlink.component_id".into(), "must be 1..=255".into()));
        }
        if let Some(o) = &self.ekf_origin {
            o.validate()
                .map_err(|e| ("mavlink.ekf_origin".to_string(), e.to_string()))?;
        }
        Ok(())
    }

    /// The `udpin` peer policy (patterns that do not parse were refused by `validate`).
    pub fn peer_policy(&self) -> PeerPolicy {
        PeerPolicy {
            pin: self.pin_peer,
            allowed: self
                .allowed_peers
                .iter()
                .filter_map(|p| PeerPattern::parse(p).ok())
                .collect(),
            target_system: self.target_system,
            repin_after: Duration::from_secs_f64(self.repin_after_s.clamp(5.0, 86_400.0)),
        }
    }

    pub fn session_config(&self) -> SessionConfig {
        SessionConfig {
            system_id: self.system_id,
            component_id: self.component_id,
            target_system: self.target_system,
            ekf_origin: self.ekf_origin,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn udpin_peers_are_pinned_by_default_and_allowed_peers_must_be_addresses() {
        let default = MavlinkSection::default();
        assert!(default.peer_policy().pin);
        let section: MavlinkSection = toml::from_str(
            "target_system = 3\nallowed_peers = [\"127.0.0.1:14580\", \"10.0.0.2\"]",
        )
        .unwrap();
        assert_eq!(section.validate(), Ok(()));
        let policy = section.peer_policy();
        assert_eq!((policy.allowed.len(), policy.target_system), (2, Some(3)));
        let bad: MavlinkSection = toml::from_str("allowed_peers = [\"gcs.local\"]").unwrap();
        let (field, message) = bad.validate().unwrap_err();
        assert_eq!(field, "mavlink.allowed_peers");
        assert!(message.contains("gcs.local"), "{message}");
    }

    #[test]
    fn repin_after_s_is_bounded_and_reaches_the_policy() {
        let section: MavlinkSection = toml::from_str("repin_after_s = 120.0").unwrap();
        assert_eq!(section.validate(), Ok(()));
        assert_eq!(section.peer_policy().repin_after, Duration::from_secs(120));
        for bad in ["repin_after_s = 1.0", "repin_after_s = nan"] {
            let section: MavlinkSection = toml::from_str(bad).unwrap();
            let (field, message) = section.validate().unwrap_err();
            assert_eq!(field, "mavlink.repin_after_s", "{bad}");
            assert!(message.contains("5..=86400"), "{message}");
        }
    }
}
