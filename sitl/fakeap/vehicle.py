"""Personality-independent part of a simulated vehicle: boot, link I/O with faults,
commands, params, stream scheduling, frames and the control-channel view."""
import json
import math
import socket
import sys
import time
from collections import deque

from .dynamics import Multirotor, Target, Wander, wrap_pi
from .faults import Faults, SetpointStats, DelayLine
from .mav import mavlink
from .setpoints import SetpointMixin
from .telemetry import TelemetryMixin

M = mavlink
GCS_SYSID, GCS_COMPID = 255, 190  # QGroundControl's ids on the autopilot's own GCS link


def pint(value):
    """Integer value of a float command parameter (NaN/None -> 0)."""
    if value is None or value != value or value in (float("inf"), float("-inf")):
        return 0
    return int(round(value))


class Vehicle(TelemetryMixin, SetpointMixin):
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
        # what arrived from the companion and other senders: (t, kind, detail, src_sys, src_comp)
        self.received = deque(maxlen=20000)
        self.last_ack_result = None
        self.out_delay = DelayLine()
        self.in_delay = DelayLine()
        self.gcs_sock = None
        self.rebooting_until = 0.0
        self.boot_count = 0
        x, y, yaw = start_pose
        self.model = Multirotor(x, y, yaw, self.limits(),
                                wander=Wander(getattr(opts, "velocity_wander_mps", 0.0), seed=opts.seed + 7 * index,
                                              in_estimate=getattr(opts, "velocity_wander_in_estimate", False)))
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

    def setpoints_expected(self):
        """Whether the autopilot now flies on the companion's setpoint stream (and would fail
        over without it). ArduPilot's own NAV_TAKEOFF climb in GUIDED is not such a time."""
        return self.in_external_control()

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
        f = self.faults
        if f.latency_s > 0 or f.jitter_s > 0:
            jitter = f.rng.uniform(0.0, f.jitter_s) if f.jitter_s > 0 else 0.0
            self.out_delay.push(time.monotonic() + f.latency_s + jitter, data)
        else:
            self.link.send(data)

    def ack(self, msg, command, result):
        self.send(M.MAVLink_command_ack_message(command, result, 0, 0, msg.get_srcSystem(), msg.get_srcComponent()))
        self.last_ack_result = result
        self.note("ack", f"command {command} -> {result}", command=command, result=result,
                  src=[msg.get_srcSystem(), msg.get_srcComponent()])

    # ------------------------------------------------------------------ other pilots
    def from_gcs(self, command, params):
        """A COMMAND_LONG from a ground station on the autopilot's own GCS link (QGC sending
        DO_SET_MODE, NAV_LAND, a disarm): handled exactly as one from the companion's link,
        returns the COMMAND_ACK result (the ACK also goes out, addressed to the GCS)."""
        p = [float(x) for x in list(params) + [0.0] * (7 - len(params))]
        gcs = M.MAVLink(None, srcSystem=GCS_SYSID, srcComponent=GCS_COMPID)
        frame = M.MAVLink_command_long_message(self.sysid, 1, int(command), 0, *p).pack(gcs)
        self.last_ack_result = None
        for msg in M.MAVLink(None).parse_buffer(frame) or []:
            self.note("gcs", f"COMMAND_LONG {int(command)} {p}")
            self.dispatch(msg, time.monotonic())
        return self.last_ack_result

    def rc_mode(self, name):
        """The pilot's flight-mode switch on the RC transmitter: a mode change with no MAVLink
        command at all. Returns whether the autopilot took it."""
        raise NotImplementedError

    def received_since(self, since):
        """What the vehicle received since `since` (simulated s): setpoints counted, commands
        and mode changes listed with their sender."""
        setpoints = [e for e in self.received if e[0] >= since and e[1] == "setpoint"]
        others = [{"t": round(e[0], 3), "kind": e[1], "detail": e[2], "src": [e[3], e[4]]}
                  for e in self.received if e[0] >= since and e[1] != "setpoint"]
        return {"setpoints": len(setpoints),
                "last_setpoint_t": round(setpoints[-1][0], 3) if setpoints else None,
                "commands": others}

    def _record(self, msg, kind, detail):
        self.received.append((self.clock.now(), kind, detail, msg.get_srcSystem(), msg.get_srcComponent()))

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

    def forward_to_gcs(self, msg):
        """PX4 with MAVLink forwarding on (MAV_x_FORWARD): a message from the companion that is
        not for this autopilot (no target, e.g. HEARTBEAT and STATUSTEXT, or another system's)
        goes on, byte for byte, to the ground-station link (here UDP --gcs-port-base + N)."""
        port = getattr(self.opts, "gcs_port_base", 0)
        if not port or getattr(msg, "target_system", 0) == self.sysid:
            return
        if self.gcs_sock is None:
            self.gcs_sock = socket.socket(socket.AF_INET, socket.SOCK_DGRAM)
        try:
            self.gcs_sock.sendto(msg.get_msgbuf(), ("127.0.0.1", port + self.index))
        except OSError:
            pass  # no ground station listening: UDP drops

    def dispatch(self, msg, wall):
        self.forward_to_gcs(msg)
        try:
            self._dispatch(msg, wall)
        except Exception as exc:  # a malformed request must never kill the fake
            text = f"{msg.get_type()}: {type(exc).__name__}: {exc}"
            self.note("error", text)
            sys.stderr.write(f"fake autopilot vehicle {self.index}: error handling {text}\n")

    def _dispatch(self, msg, wall):
        t = msg.get_type()
        if t in ("COMMAND_LONG", "COMMAND_INT"):
            self._record(msg, "command", msg.command)
        elif t == "SET_MODE":
            self._record(msg, "set_mode", msg.custom_mode)
        elif t in ("SET_POSITION_TARGET_LOCAL_NED", "SET_POSITION_TARGET_GLOBAL_INT", "SET_ATTITUDE_TARGET"):
            self._record(msg, "setpoint", t)
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
                self.stats.record(wall, self.setpoints_expected())
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
        if not self.setpoints_expected():
            self.stats.break_stream()
        self.model.step(dt, self.armed)
        if self.opts.collisions and self.world.collides(*self.model.body.pos):
            if not getattr(self, "_colliding", False):
                self.note("collision", "vehicle hit an obstacle", pos_enu=[round(v, 2) for v in self.model.body.pos])
            self._colliding = True
        else:
            self._colliding = False

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
