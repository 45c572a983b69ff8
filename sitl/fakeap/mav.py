"""MAVLink 2 codec for the fake autopilot and its tests.

Uses pymavlink's ardupilotmega dialect (which includes common) and adds the PX4 messages
that stock pymavlink 2.4.50 dialects lack: EVENT (410), CURRENT_EVENT_SEQUENCE (411) and
CURRENT_MODE (436). The extra classes are built from the message definitions (field types
and names from MAVLink's common.xml); CRC_EXTRA is computed the way mavgen does.
"""
import os
import struct

os.environ["MAVLINK20"] = "1"
os.environ.setdefault("MAVLINK_DIALECT", "ardupilotmega")

from pymavlink import mavutil  # noqa: E402
from pymavlink.dialects.v20 import ardupilotmega as mavlink  # noqa: E402
from pymavlink.generator.mavcrc import x25crc  # noqa: E402

_TYPE_INFO = {  # mavlink type -> (struct char, size)
    "uint8_t": ("B", 1), "int8_t": ("b", 1), "uint16_t": ("H", 2), "int16_t": ("h", 2),
    "uint32_t": ("I", 4), "int32_t": ("i", 4), "float": ("f", 4), "uint64_t": ("Q", 8),
}


def _crc_extra(name, wire_fields):
    crc = x25crc()
    crc.accumulate_str(name + " ")
    for ftype, fname, alen in wire_fields:
        crc.accumulate_str(ftype + " ")
        crc.accumulate_str(fname + " ")
        if alen:
            crc.accumulate([alen])
    return (crc.crc & 0xFF) ^ (crc.crc >> 8)


def _define(msg_id, name, fields):
    """fields: list of (type, name, array_len) in XML order (no extensions)."""
    wire = sorted(fields, key=lambda f: -_TYPE_INFO[f[0]][1])  # stable sort by size, desc
    fmt = "<" + "".join(
        (f"{f[2]}s" if f[0] in ("uint8_t", "int8_t") and f[2] else _TYPE_INFO[f[0]][0] * (f[2] or 1))
        for f in wire
    )
    fieldnames = [f[1] for f in fields]
    ordered = [f[1] for f in wire]
    crc_extra = _crc_extra(name, wire)
    unpacker = struct.Struct(fmt)

    class Msg(mavlink.MAVLink_message):
        def __init__(self, *args):
            mavlink.MAVLink_message.__init__(self, msg_id, name)
            self._fieldnames = fieldnames
            self._instance_field = None
            self._instance_offset = -1
            for fname, value in zip(fieldnames, args):
                setattr(self, fname, value)

        def pack(self, mav, force_mavlink1=False):
            values = []
            for f in wire:
                v = getattr(self, f[1])
                if f[2]:
                    v = bytes(v) + bytes(f[2] - len(v))
                values.append(v)
            return self._pack(mav, crc_extra, unpacker.pack(*values), force_mavlink1=force_mavlink1)

    Msg.id = msg_id
    Msg.msgname = name
    Msg.fieldnames = fieldnames
    Msg.ordered_fieldnames = ordered
    Msg.fieldtypes = [f[0] for f in fields]
    Msg.fielddisplays_by_name = {}
    Msg.fieldenums_by_name = {}
    Msg.fieldunits_by_name = {}
    Msg.native_format = bytearray(fmt.encode())
    Msg.orders = [ordered.index(n) for n in fieldnames]
    Msg.lengths = [1 for _ in wire]
    Msg.array_lengths = [f[2] for f in wire]
    Msg.crc_extra = crc_extra
    Msg.unpacker = unpacker
    Msg.instance_field = None
    Msg.instance_offset = -1
    Msg.__name__ = f"MAVLink_{name.lower()}_message"
    setattr(Msg, "name", property(lambda self: self.msgname))
    mavlink.mavlink_map[msg_id] = Msg
    return Msg


if 410 not in mavlink.mavlink_map:
    EventMsg = _define(410, "EVENT", [
        ("uint8_t", "destination_component", 0), ("uint8_t", "destination_system", 0),
        ("uint32_t", "id", 0), ("uint32_t", "event_time_boot_ms", 0), ("uint16_t", "sequence", 0),
        ("uint8_t", "log_levels", 0), ("uint8_t", "arguments", 40),
    ])
else:
    EventMsg = mavlink.mavlink_map[410]
if 411 not in mavlink.mavlink_map:
    CurrentEventSequenceMsg = _define(411, "CURRENT_EVENT_SEQUENCE", [
        ("uint16_t", "sequence", 0), ("uint8_t", "flags", 0),
    ])
else:
    CurrentEventSequenceMsg = mavlink.mavlink_map[411]
if 436 not in mavlink.mavlink_map:
    CurrentModeMsg = _define(436, "CURRENT_MODE", [
        ("uint8_t", "standard_mode", 0), ("uint32_t", "custom_mode", 0),
        ("uint32_t", "intended_custom_mode", 0),
    ])
else:
    CurrentModeMsg = mavlink.mavlink_map[436]

__all__ = ["mavlink", "mavutil", "EventMsg", "CurrentEventSequenceMsg", "CurrentModeMsg"]
