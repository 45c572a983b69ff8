//! Messages MAVLink marks as superseded that ArduPilot still needs.
//!
//! In: the target and the values. Out: the message. ArduCopter 4.x takes its EKF origin only from
//! SET_GPS_GLOBAL_ORIGIN (MAV_CMD_DO_SET_GLOBAL_ORIGIN is newer than most deployed firmware),
//! and older firmware streams telemetry only after REQUEST_DATA_STREAM; the deprecation
//! warnings are allowed here and nowhere else.
#![allow(deprecated)]

use crate::types::GeoPoint;
use mavlink::dialects::ardupilotmega::{
    MavDataStream, MavMessage, REQUEST_DATA_STREAM_DATA, SET_GPS_GLOBAL_ORIGIN_DATA,
};

/// REQUEST_DATA_STREAM for every stream group at `rate_hz`.
pub fn request_all_streams(target_system: u8, target_component: u8, rate_hz: u16) -> MavMessage {
    MavMessage::REQUEST_DATA_STREAM(REQUEST_DATA_STREAM_DATA {
        req_message_rate: rate_hz,
        target_system,
        target_component,
        req_stream_id: MavDataStream::MAV_DATA_STREAM_ALL,
        start_stop: 1,
    })
}

/// SET_GPS_GLOBAL_ORIGIN (degrees × 1e7, millimetres).
pub fn set_gps_global_origin(target_system: u8, origin: &GeoPoint) -> MavMessage {
    MavMessage::SET_GPS_GLOBAL_ORIGIN(SET_GPS_GLOBAL_ORIGIN_DATA {
        latitude: (origin.lat_deg * 1e7).round() as i32,
        longitude: (origin.lon_deg * 1e7).round() as i32,
        altitude: (origin.alt_m * 1000.0).round() as i32,
        target_system,
        time_usec: 0,
    })
}
