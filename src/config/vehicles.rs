//! The `[[vehicle]]` list of the config file: several autopilots flown by one `kestrel run`,
//! each over its own MAVLink connection or several behind one (a telemetry radio,
//! mavlink-router: told apart by system id), each with its own core and mission executor.
//!
//! In: TOML (unknown keys refused) and the `[mavlink]` section the vehicles share the rest of
//! their link settings with. Out: the checked list; `Err((field, message))` naming the entry
//! (`vehicle[2].connection`) for an empty or repeated id, a connection that does not parse,
//! vehicles sharing a connection without each naming its autopilot's system id (or with
//! different `forward` lists), or a frame origin out of bounds.
//!
//! Without the list the config flies one vehicle: `[drone] id` over `[mavlink]`, as always.

use crate::platform::mavlink::config::MavlinkSection;
use crate::types::SensorConfig;
use serde::{Deserialize, Serialize};

/// The most vehicles one host flies (each has its own link tasks and core).
pub const MAX_VEHICLES: usize = 32;

/// How far a vehicle's local frame origin may lie from the shared frame's (m, each axis).
pub const MAX_ORIGIN_OFFSET_M: f64 = 10_000.0;

/// One autopilot of the fleet.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct VehicleSection {
    /// Id used in missions (`target`), the API and logs; unique in the list.
    pub id: String,
    /// Autopilot profile (as `mavlink.platform`); absent = `mavlink.platform`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub platform: Option<String>,
    /// This vehicle's MAVLink connection (as `mavlink.connection`). Several vehicles may share
    /// one when each names its `target_system`.
    pub connection: String,
    /// The autopilot's MAVLink system id: only this one is followed on the connection; absent =
    /// the first autopilot heard (as `mavlink.target_system`). Required on a shared connection.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub target_system: Option<u8>,
    /// Where the autopilot's local frame origin (where its estimator started, usually where it
    /// was switched on) lies in the fleet's shared ENU frame (m). Positions it reports are
    /// shifted by this, and position setpoints shifted back, so all cores, the merged map and
    /// missions share one frame. Autopilot local frames are north-aligned, so no rotation.
    #[serde(default)]
    pub origin_enu_m: [f64; 3],
    /// Ground station endpoints that get this vehicle's stream (`[mavlink] forward` is for the
    /// single-vehicle config only: two vehicles cannot bind one `udpin` endpoint). Vehicles
    /// sharing a connection list the same endpoints: they get the whole connection's stream.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub forward: Vec<String>,
    /// The range sensor `kestrel run --virtual-world` casts for this vehicle (as `[sim.sensor]`:
    /// `kind` = `multiranger`, `lidar360` or `none`); absent = `[sim] sensor`, else the world
    /// file's, else the four-beam multi-ranger. Unused without a virtual world.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sensor: Option<SensorConfig>,
}

/// Checks the list against itself and the shared `[mavlink]` section.
pub fn validate(
    vehicles: &[VehicleSection],
    mavlink: &MavlinkSection,
) -> Result<(), (String, String)> {
    if vehicles.is_empty() {
        return Ok(());
    }
    if vehicles.len() > MAX_VEHICLES {
        return Err((
            "vehicle".into(),
            format!("{} vehicles, at most {MAX_VEHICLES}", vehicles.len()),
        ));
    }
    if !mavlink.forward.is_empty() {
        return Err((
            "mavlink.forward".into(),
            "with a [[vehicle]] list, give each vehicle its own `forward`".into(),
        ));
    }
    if mavlink.target_system.is_some() {
        return Err((
            "mavlink.target_system".into(),
            "with a [[vehicle]] list, give each vehicle its own `target_system`".into(),
        ));
    }
    for (i, v) in vehicles.iter().enumerate() {
        let key = |field: &str| format!("vehicle[{i}].{field}");
        if v.id.is_empty() {
            return Err((key("id"), "must not be empty".into()));
        }
        if let Some(j) = vehicles[..i].iter().position(|w| w.id == v.id) {
            return Err((key("id"), format!("`{}` is also vehicle[{j}]'s id", v.id)));
        }
        let address = |field: &str, s: &str| {
            mavlink::ConnectionAddress::parse_address(s)
                .map(|_| ())
                .map_err(|e| (key(field), format!("`{s}`: {e}")))
        };
        address("connection", &v.connection)?;
        for f in &v.forward {
            address("forward", f)?;
        }
        // Vehicles behind one connection (a radio, mavlink-router) are told apart by the
        // autopilots' system ids: every one must name its own.
        for (j, w) in vehicles[..i].iter().enumerate() {
            if !same_endpoint(&w.connection, &v.connection) {
                continue;
            }
            match (w.target_system, v.target_system) {
                (Some(a), Some(b)) if a == b => {
                    return Err((
                        key("target_system"),
                        format!(
                            "{b} is also vehicle[{j}]'s, on the same connection `{}`",
                            v.connection
                        ),
                    ))
                }
                (Some(_), Some(_)) => {}
                _ => {
                    return Err((
                        key("connection"),
                        format!(
                            "`{}` is also vehicle[{j}]'s connection: vehicles sharing a \
                             connection are told apart by system id, give each its autopilot's \
                             `target_system`",
                            v.connection
                        ),
                    ))
                }
            }
            if w.forward != v.forward {
                return Err((
                    key("forward"),
                    format!(
                        "vehicles sharing `{}` must list the same `forward` (it forwards the \
                         connection, every vehicle on it): vehicle[{j}] lists {:?}",
                        v.connection, w.forward
                    ),
                ));
            }
        }
        if v.target_system == Some(0) {
            return Err((key("target_system"), "must be 1..=255".into()));
        }
        if let Some(sensor) = &v.sensor {
            sensor
                .validate()
                .map_err(|e| (key("sensor"), e.to_string()))?;
        }
        for c in v.origin_enu_m {
            crate::config::bounds::within(
                &key("origin_enu_m"),
                c,
                (-MAX_ORIGIN_OFFSET_M, MAX_ORIGIN_OFFSET_M),
                false,
                "m",
            )?;
        }
    }
    Ok(())
}

