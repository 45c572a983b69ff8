//! `kestrel fleet-key FILE`: this node's fleet-bus key, made once, and its public key for the
//! roster every node of the fleet keeps (`[fleet.roster.NODE] keys`).

use anyhow::{bail, Result};
use kestrel::config::Config;
use kestrel::fleet_bus::config::FleetSection;
use std::collections::BTreeMap;
use std::path::Path;

/// Makes `file` (never replacing one) unless `public`, then prints its public key and the
/// roster entry to paste.
#[cfg(feature = "fleet-bus")]
pub fn key(file: &Path, public: bool) -> Result<()> {
    use kestrel::fleet_bus::identity::Signer;
    let signer = if public {
        Signer::read(file)?
    } else {
        let made = Signer::generate(file)?;
        println!(
            "made {} (keep it on this node only, readable by Kestrel; point [fleet] key_file at it)",
            file.display()
        );
        made
    };
    let key = signer.public().to_base64();
    println!("public key: {key}");
    println!("in every node's config (NODE: this node's [fleet] node, DRONES: the ids it flies):");
    println!("    [fleet.roster.NODE]\n    keys = [\"{key}\"]\n    drones = [\"DRONES\"]");
    Ok(())
}

#[cfg(not(feature = "fleet-bus"))]
pub fn key(_file: &Path, _public: bool) -> Result<()> {
    bail!("this kestrel was built without the fleet bus (cargo feature `fleet-bus`)")
}

/// `[fleet]` as `kestrel run` would start it: the bus built in, this node's key readable and
/// the roster's for this node, the credentials file (if any) well formed. Said as warnings: a
/// key file others can read, a bus without credentials.
pub fn check(config: &Config, file: &str, warnings: &mut Vec<String>) -> Result<()> {
    let fleet = &config.fleet;
    if !fleet.enabled {
        return Ok(());
    }
    if cfg!(not(feature = "fleet-bus")) {
        bail!(
            "{file}: fleet.enabled: this kestrel was built without the fleet bus (cargo \
             feature `fleet-bus`)"
        );
    }
    let node = fleet.node_name(&config.drone_ids());
    identity(fleet, &node).map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
    if let Some(path) = &fleet.key_file {
        if readable_by_others(path) {
            warnings.push(format!(
                "fleet.key_file {}: readable by other users (chmod 600 it): whoever reads it can \
                 speak for node `{node}`",
                path.display()
            ));
        }
    }
    if let Some(path) = &fleet.credentials_file {
        kestrel::fleet_bus::credentials::read_credentials(path)
            .map_err(|e| anyhow::anyhow!("{file}: {e}"))?;
    }
    Ok(())
}

#[cfg(unix)]
fn readable_by_others(path: &Path) -> bool {
    use std::os::unix::fs::PermissionsExt;
    std::fs::metadata(path).is_ok_and(|m| m.permissions().mode() & 0o044 != 0)
}

#[cfg(not(unix))]
fn readable_by_others(_path: &Path) -> bool {
    false
}

/// One line for `kestrel check-config`.
pub fn summary(config: &Config) -> Option<String> {
    let fleet = &config.fleet;
    if !fleet.enabled {
        return None;
    }
    let node = fleet.node_name(&config.drone_ids());
    Some(format!(
        "`{}` as node `{node}`, {} members in the roster, key {}",
        fleet.name,
        fleet.roster.len(),
        fleet
            .key_file
            .as_ref()
            .map_or("none".to_string(), |p| p.display().to_string())
    ))
}

/// This node's signer, read from `[fleet] key_file` and found in its roster entry, and the
/// other members with their keys parsed.
#[cfg(feature = "fleet-bus")]
pub fn identity(
    fleet: &FleetSection,
    node: &str,
) -> Result<(
    kestrel::fleet_bus::identity::Signer,
    BTreeMap<String, kestrel::fleet_bus::intake::Member>,
)> {
    use kestrel::fleet_bus::identity::{PublicKey, Signer};
    use kestrel::fleet_bus::intake::Member;
    let Some(path) = &fleet.key_file else {
        bail!("fleet.key_file: missing (`kestrel fleet-key FILE` makes one)");
    };
    let signer = Signer::read(path)?;
    let public = signer.public();
    let own = fleet.roster.get(node).map(|m| &m.keys);
    if !own.is_some_and(|keys| {
        keys.iter()
            .any(|k| PublicKey::parse(k).ok() == Some(public.clone()))
    }) {
        bail!(
            "fleet.key_file {}: its public key {} is not among [fleet.roster.{node}] keys \
             (`kestrel fleet-key --public {}` prints it)",
            path.display(),
            public.to_base64(),
            path.display()
        );
    }
    let mut members = BTreeMap::new();
    for (name, m) in fleet.roster.iter().filter(|(n, _)| *n != node) {
        let keys = m
            .keys
            .iter()
            .map(|k| PublicKey::parse(k))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| anyhow::anyhow!("fleet.roster.{name}.keys: {e}"))?;
        members.insert(
            name.clone(),
            Member {
                keys,
                drones: m.drones.clone(),
            },
        );
    }
    Ok((signer, members))
}

#[cfg(not(feature = "fleet-bus"))]
pub fn identity(_fleet: &FleetSection, _node: &str) -> Result<()> {
    bail!("this kestrel was built without the fleet bus (cargo feature `fleet-bus`)")
}
