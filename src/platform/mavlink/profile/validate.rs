//! From a profile's raw TOML to the checked [`Profile`]: every range, mode number and role.
//!
//! In: the deserialized [`RawProfile`]. Out: the [`Profile`], or the field at fault and why.

use super::*;

pub(super) type Invalid = (String, String);

fn seconds(field: &str, v: f64, min: f64, max: f64) -> Result<Duration, Invalid> {
    if v.is_finite() && (min..=max).contains(&v) {
        Ok(Duration::from_secs_f64(v))
    } else {
        Err((
            field.into(),
            format!("must be within {min}..={max} s, got {v}"),
        ))
    }
}

fn mode_value(kind: AutopilotKind, name: &str, raw: RawMode) -> Result<u32, Invalid> {
    let field = format!("modes.{name}");
    match (kind, raw) {
        (
            AutopilotKind::Px4,
            RawMode {
                main: Some(main),
                sub,
                number: None,
            },
        ) => Ok((u32::from(main) << 16) | (u32::from(sub.unwrap_or(0)) << 24)),
        (
            AutopilotKind::Ardupilot,
            RawMode {
                main: None,
                sub: None,
                number: Some(n),
            },
        ) => Ok(n),
        (AutopilotKind::Px4, _) => Err((field, "PX4 modes are `{ main = M, sub = S }`".into())),
        (AutopilotKind::Ardupilot, _) => {
            Err((field, "ArduPilot modes are `{ number = N }`".into()))
        }
    }
}

pub(super) fn validate(raw: RawProfile) -> Result<Profile, Invalid> {
    let PlatformKey::Mavlink = raw.platform;
    let (modes, roles) = modes_and_roles(&raw)?;
    if !(raw.setpoint_rate_hz.is_finite() && (2.0..=200.0).contains(&raw.setpoint_rate_hz)) {
        return Err((
            "setpoint_rate_hz".into(),
            format!("must be within 2..=200 Hz, got {}", raw.setpoint_rate_hz),
        ));
    }
    let setpoint_period = Duration::from_secs_f64(1.0 / raw.setpoint_rate_hz);
    let offboard_loss_timeout = seconds(
        "offboard_loss_timeout_s",
        raw.offboard_loss_timeout_s,
        0.1,
        60.0,
    )?;
    let setpoint_max_age = seconds("setpoint_max_age_s", raw.setpoint_max_age_s, 0.005, 5.0)?;
    if setpoint_max_age >= offboard_loss_timeout || setpoint_period * 2 >= offboard_loss_timeout {
        return Err((
            "setpoint_max_age_s".into(),
            "the setpoint period and maximum age must stay well below offboard_loss_timeout_s"
                .into(),
        ));
    }
    let message_intervals = message_intervals(&raw)?;
    if raw.takeoff == TakeoffMethod::NavTakeoff
        && raw.autopilot == AutopilotKind::Px4
        && roles.takeoff.is_none()
    {
        return Err((
            "roles.takeoff".into(),
            "PX4 NAV_TAKEOFF needs the takeoff mode (AUTO.TAKEOFF)".into(),
        ));
    }
    let position_loop = match raw.drive.setpoints {
        DriveSetpoints::Velocity => None,
        DriveSetpoints::PositionTarget => Some(PositionLoop {
            gain_xy_per_s: gain(
                "drive.position_gain_xy_per_s",
                raw.drive.position_gain_xy_per_s,
            )?,
            gain_z_per_s: gain(
                "drive.position_gain_z_per_s",
                raw.drive.position_gain_z_per_s,
            )?,
        }),
    };
    Ok(Profile {
        name: raw.name,
        autopilot: raw.autopilot,
        takeoff: raw.takeoff,
        takeoff_altitude: raw.takeoff_altitude,
        land: raw.land,
        arm_in_offboard_mode: raw.arm_in_offboard_mode,
        setpoint_period,
        setpoint_max_age,
        offboard_prestream: seconds("offboard_prestream_s", raw.offboard_prestream_s, 0.0, 10.0)?,
        offboard_loss_timeout,
        heartbeat_timeout: seconds("heartbeat_timeout_s", raw.heartbeat_timeout_s, 0.2, 30.0)?,
        command_timeout: seconds("command_timeout_s", raw.command_timeout_s, 0.01, 30.0)?,
        command_retries: raw.command_retries,
        mode_confirm_timeout: seconds(
            "mode_confirm_timeout_s",
            raw.mode_confirm_timeout_s,
            0.1,
            60.0,
        )?,
        ready_timeout: seconds("ready_timeout_s", raw.ready_timeout_s, 0.0, 600.0)?,
        message_interval_fallback: raw.message_interval_fallback,
        gimbal: raw.gimbal,
        camera_component: raw.camera_component,
        readiness: Readiness {
            ekf_flags_required: raw.readiness.ekf_flags_required,
            ekf_flags_forbidden: raw.readiness.ekf_flags_forbidden,
            prearm_check_bit: raw.readiness.prearm_check_bit,
        },
        modes,
        roles,
        message_intervals,
        position_loop,
        velocity_lag: seconds("drive.velocity_lag_s", raw.drive.velocity_lag_s, 0.0, 5.0)?,
        velocity_check: raw
            .drive
            .velocity_check_s
            .map(|s| seconds("drive.velocity_check_s", s, 0.0, 5.0))
            .transpose()?,
        command_slew_mps2: raw
            .drive
            .command_slew_mps2
            .map(|a| bounded("drive.command_slew_mps2", a, (0.1, 50.0), "m/s^2"))
            .transpose()?,
        velocity_overshoot: raw
            .drive
            .velocity_overshoot
            .map(|share| fraction("drive.velocity_overshoot", share))
            .transpose()?,
        yaw_rate_overshoot: raw
            .drive
            .yaw_rate_overshoot
            .map(|share| fraction("drive.yaw_rate_overshoot", share))
            .transpose()?,
        height_error_m: raw
            .height_error_m
            .map(|e| bounded("height_error_m", e, (0.0, 20.0), "m"))
            .transpose()?,
    })
}

