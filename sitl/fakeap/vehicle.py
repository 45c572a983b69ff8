"""Personality-independent part of a simulated vehicle: boot, link I/O with faults,
stream scheduling, frames, common telemetry, sensors and the control-channel view."""
import json
import math
import sys
import time
from collections import deque

from .dynamics import Multirotor, Target, wrap_pi
from .faults import Faults, SetpointStats, DelayLine
from .mav import mavlink, CurrentModeMsg, CurrentEventSequenceMsg

M = mavlink
# SET_POSITION_TARGET type_mask bits
IGNORE_POS = 0x7
IGNORE_VEL = 0x38
IGNORE_YAW = 0x400
IGNORE_YAW_RATE = 0x800


def pint(value):
    """Integer value of a float command parameter (NaN/None -> 0)."""
    if value is None or value != value or value in (float("inf"), float("-inf")):
        return 0
    return int(round(value))


class Vehicle:
    autopilot = M.MAV_AUTOPILOT_GENERIC
    name = "generic"

    def __init__(self, index, link, world, start_pose, clock, opts):
        self.index = index
        self.sysid = opts.sysid_base + index
        self.link = link
        self.world = world
        self.clock = clock
        self.opts = opts
        self.start_pose = start_pose
        self.faults = Faults(seed=opts.seed + index)
        self.stats = SetpointStats()
        self.log = deque(maxlen=1000)
        self.out_delay = DelayLine()
        self.in_delay = DelayLine()
        self.rebooting_until = 0.0
        self.boot_count = 0
        x, y, yaw = start_pose
        self.model = Multirotor(x, y, yaw, self.limits())
        self.boot()

    # ------------------------------------------------------------------ lifecycle
    def boot(self):
        now = self.clock.now()
        self.boot_count += 1
        self.boot_time = now
        self.mav = M.MAVLink(None, srcSystem=self.sysid, srcComponent=1)
        self.parser = M.MAVLink(None)
        self.parser.robust_parsing = True
        self.armed = False
        self.armed_time = None
        b = self.model.body
        b.pos[2] = self.model.ground_z_m
        b.vel = [0.0, 0.0, 0.0]
        b.on_ground = True
        self.model.target = Target(kind="idle")
        # the estimator's local origin is where the vehicle boots
        self.origin_enu = (b.pos[0], b.pos[1], self.model.ground_z_m)
        self.home_enu = tuple(self.origin_enu)
        self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
        self.touchdown_time = None
        self.streams = dict(self.default_streams())
        self.next_due = {}
        self.params = dict(self.default_params())
        self.last_setpoint_sim = None
        self.personality_boot()
        self.note("boot", f"boot #{self.boot_count}")

    def reboot(self, gap_s):
        """Simulated reboot: silent for gap_s (sim), then a fresh boot."""
        self.rebooting_until = self.clock.now() + gap_s
        self.out_delay.clear()
        self.in_delay.clear()
        self.armed = False
        self.model.target = Target(kind="idle")
        self.note("fault", f"reboot, silent for {gap_s} s")
        self._pending_boot = True
        self.link.set_down(True)

    # ------------------------------------------------------------------ personality hooks
    def limits(self):
        raise NotImplementedError

    def default_streams(self):
        return {}

    def default_params(self):
        return {}

    def personality_boot(self):
        pass

    def heartbeat_fields(self):
        raise NotImplementedError

    def mode_name(self):
        raise NotImplementedError

    def in_external_control(self):
        return False

    def handle_command(self, msg, cmd, p):
        return M.MAV_RESULT_UNSUPPORTED

    def handle_other(self, msg):
        pass

    def update(self, now, dt):
        pass

    # ------------------------------------------------------------------ time/frames
    def boot_ms(self):
        return int(max(0.0, self.clock.now() - self.boot_time) * 1000) & 0xFFFFFFFF

    def boot_us(self):
        return int(max(0.0, self.clock.now() - self.boot_time) * 1e6)

    def enu_to_ned(self, p):
        o = self.origin_enu
        return (p[1] - o[1], p[0] - o[0], -(p[2] - o[2]))

    def ned_to_enu(self, n, e, d):
        o = self.origin_enu
        return (o[0] + e, o[1] + n, o[2] - d)

    @staticmethod
    def yaw_enu_to_ned(yaw):
        return wrap_pi(math.pi / 2 - yaw)

    @staticmethod
    def yaw_ned_to_enu(yaw):
        return wrap_pi(math.pi / 2 - yaw)

    def altitude_agl_m(self):
        return self.model.body.pos[2] - self.model.ground_z_m

    # ------------------------------------------------------------------ logging
    def note(self, kind, text, **extra):
        entry = {"t": round(self.clock.now(), 3), "kind": kind, "text": text}
        entry.update(extra)
        self.log.append(entry)
        sink = getattr(self.opts, "log_sink", None)
        if sink is not None:
            sink.write(json.dumps({"vehicle": self.index, **entry}) + "\n")
            sink.flush()

    # ------------------------------------------------------------------ I/O
    ack_before_replies = False  # PX4 emits a command's EVENTs after its COMMAND_ACK

    def send(self, msg):
        if getattr(self, "_deferred", None) is not None:
            self._deferred.append(msg)
            return
        data = msg.pack(self.mav)  # advances the sequence number even if the frame is lost
        now = self.clock.now()
        if now < self.rebooting_until or self.faults.link_down(now) or self.faults.lose():
            return
        if self.faults.latency_s > 0:
            self.out_delay.push(time.monotonic() + self.faults.latency_s, data)
        else:
            self.link.send(data)

    def ack(self, msg, command, result):
        self.send(M.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        self.note("ack", f"command {command} -> {result}", command=command, result=result)

    def receive(self, chunks):
        now = self.clock.now()
        for wall, data in chunks:
            if now < self.rebooting_until or self.faults.link_down(now):
                continue
            try:
                msgs = self.parser.parse_buffer(data) or []
            except M.MAVError:
                continue
            for msg in msgs:
                if msg.get_type() == "BAD_DATA" or self.faults.lose():
                    continue
                if self.faults.latency_s > 0:
                    self.in_delay.push(time.monotonic() + self.faults.latency_s, (wall, msg))
                else:
                    self.dispatch(msg, wall)

    def flush_delayed(self):
        wall = time.monotonic()
        for data in self.out_delay.pop_due(wall):
            self.link.send(data)
        for arrival, msg in self.in_delay.pop_due(wall):
            self.dispatch(msg, arrival)

    def addressed_to_me(self, msg, field="target_system"):
        t = getattr(msg, field, 0)
        return t in (0, self.sysid)

    def dispatch(self, msg, wall):
        try:
            self._dispatch(msg, wall)
        except Exception as exc:  # a malformed request must never kill the fake
            text = f"{msg.get_type()}: {type(exc).__name__}: {exc}"
            self.note("error", text)
            sys.stderr.write(f"fake autopilot vehicle {self.index}: error handling {text}\n")

    def _dispatch(self, msg, wall):
        t = msg.get_type()
        if t == "COMMAND_LONG":
            if not self.addressed_to_me(msg):
                return
            p = [None, msg.param1, msg.param2, msg.param3, msg.param4, msg.param5, msg.param6, msg.param7]
            self._command(msg, msg.command, p)
        elif t == "COMMAND_INT":
            if not self.addressed_to_me(msg):
                return
            p = [None, msg.param1, msg.param2, msg.param3, msg.param4, msg.x, msg.y, msg.z]
            self._command(msg, msg.command, p)
        elif t == "SET_POSITION_TARGET_LOCAL_NED":
            if self.addressed_to_me(msg):
                self.stats.record(wall, self.in_external_control())
                self.last_setpoint_sim = self.clock.now()
                self.on_setpoint_local(msg)
        elif t == "SET_POSITION_TARGET_GLOBAL_INT":
            if self.addressed_to_me(msg):
                self.last_setpoint_sim = self.clock.now()
                self.on_setpoint_global(msg)
        elif t == "SET_ATTITUDE_TARGET":
            if self.addressed_to_me(msg):
                self.last_setpoint_sim = self.clock.now()
                self.on_attitude_target(msg)
        elif t == "SET_MESSAGE_INTERVAL":
            pass
        elif t == "PARAM_REQUEST_READ":
            if self.addressed_to_me(msg):
                self._param_read(msg)
        elif t == "PARAM_REQUEST_LIST":
            if self.addressed_to_me(msg):
                for i, name in enumerate(self.params):
                    self._send_param(name, i)
        elif t == "PARAM_SET":
            if self.addressed_to_me(msg):
                name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
                name = name.rstrip("\x00")
                if name in self.params:
                    self.params[name] = (self._param_decode(msg.param_value, msg.param_type), self.params[name][1])
                    self._send_param(name, list(self.params).index(name))
        elif t == "TIMESYNC":
            if msg.tc1 == 0:
                self.send(M.MAVLink_timesync_message(int(time.monotonic() * 1e9), msg.ts1))
        else:
            self.handle_other(msg)

    def _command(self, msg, cmd, p):
        deferred = []
        forced = self.faults.take_reject(cmd)
        if forced is not None:
            self.note("fault", f"rejected command {cmd} with {forced}")
            self.ack(msg, cmd, forced)
            return
        if cmd == M.MAV_CMD_SET_MESSAGE_INTERVAL:
            result = self.set_message_interval(pint(p[1]), p[2])
        elif cmd == M.MAV_CMD_GET_MESSAGE_INTERVAL:
            mid = pint(p[1])
            iv = self.streams.get(mid)
            us = -1 if not iv else int(iv * 1e6)
            if mid not in self.generators():
                us = 0
            self.send(M.MAVLink_message_interval_message(mid, us))
            result = M.MAV_RESULT_ACCEPTED
        elif cmd == M.MAV_CMD_REQUEST_MESSAGE:
            result = self.request_message(pint(p[1]), msg)
            if result is None:
                return
        elif cmd == M.MAV_CMD_REQUEST_AUTOPILOT_CAPABILITIES:
            self.send(self.autopilot_version())
            result = M.MAV_RESULT_ACCEPTED
        else:
            deferred = []
            if self.ack_before_replies:
                self._deferred = []
            try:
                result = self.handle_command(msg, cmd, p)
            finally:
                deferred, self._deferred = getattr(self, "_deferred", None) or [], None
        if result is not None:
            self.ack(msg, cmd, result)
        for m in deferred:
            self.send(m)

    # ------------------------------------------------------------------ params
    def _param_decode(self, value, ptype):
        return value

    def _param_encode(self, value, ptype):
        return float(value)

    def _send_param(self, name, index):
        value, ptype = self.params[name]
        self.send(M.MAVLink_param_value_message(name.encode(), self._param_encode(value, ptype), ptype,
                                                len(self.params), index))

    def _param_read(self, msg):
        name = msg.param_id if isinstance(msg.param_id, str) else msg.param_id.decode()
        name = name.rstrip("\x00")
        names = list(self.params)
        if msg.param_index >= 0 and msg.param_index < len(names):
            name = names[msg.param_index]
        if name in self.params:
            self._send_param(name, names.index(name))

    def param(self, name):
        return self.params[name][0]

    # ------------------------------------------------------------------ streams
    def set_message_interval(self, msg_id, interval_us):
        if msg_id not in self.generators():
            return self.unknown_stream_result(msg_id)
        if interval_us < 0:
            self.streams[msg_id] = 0.0
        elif interval_us == 0:
            self.streams[msg_id] = self.default_streams().get(msg_id, 0.0)
        else:
            self.streams[msg_id] = interval_us / 1e6
        self.next_due.pop(msg_id, None)
        return M.MAV_RESULT_ACCEPTED

    def unknown_stream_result(self, msg_id):
        return M.MAV_RESULT_FAILED

    def request_message(self, msg_id, req):
        if msg_id == M.MAVLINK_MSG_ID_AUTOPILOT_VERSION:
            self.send(self.autopilot_version())
            return M.MAV_RESULT_ACCEPTED
        gen = self.generators().get(msg_id)
        if gen is None:
            return M.MAV_RESULT_UNSUPPORTED
        for m in self._as_list(gen()):
            self.send(m)
        return M.MAV_RESULT_ACCEPTED

    @staticmethod
    def _as_list(x):
        if x is None:
            return []
        return x if isinstance(x, list) else [x]

    def generators(self):
        return {
            0: self.msg_heartbeat,
            1: self.msg_sys_status,
            2: self.msg_system_time,
            24: self.msg_gps_raw_int,
            30: self.msg_attitude,
            31: self.msg_attitude_quaternion,
            32: self.msg_local_position_ned,
            33: self.msg_global_position_int,
            74: self.msg_vfr_hud,
            85: self.msg_position_target_local_ned,
            132: self.msg_distance_sensors,
            147: self.msg_battery_status,
            242: self.msg_home_position,
            245: self.msg_extended_sys_state,
        }

    def send_streams(self, now):
        if now < self.rebooting_until:
            return
        gens = self.generators()
        for mid, interval in self.streams.items():
            if not interval or mid not in gens:
                continue
            due = self.next_due.get(mid)
            if due is None:
                due = now
            if now + 1e-9 >= due:
                for m in self._as_list(gens[mid]()):
                    self.send(m)
                # keep the phase; skip missed slots after a stall
                due += interval
                if due < now:
                    due = now + interval
                self.next_due[mid] = due

    # ------------------------------------------------------------------ main tick
    def tick(self, now, dt):
        if getattr(self, "_pending_boot", False) and now >= self.rebooting_until:
            self._pending_boot = False
            self.link.set_down(False)
            self.link.reset_peer()
            self.boot()
        if now < self.rebooting_until:
            self.model.step(dt, False)
            return
        self.update(now, dt)
        self.model.step(dt, self.armed)
        if self.opts.collisions and self.world.collides(*self.model.body.pos):
            if not getattr(self, "_colliding", False):
                self.note("collision", "vehicle hit an obstacle", pos_enu=[round(v, 2) for v in self.model.body.pos])
            self._colliding = True
        else:
            self._colliding = False

    # ------------------------------------------------------------------ common telemetry
    capabilities = 0
    flight_sw_version = 0

    def autopilot_version(self):
        uid = 0x4B45535452454C00 + self.sysid  # "KESTREL" + sysid
        return M.MAVLink_autopilot_version_message(self.capabilities, self.flight_sw_version, 0, 0, 0,
                                                   [0] * 8, [0] * 8, [0] * 8, 0, 0, uid)

    def msg_heartbeat(self):
        base, custom, status = self.heartbeat_fields()
        return M.MAVLink_heartbeat_message(M.MAV_TYPE_QUADROTOR, self.autopilot, base, custom, status, 3)

    def position_valid(self):
        return True

    def _ned_state(self):
        b = self.model.body
        n, e, d = self.enu_to_ned(b.pos)
        vn, ve, vd = b.vel[1], b.vel[0], -b.vel[2]
        return n, e, d, vn, ve, vd

    def msg_attitude(self):
        b = self.model.body
        return M.MAVLink_attitude_message(self.boot_ms(), b.roll_rad, b.pitch_rad,
                                          self.yaw_enu_to_ned(b.yaw_rad), 0.0, 0.0, -b.yaw_rate_rps)

    def quaternion(self):
        b = self.model.body
        r, p, y = b.roll_rad, b.pitch_rad, self.yaw_enu_to_ned(b.yaw_rad)
        cr, sr, cp, sp, cy, sy = (math.cos(r / 2), math.sin(r / 2), math.cos(p / 2), math.sin(p / 2),
                                  math.cos(y / 2), math.sin(y / 2))
        return [cr * cp * cy + sr * sp * sy, sr * cp * cy - cr * sp * sy,
                cr * sp * cy + sr * cp * sy, cr * cp * sy - sr * sp * cy]

    def msg_attitude_quaternion(self):
        b = self.model.body
        q = self.quaternion()
        return M.MAVLink_attitude_quaternion_message(self.boot_ms(), q[0], q[1], q[2], q[3], 0.0, 0.0,
                                                     -b.yaw_rate_rps, [0, 0, 0, 0])

    def msg_local_position_ned(self):
        if not self.position_valid():
            return None
        n, e, d, vn, ve, vd = self._ned_state()
        return M.MAVLink_local_position_ned_message(self.boot_ms(), n, e, d, vn, ve, vd)

    def geo(self):
        b = self.model.body
        return self.world.enu_to_geo(*b.pos)

    def msg_global_position_int(self):
        if not self.position_valid():
            return M.MAVLink_global_position_int_message(self.boot_ms(), 0, 0, 0, 0, 0, 0, 0,
                                                         int(math.degrees(self.yaw_enu_to_ned(self.model.body.yaw_rad)) % 360 * 100))
        b = self.model.body
        lat, lon, alt = self.geo()
        rel = b.pos[2] - self.home_enu[2]
        hdg = int((math.degrees(self.yaw_enu_to_ned(b.yaw_rad)) % 360) * 100)
        return M.MAVLink_global_position_int_message(self.boot_ms(), int(lat * 1e7), int(lon * 1e7),
                                                     int(alt * 1000), int(rel * 1000),
                                                     int(b.vel[1] * 100), int(b.vel[0] * 100), int(-b.vel[2] * 100), hdg)

    def gps_fix(self):
        return 3, 10

    def msg_gps_raw_int(self):
        fix, sats = self.gps_fix()
        if fix < 2:
            return M.MAVLink_gps_raw_int_message(self.boot_us(), fix, 0, 0, 0, 65535, 65535, 0, 0, sats)
        b = self.model.body
        lat, lon, alt = self.geo()
        vel = int(math.hypot(b.vel[0], b.vel[1]) * 100)
        cog = int((math.degrees(math.atan2(b.vel[0], b.vel[1])) % 360) * 100) if vel > 10 else 0
        return M.MAVLink_gps_raw_int_message(self.boot_us(), fix, int(lat * 1e7), int(lon * 1e7), int(alt * 1000),
                                             70, 100, vel, cog, sats)

    def msg_vfr_hud(self):
        b = self.model.body
        spd = math.hypot(b.vel[0], b.vel[1])
        hdg = int(math.degrees(self.yaw_enu_to_ned(b.yaw_rad)) % 360)
        thr = 50 if (self.armed and not b.on_ground) else 0
        return M.MAVLink_vfr_hud_message(spd, spd, hdg, thr, self.geo()[2], b.vel[2])

    # SYS_STATUS sensor bitmasks and battery as captured (overridden per personality)
    sensors_present_enabled_health = (0x20802F, 0x20802F, 0x20802F)
    battery_mv = 16200

    def msg_sys_status(self):
        present, enabled, health = self.sensors_present_enabled_health
        return M.MAVLink_sys_status_message(present, enabled, health, 100, self.battery_mv, -100, 100,
                                            0, 0, 0, 0, 0, 0)

    def msg_battery_status(self):
        cells = [self.battery_mv] + [65535] * 9
        return M.MAVLink_battery_status_message(0, M.MAV_BATTERY_FUNCTION_ALL, M.MAV_BATTERY_TYPE_LIPO, 32767,
                                                cells, -100, 0, -1, 100, 0, M.MAV_BATTERY_CHARGE_STATE_OK)

    def msg_system_time(self):
        return M.MAVLink_system_time_message(int(time.time() * 1e6), self.boot_ms())

    def msg_home_position(self):
        if not self.position_valid():
            return None
        lat, lon, alt = self.world.enu_to_geo(*self.home_enu)
        n, e, d = self.enu_to_ned(self.home_enu)
        return M.MAVLink_home_position_message(int(lat * 1e7), int(lon * 1e7), int(alt * 1000), n, e, d,
                                               [1, 0, 0, 0], 0, 0, 0, self.boot_us())

    def msg_extended_sys_state(self):
        return M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_UNDEFINED, self.landed_state)

    def msg_position_target_local_ned(self):
        t = self.model.target
        if t.kind == "position":
            n, e, d = self.enu_to_ned(t.pos_enu)
            mask = 3576
            vn = ve = vd = 0.0
        elif t.kind == "velocity":
            n = e = d = 0.0
            vn, ve, vd = t.vel_enu[1], t.vel_enu[0], -t.vel_enu[2]
            mask = 3527
        else:
            return None
        yaw = self.yaw_enu_to_ned(t.yaw_rad) if t.yaw_rad is not None else 0.0
        return M.MAVLink_position_target_local_ned_message(self.boot_ms(), M.MAV_FRAME_LOCAL_NED, mask,
                                                           n, e, d, vn, ve, vd, 0, 0, 0, yaw, 0)

    # ------------------------------------------------------------------ sensors
    def range_beams(self):
        """List of (id, orientation, type, min_cm, max_cm, body_heading_rad) horizontal beams."""
        return []

    def down_sensor(self):
        """(id, type, min_cm, max_cm) of the downward rangefinder, or None."""
        return None

    def msg_distance_sensors(self):
        b = self.model.body
        out = []
        down = self.down_sensor()
        if down:
            sid, stype, lo, hi = down
            dist = self.world.down_distance(b.pos[2], b.pos[0], b.pos[1])
            cm = int(min(hi, max(lo, dist * 100)))
            out.append(M.MAVLink_distance_sensor_message(self.boot_ms(), lo, hi, cm, stype, sid,
                                                         M.MAV_SENSOR_ROTATION_PITCH_270, 0))
        for sid, orient, stype, lo, hi, rel in self.range_beams():
            heading = b.yaw_rad - rel  # body FRD yaw offset rel is clockwise; ENU heading is CCW
            dist = self.world.ray_distance(b.pos[0], b.pos[1], b.pos[2], heading, hi / 100.0)
            cm = int(max(lo, min(hi, dist * 100)))
            out.append(M.MAVLink_distance_sensor_message(self.boot_ms(), lo, hi, cm, stype, sid, orient, 0))
        return out

    # ------------------------------------------------------------------ setpoints
    def target_from_local(self, msg):
        """Convert a SET_POSITION_TARGET_LOCAL_NED into a dynamics Target (or None)."""
        mask = msg.type_mask
        frame = msg.coordinate_frame
        b = self.model.body
        yaw = None if mask & IGNORE_YAW else self.yaw_ned_to_enu(msg.yaw)
        yaw_rate = None if mask & IGNORE_YAW_RATE else -msg.yaw_rate
        has_pos = (mask & IGNORE_POS) != IGNORE_POS
        has_vel = (mask & IGNORE_VEL) != IGNORE_VEL
        vx, vy, vz = (msg.vx, msg.vy, msg.vz) if has_vel else (0.0, 0.0, 0.0)
        if frame in (M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_FRD, M.MAV_FRAME_BODY_OFFSET_NED):
            # body-frame velocity: rotate forward/right by heading (NED yaw)
            psi = self.yaw_enu_to_ned(b.yaw_rad)
            vx, vy = vx * math.cos(psi) - vy * math.sin(psi), vx * math.sin(psi) + vy * math.cos(psi)
        vel_enu = (vy, vx, -vz)
        if has_pos:
            if frame in (M.MAV_FRAME_LOCAL_OFFSET_NED, M.MAV_FRAME_BODY_OFFSET_NED):
                n, e, d = self.enu_to_ned(b.pos)
                pos = self.ned_to_enu(n + msg.x, e + msg.y, d + msg.z)
            else:
                pos = self.ned_to_enu(msg.x, msg.y, msg.z)
            if any(math.isnan(v) for v in pos):
                return None
            return Target("position", pos, vel_enu if has_vel else (0.0, 0.0, 0.0), yaw, yaw_rate)
        if has_vel:
            if any(math.isnan(v) for v in vel_enu):
                return None
            return Target("velocity", (0.0, 0.0, 0.0), vel_enu, yaw, yaw_rate)
        return None

    def target_from_global(self, msg):
        mask = msg.type_mask
        if (mask & IGNORE_POS) == IGNORE_POS:
            return None
        x, y, _ = self.world.geo_to_enu(msg.lat_int / 1e7, msg.lon_int / 1e7, 0.0)
        if msg.coordinate_frame in (M.MAV_FRAME_GLOBAL, M.MAV_FRAME_GLOBAL_INT):
            z = msg.alt - self.world.origin["alt_m"]
        else:
            z = self.home_enu[2] + msg.alt
        yaw = None if mask & IGNORE_YAW else self.yaw_ned_to_enu(msg.yaw)
        return Target("position", (x, y, z), (0.0, 0.0, 0.0), yaw, None)

    def on_setpoint_local(self, msg):
        pass

    def on_setpoint_global(self, msg):
        pass

    def on_attitude_target(self, msg):
        pass

    def reposition_target(self, p):
        """DO_REPOSITION p5 lat, p6 lon (degrees, or degE7 from COMMAND_INT), p7 AMSL alt, p4 yaw deg."""
        lat, lon, alt = p[5], p[6], p[7]
        if any(v is None or v != v for v in (lat, lon)):
            b = self.model.body
            x, y = b.pos[0], b.pos[1]
        else:
            if abs(lat) > 1000 or abs(lon) > 1000:
                lat, lon = lat / 1e7, lon / 1e7
            x, y, _ = self.world.geo_to_enu(lat, lon, 0.0)
        z = self.model.body.pos[2] if alt is None or alt != alt else alt - self.world.origin["alt_m"]
        yaw = None if p[4] is None or p[4] != p[4] else self.yaw_ned_to_enu(math.radians(p[4]))
        speed = p[1] if p[1] is not None and p[1] == p[1] and p[1] > 0 else None
        return Target("position", (x, y, z), (0.0, 0.0, 0.0), yaw, None, speed_xy_mps=speed)

    def hold_here(self):
        b = self.model.body
        return Target("position", (b.pos[0], b.pos[1], b.pos[2]), (0.0, 0.0, 0.0), None, None)

    # ------------------------------------------------------------------ control channel view
    def state(self):
        b = self.model.body
        n, e, d = self.enu_to_ned(b.pos)
        return {
            "vehicle": self.index,
            "sysid": self.sysid,
            "personality": self.name,
            "link": self.link.describe,
            "time_s": round(self.clock.now(), 3),
            "boot_count": self.boot_count,
            "rebooting": self.clock.now() < self.rebooting_until,
            "armed": self.armed,
            "mode": self.mode_name(),
            "custom_mode": self.heartbeat_fields()[1],
            "landed_state": self.landed_state,
            "position_enu_m": [round(v, 3) for v in b.pos],
            "velocity_enu_mps": [round(v, 3) for v in b.vel],
            "yaw_enu_rad": round(b.yaw_rad, 4),
            "local_ned_m": [round(v, 3) for v in (n, e, d)],
            "local_origin_enu_m": [round(v, 3) for v in self.origin_enu],
            "on_ground": b.on_ground,
            "target": {"kind": self.model.target.kind,
                       "pos_enu_m": [round(v, 3) for v in self.model.target.pos_enu],
                       "vel_enu_mps": [round(v, 3) for v in self.model.target.vel_enu]},
            "faults": self.faults.describe(self.clock.now()),
            "collision": bool(getattr(self, "_colliding", False)),
            "last_setpoint_age_s": None if self.last_setpoint_sim is None
            else round(self.clock.now() - self.last_setpoint_sim, 3),
            **self.extra_state(),
        }

    def extra_state(self):
        return {}
