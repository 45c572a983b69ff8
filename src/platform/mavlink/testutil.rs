//! Helpers shared by this module's unit tests.

use super::profile::Profile;
use mavlink::dialects::ardupilotmega::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
};
use mavlink::MavHeader;

pub fn px4_profile() -> Profile {
    Profile::builtin("px4").unwrap().unwrap()
}

pub fn ardupilot_profile() -> Profile {
    Profile::builtin("ardupilot-copter").unwrap().unwrap()
}

/// The header of the autopilot (system 1, component 1).
pub fn autopilot_header() -> MavHeader {
    MavHeader {
        system_id: 1,
        component_id: 1,
        sequence: 0,
    }
}

/// A PX4 HEARTBEAT with this custom mode.
pub fn hb(custom_mode: u32, armed: bool) -> MavMessage {
    let mut base = MavModeFlag::MAV_MODE_FLAG_CUSTOM_MODE_ENABLED;
    if armed {
        base |= MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED;
    }
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode,
        mavtype: MavType::MAV_TYPE_QUADROTOR,
        autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
        base_mode: base,
        system_status: MavState::MAV_STATE_STANDBY,
        mavlink_version: 3,
    })
}