/// `v` when it is within `lo..=hi` (in `unit`), else the error naming `field`.
fn bounded(field: &str, v: f64, (lo, hi): (f64, f64), unit: &str) -> Result<f64, Invalid> {
    if v.is_finite() && (lo..=hi).contains(&v) {
        Ok(v)
    } else {
        Err((
            field.to_string(),
            format!("must be within {lo}..={hi} {unit}, got {v}"),
        ))
    }
}

/// `share` when it is a fraction within 0..=1, else the error naming `field`.
fn fraction(field: &str, share: f64) -> Result<f64, Invalid> {
    if share.is_finite() && (0.0..=1.0).contains(&share) {
        Ok(share)
    } else {
        Err((
            field.to_string(),
            format!("must be a fraction within 0..=1, got {share}"),
        ))
    }
}

/// The profile's modes with their numbers, and the mode each role names.
fn modes_and_roles(raw: &RawProfile) -> Result<(Vec<Mode>, Roles), Invalid> {
    let mut modes = Vec::with_capacity(raw.modes.len());
    for (name, m) in &raw.modes {
        modes.push(Mode {
            name: name.clone(),
            custom_mode: mode_value(raw.autopilot, name, *m)?,
        });
    }
    let find = |role: &str, name: &str| -> Result<Mode, Invalid> {
        modes
            .iter()
            .find(|m| m.name == name)
            .cloned()
            .ok_or_else(|| {
                (
                    format!("roles.{role}"),
                    format!("no mode `{name}` in [modes]"),
                )
            })
    };
    let roles = Roles {
        offboard: find("offboard", &raw.roles.offboard)?,
        land: find("land", &raw.roles.land)?,
        hold: find("hold", &raw.roles.hold)?,
        rtl: raw
            .roles
            .rtl
            .as_deref()
            .map(|n| find("rtl", n))
            .transpose()?,
        takeoff: raw
            .roles
            .takeoff
            .as_deref()
            .map(|n| find("takeoff", n))
            .transpose()?,
    };
    Ok((modes, roles))
}

/// The messages asked of the autopilot, by id, with their rates (0..=500 Hz).
fn message_intervals(raw: &RawProfile) -> Result<Vec<(u32, f64)>, Invalid> {
    let mut message_intervals = Vec::with_capacity(raw.message_intervals_hz.len());
    for (name, hz) in &raw.message_intervals_hz {
        let field = format!("message_intervals_hz.{name}");
        let id = MavMessage::message_id_from_name(name)
            .ok_or_else(|| (field.clone(), "no such MAVLink message".to_string()))?;
        if !(hz.is_finite() && *hz > 0.0 && *hz <= 500.0) {
            return Err((field, format!("must be within 0..=500 Hz, got {hz}")));
        }
        message_intervals.push((id, *hz));
    }
    Ok(message_intervals)
}

fn gain(field: &str, v: f64) -> Result<f64, Invalid> {
    if v.is_finite() && (0.1..=5.0).contains(&v) {
        Ok(v)
    } else {
        Err((field.into(), format!("must be within 0.1..=5 1/s, got {v}")))
    }
}
