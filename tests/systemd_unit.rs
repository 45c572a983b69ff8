#![allow(clippy::unwrap_used, clippy::expect_used)]
//! The shipped unit (systemd/kestrel.service): the serial devices of the companion boards are
//! allowed, and `systemd-analyze verify` accepts it (when systemd is installed; CI installs it).

use std::path::Path;
use std::process::Command;

fn unit() -> String {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("systemd/kestrel.service");
    std::fs::read_to_string(path).unwrap()
}

/// Values of `key=` lines, comments left out.
fn values<'a>(unit: &'a str, key: &str) -> Vec<&'a str> {
    unit.lines()
        .filter_map(|l| l.trim().strip_prefix(key)?.strip_prefix('='))
        .map(str::trim)
        .collect()
}

#[test]
fn every_companion_boards_serial_driver_group_is_allowed() {
    let unit = unit();
    let allowed = values(&unit, "DeviceAllow");
    // USB flight controllers, USB-serial adapters, Raspberry Pi (PL011 and mini UART; its
    // /dev/serial0 is a symlink to one of them), NVIDIA Jetson.
    for group in ["ttyACM", "ttyUSB", "ttyAMA", "ttyS", "ttyTHS"] {
        let rule = format!("char-{group} rw");
        assert!(
            allowed.contains(&rule.as_str()),
            "{rule} missing: {allowed:?}"
        );
    }
    assert_eq!(values(&unit, "DevicePolicy"), ["closed"]);
    assert_eq!(values(&unit, "SupplementaryGroups"), ["dialout"]);
}

#[test]
fn systemd_analyze_verify_accepts_the_unit() {
    if Command::new("systemd-analyze")
        .arg("--version")
        .output()
        .is_err()
    {
        eprintln!("systemd-analyze not installed: skipped (CI runs it)");
        return;
    }
    let dir = tempfile::tempdir().unwrap();
    // verify checks that ExecStart exists: point it at the binary just built.
    let unit = unit().replace("/usr/bin/kestrel", env!("CARGO_BIN_EXE_kestrel"));
    let path = dir.path().join("kestrel.service");
    std::fs::write(&path, unit).unwrap();
    let out = Command::new("systemd-analyze")
        .arg("verify")
        .arg(&path)
        .output()
        .unwrap();
    let said = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "{said}");
    assert!(
        !said.contains("kestrel.service:"),
        "warnings about the unit:\n{said}"
    );
}
