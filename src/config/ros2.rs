//! The `[ros2]` section: whether this Kestrel shows its drones to ROS 2 (rmw_zenoh), under which
//! domain and namespace, which Zenoh router it connects to, and how often it publishes.
//!
//! In: TOML (unknown keys refused). Out: [`Ros2Section::validate`] → `Err((field, message))`
//! naming the field: a domain out of ROS's range, a namespace or node name that is not a ROS
//! name, an endpoint that is not `tcp/HOST:PORT`, a rate or speed out of bounds.

use serde::{Deserialize, Serialize};

/// Highest ROS domain id (ROS 2's own limit for DDS; kept with rmw_zenoh too).
pub const MAX_DOMAIN_ID: u32 = 232;
/// Most routers in `connect`.
pub const MAX_ENDPOINTS: usize = 8;
/// Longest namespace or node name.
pub const MAX_NAME_LEN: usize = 128;

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Ros2Section {
    /// Publish the drones as ROS 2 topics over rmw_zenoh (off by default).
    pub enabled: bool,
    /// `ROS_DOMAIN_ID` of the ROS 2 machines that should see Kestrel.
    pub domain_id: u32,
    /// Namespace of every topic but `/tf` and `/map` (`""` or `/fleet_a`); each drone's topics
    /// are `<namespace>/<drone id>/pose` and so on.
    pub namespace: String,
    /// The ROS node Kestrel appears as.
    pub node: String,
    /// Zenoh routers to connect to (`tcp/127.0.0.1:7447`: the `rmw_zenohd` of a ROS 2 machine).
    pub connect: Vec<String>,
    /// Poses, odometry, frames and paths sent per second and drone.
    pub rate_hz: f64,
    /// `/map` sent at most this often, and only when it changed (Hz).
    pub map_rate_hz: f64,
    /// Speed of a flight to a `goal_pose` (m/s).
    pub goal_speed_mps: f64,
}

impl Default for Ros2Section {
    fn default() -> Self {
        Self {
            enabled: false,
            domain_id: 0,
            namespace: String::new(),
            node: "kestrel".into(),
            connect: vec!["tcp/127.0.0.1:7447".into()],
            rate_hz: 10.0,
            map_rate_hz: 1.0,
            goal_speed_mps: 1.0,
        }
    }
}

/// One ROS name token: a letter or `_` first, then letters, digits and `_`.
fn valid_token(t: &str) -> bool {
    let mut bytes = t.bytes();
    bytes
        .next()
        .is_some_and(|b| b.is_ascii_alphabetic() || b == b'_')
        && bytes.all(|b| b.is_ascii_alphanumeric() || b == b'_')
}

/// A ROS id usable as one name token (the drone ids become topic names).
pub fn valid_ros_token(t: &str) -> bool {
    t.len() <= MAX_NAME_LEN && valid_token(t)
}

/// `""`, or `/` followed by tokens separated by `/` (a leading `/` may be left out).
fn valid_namespace(ns: &str) -> bool {
    let body = ns.strip_prefix('/').unwrap_or(ns);
    ns.len() <= MAX_NAME_LEN && (body.is_empty() || body.split('/').all(valid_token))
}

/// `tcp/HOST:PORT` with a port number (Kestrel builds Zenoh's TCP links only).
fn valid_endpoint(e: &str) -> bool {
    let Some(("tcp", addr)) = e.split_once('/') else {
        return false;
    };
    let Some((host, port)) = addr.rsplit_once(':') else {
        return false;
    };
    !host.is_empty() && !host.contains('/') && port.parse::<u16>().is_ok()
}

