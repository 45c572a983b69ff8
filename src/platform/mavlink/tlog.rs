//! Telemetry logs (`.tlog`): records of an 8-byte big-endian microsecond timestamp followed by
//! one MAVLink frame, as QGroundControl, MAVProxy and the captures in `../shared/traces/` write.
//!
//! In: the file's bytes. Out: `(timestamp, header, message)` for every frame the ardupilotmega
//! dialect decodes; frames it does not know (or with a bad checksum) are counted and skipped.

use mavlink::dialects::ardupilotmega::MavMessage;
use mavlink::{MavHeader, MavlinkReader};
use std::time::Duration;

const STX_V1: u8 = 0xFE;
const STX_V2: u8 = 0xFD;
const V2_SIGNED: u8 = 0x01;
const SIGNATURE_LEN: usize = 13;

/// One decoded record.
#[derive(Debug, Clone)]
pub struct Record {
    /// Wall-clock time of the capture (since the Unix epoch).
    pub stamp: Duration,
    pub header: MavHeader,
    pub msg: MavMessage,
}

/// The records of a tlog and how many frames were skipped.
#[derive(Debug, Default)]
pub struct Tlog {
    pub records: Vec<Record>,
    pub skipped: usize,
}

/// Length of the frame starting at `frame`, from its header.
fn frame_len(frame: &[u8]) -> Option<usize> {
    let payload = usize::from(*frame.get(1)?);
    match *frame.first()? {
        STX_V2 => {
            let signed = frame.get(2)? & V2_SIGNED != 0;
            Some(10 + payload + 2 + if signed { SIGNATURE_LEN } else { 0 })
        }
        STX_V1 => Some(6 + payload + 2),
        _ => None,
    }
}

/// Splits a tlog into `(timestamp, frame bytes)`; stops at the first record that does not parse.
pub fn frames(bytes: &[u8]) -> impl Iterator<Item = (Duration, &[u8])> {
    let mut rest = bytes;
    std::iter::from_fn(move || {
        let (stamp, tail) = rest.split_first_chunk::<8>()?;
        let len = frame_len(tail)?;
        let frame = tail.get(..len)?;
        rest = tail.get(len..)?;
        Some((Duration::from_micros(u64::from_be_bytes(*stamp)), frame))
    })
}

/// Decodes one frame.
pub fn decode_frame(frame: &[u8]) -> Option<(MavHeader, MavMessage)> {
    let mut reader = MavlinkReader::new(frame);
    reader.read_any_message::<MavMessage>().ok()
}

/// Decodes every record of a tlog.
pub fn read(bytes: &[u8]) -> Tlog {
    let mut out = Tlog::default();
    for (stamp, frame) in frames(bytes) {
        match decode_frame(frame) {
            Some((header, msg)) => out.records.push(Record { stamp, header, msg }),
            None => out.skipped += 1,
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use mavlink::dialects::ardupilotmega::{MavAutopilot, HEARTBEAT_DATA};

    #[test]
    fn round_trip_of_a_written_record() {
        let hb = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
            autopilot: MavAutopilot::MAV_AUTOPILOT_PX4,
            custom_mode: 0x0006_0000,
            ..HEARTBEAT_DATA::DEFAULT
        });
        let header = MavHeader {
            system_id: 1,
            component_id: 1,
            sequence: 7,
        };
        let mut bytes = 1_700_000_000_000_000u64.to_be_bytes().to_vec();
        mavlink::write_v2_msg(&mut bytes, header, &hb).unwrap();
        bytes.extend_from_slice(&2u64.to_be_bytes());
        bytes.extend_from_slice(&[STX_V2, 200]); // truncated: ends the file
        let log = read(&bytes);
        assert_eq!(log.records.len(), 1);
        let r = &log.records[0];
        assert_eq!(r.header.sequence, 7);
        assert_eq!(r.stamp, Duration::from_secs(1_700_000_000));
        assert!(matches!(&r.msg, MavMessage::HEARTBEAT(h) if h.custom_mode == 0x0006_0000));
    }
}