/// The same transport endpoint: the strings compared with the bind-all address and `localhost`
/// taken for loopback, so `udpin:0.0.0.0:14540` and `udpin:127.0.0.1:14540` collide.
pub fn same_endpoint(a: &str, b: &str) -> bool {
    let norm = |s: &str| {
        s.trim()
            .replace("0.0.0.0", "127.0.0.1")
            .replace("localhost", "127.0.0.1")
    };
    norm(a) == norm(b)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Vec<VehicleSection> {
        #[derive(Deserialize)]
        struct List {
            vehicle: Vec<VehicleSection>,
        }
        toml::from_str::<List>(text).unwrap().vehicle
    }

    const TWO: &str = "[[vehicle]]\nid = \"a\"\nconnection = \"udpin:0.0.0.0:14540\"\n\
                       [[vehicle]]\nid = \"b\"\nconnection = \"udpin:0.0.0.0:14541\"\n\
                       origin_enu_m = [3.0, 0.0, 0.0]\n";

    #[test]
    fn two_vehicles_on_their_own_connections_pass() {
        let list = parse(TWO);
        assert_eq!(validate(&list, &MavlinkSection::default()), Ok(()));
        assert_eq!(list[1].origin_enu_m, [3.0, 0.0, 0.0]);
        assert_eq!(list[0].platform, None);
    }

    #[test]
    fn a_repeated_id_names_both_entries() {
        let list = parse(&TWO.replace("id = \"b\"", "id = \"a\""));
        let (field, message) = validate(&list, &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].id");
        assert!(message.contains("vehicle[0]"), "{message}");
    }

    #[test]
    fn one_connection_is_shared_only_by_vehicles_naming_distinct_system_ids() {
        let same = TWO.replace("14541", "14540");
        let (field, message) = validate(&parse(&same), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].connection");
        assert!(message.contains("vehicle[0]"), "{message}");
        assert!(message.contains("target_system"), "{message}");
        let by_sysid = same
            .replace("id = \"a\"\n", "id = \"a\"\ntarget_system = 1\n")
            .replace("id = \"b\"\n", "id = \"b\"\ntarget_system = 2\n");
        assert_eq!(
            validate(&parse(&by_sysid), &MavlinkSection::default()),
            Ok(())
        );
        let one_sysid = by_sysid.replace("target_system = 2", "target_system = 1");
        let (field, message) =
            validate(&parse(&one_sysid), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].target_system");
        assert!(message.contains("vehicle[0]"), "{message}");
        let forwards = by_sysid.replace(
            "target_system = 2\n",
            "target_system = 2\nforward = [\"udpout:127.0.0.1:14550\"]\n",
        );
        let (field, _) = validate(&parse(&forwards), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].forward");
        let loopback = TWO.replace("0.0.0.0:14541", "127.0.0.1:14540");
        assert!(validate(&parse(&loopback), &MavlinkSection::default()).is_err());
    }

    #[test]
    fn bad_connections_origins_and_shared_settings_are_refused() {
        let bad = TWO.replace("udpin:0.0.0.0:14541", "carrier-pigeon");
        let (field, _) = validate(&parse(&bad), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].connection");
        let far = TWO.replace("[3.0, 0.0, 0.0]", "[3.0, 1e9, 0.0]");
        let (field, _) = validate(&parse(&far), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].origin_enu_m");
        let nan = TWO.replace("[3.0, 0.0, 0.0]", "[nan, 0.0, 0.0]");
        assert!(validate(&parse(&nan), &MavlinkSection::default()).is_err());
        let blind = format!("{TWO}sensor = {{ kind = \"lidar360\", rate_hz = 0.0 }}\n");
        let (field, message) = validate(&parse(&blind), &MavlinkSection::default()).unwrap_err();
        assert_eq!(field, "vehicle[1].sensor");
        assert!(message.contains("rate_hz"), "{message}");
        let mavlink = MavlinkSection {
            forward: vec!["udpout:127.0.0.1:14550".into()],
            ..MavlinkSection::default()
        };
        let (field, _) = validate(&parse(TWO), &mavlink).unwrap_err();
        assert_eq!(field, "mavlink.forward");
    }
}