impl Ros2Section {
    /// Checks the section; `drones` are this Kestrel's drone ids (each becomes a name token).
    pub fn validate(&self, drones: &[String]) -> Result<(), (String, String)> {
        if !self.enabled {
            return Ok(());
        }
        if self.domain_id > MAX_DOMAIN_ID {
            return Err((
                "ros2.domain_id".into(),
                format!("{} is outside 0 to {MAX_DOMAIN_ID}", self.domain_id),
            ));
        }
        if !valid_namespace(&self.namespace) {
            return Err((
                "ros2.namespace".into(),
                format!(
                    "`{}` is not a ROS namespace (\"\" or /name/name, each name a letter or `_` \
                     then letters, digits or `_`)",
                    self.namespace
                ),
            ));
        }
        if !valid_ros_token(&self.node) {
            return Err((
                "ros2.node".into(),
                format!("`{}` is not a ROS node name", self.node),
            ));
        }
        if let Some(d) = drones.iter().find(|d| !valid_ros_token(d)) {
            return Err((
                "drone.id".into(),
                format!("with [ros2], the drone id `{d}` must be a ROS name (a letter or `_`, then letters, digits or `_`)"),
            ));
        }
        if self.connect.is_empty() || self.connect.len() > MAX_ENDPOINTS {
            return Err((
                "ros2.connect".into(),
                format!("1 to {MAX_ENDPOINTS} routers (tcp/HOST:PORT)"),
            ));
        }
        for (i, e) in self.connect.iter().enumerate() {
            if !valid_endpoint(e) {
                return Err((
                    format!("ros2.connect[{i}]"),
                    format!("`{e}` is not `tcp/HOST:PORT`"),
                ));
            }
        }
        for (field, value, lo, hi) in [
            ("rate_hz", self.rate_hz, 0.5, 50.0),
            ("map_rate_hz", self.map_rate_hz, 0.05, 5.0),
            ("goal_speed_mps", self.goal_speed_mps, 0.1, 20.0),
        ] {
            if !(lo..=hi).contains(&value) {
                return Err((
                    format!("ros2.{field}"),
                    format!("{value} is outside {lo} to {hi}"),
                ));
            }
        }
        Ok(())
    }

    /// The namespace with one leading `/` and none trailing (`""` stays `""`).
    pub fn namespace_path(&self) -> String {
        let body = self.namespace.trim_matches('/');
        if body.is_empty() {
            String::new()
        } else {
            format!("/{body}")
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn on() -> Ros2Section {
        Ros2Section {
            enabled: true,
            ..Ros2Section::default()
        }
    }

    fn field(s: Ros2Section, drones: &[&str]) -> String {
        let drones: Vec<String> = drones.iter().map(|d| d.to_string()).collect();
        s.validate(&drones).unwrap_err().0
    }

    #[test]
    fn defaults_are_valid_and_off_is_always_valid() {
        assert!(on().validate(&["drone_0".into()]).is_ok());
        assert!(Ros2Section::default().validate(&["0bad".into()]).is_ok());
        assert_eq!(on().namespace_path(), "");
        let ns = Ros2Section {
            namespace: "fleet_a/".into(),
            ..on()
        };
        assert_eq!(ns.namespace_path(), "/fleet_a");
    }

    #[test]
    fn each_bad_field_is_named() {
        let s = |f: fn(&mut Ros2Section)| {
            let mut s = on();
            f(&mut s);
            s
        };
        assert_eq!(field(s(|s| s.domain_id = 233), &[]), "ros2.domain_id");
        assert_eq!(
            field(s(|s| s.namespace = "/a b".into()), &[]),
            "ros2.namespace"
        );
        assert_eq!(
            field(s(|s| s.namespace = "/a//b".into()), &[]),
            "ros2.namespace"
        );
        assert_eq!(field(s(|s| s.node = "9".into()), &[]), "ros2.node");
        assert_eq!(field(on(), &["drone-1"]), "drone.id");
        assert_eq!(field(s(|s| s.connect.clear()), &[]), "ros2.connect");
        assert_eq!(
            field(s(|s| s.connect.push("udp/1.2.3.4:7447".into())), &[]),
            "ros2.connect[1]"
        );
        assert_eq!(field(s(|s| s.rate_hz = 0.0), &[]), "ros2.rate_hz");
        assert_eq!(
            field(s(|s| s.map_rate_hz = f64::NAN), &[]),
            "ros2.map_rate_hz"
        );
        assert_eq!(
            field(s(|s| s.goal_speed_mps = 100.0), &[]),
            "ros2.goal_speed_mps"
        );
    }
}
