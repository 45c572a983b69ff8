"""PX4 personality (as seen in the PX4 SIH captures, PX4 main 2025-07)."""
import math
import struct

from .dynamics import Limits, Target
from .mav import mavlink as M, EventMsg, CurrentModeMsg, CurrentEventSequenceMsg
from .vehicle import Vehicle, pint

MODES = {  # name -> (main, sub)
    "MANUAL": (1, 0), "ALTCTL": (2, 0), "POSCTL": (3, 0), "AUTO.READY": (4, 1),
    "AUTO.TAKEOFF": (4, 2), "AUTO.LOITER": (4, 3), "AUTO.MISSION": (4, 4), "AUTO.RTL": (4, 5),
    "AUTO.LAND": (4, 6), "ACRO": (5, 0), "OFFBOARD": (6, 0), "STABILIZED": (7, 0),
}
BY_NUMBERS = {v: k for k, v in MODES.items()}
STANDARD_MODE = {"POSCTL": 1, "AUTO.RTL": 3, "AUTO.LAND": 7, "AUTO.TAKEOFF": 8}
# PX4 event ids (events JSON, common/px4 namespaces) and log levels as captured
EVENTS = {
    "commander_armed_by": (26266355, 0x66),
    "commander_disarmed_by": (32794487, 0x66),
    "commander_takeoff_detected": (21054825, 0x66),
    "commander_landing_detected": (26622124, 0x66),
    "commander_arm_denied_resolve_failures": (16910493, 0x62),
    "check_modes_offboard_signal": (19865031, 0x33),
    "check_modes_cannot_takeoff": (18648929, 0x66),
    "commander_failsafe_enter_generic": (31382480, 0x42),
}
FORCE_MAGIC = 21196
SPOOLUP_S = 2.0        # arming to leaving the ground (takeoff detected ~1.7-1.9 s after arming)
LAND_DETECT_S = 2.5    # touchdown to "Landing detected"
FAILSAFE_SWITCH_S = 0.06


def custom_mode_of(name):
    main, sub = MODES[name]
    return (main << 16) | (sub << 24)


class Px4Vehicle(Vehicle):
    autopilot = M.MAV_AUTOPILOT_PX4
    name = "px4"
    capabilities = 59647        # as captured
    flight_sw_version = 255
    ack_before_replies = True
    sensors_present_enabled_health = (50348079, 50413615, 320915519)
    battery_mv = 16200

    def limits(self):
        # tuned so offboard takeoff to 5 m, the 11 m go-to and AUTO.LAND take about as long as captured
        return Limits(max_speed_xy_mps=12.0, max_speed_up_mps=3.0, max_speed_down_mps=1.5,
                      max_accel_mps2=4.5, max_accel_z_mps2=1.5, velocity_tau_s=0.6, pos_gain_xy=0.8,
                      pos_gain_z=0.9, max_yaw_rate_rps=math.radians(60))

    def default_params(self):
        f, i = M.MAV_PARAM_TYPE_REAL32, M.MAV_PARAM_TYPE_INT32
        return {
            "COM_OF_LOSS_T": (1.0, f), "COM_OBL_RC_ACT": (4 if self.opts.offboard_loss_action == "land" else 0, i),
            "COM_DISARM_LAND": (2.0, f), "COM_DISARM_PRFLT": (10.0, f), "MIS_TAKEOFF_ALT": (2.5, f),
            "MPC_XY_VEL_MAX": (12.0, f), "MPC_Z_VEL_MAX_UP": (3.0, f), "MPC_Z_VEL_MAX_DN": (1.5, f),
            "MPC_TKO_SPEED": (1.5, f), "MPC_LAND_SPEED": (0.7, f), "RTL_RETURN_ALT": (30.0, f),
            "NAV_DLL_ACT": (0, i), "COM_RC_IN_MODE": (1, i), "MAV_SYS_ID": (self.sysid, i),
            "SYS_AUTOSTART": (10040, i), "COM_ARM_WO_GPS": (1, i),
        }

    # PX4 sends integer params bytewise in the float field
    def _param_encode(self, value, ptype):
        if ptype == M.MAV_PARAM_TYPE_REAL32:
            return float(value)
        return struct.unpack("<f", struct.pack("<i", int(value)))[0]

    def _param_decode(self, value, ptype):
        if ptype == M.MAV_PARAM_TYPE_REAL32:
            return float(value)
        return struct.unpack("<i", struct.pack("<f", value))[0]

    def default_streams(self):
        hz = self.opts.attitude_hz
        return {0: 1.0, 1: 0.2, 2: 1.0, 24: 0.125, 30: 1.0 / hz, 31: 2.0 / hz, 32: 1 / 30, 33: 1.0 / hz,
                331: 1 / 30, 132: 0.1, 245: 0.2, 242: 2.0, 147: 2.0, 436: 2.0, 411: 3.0, 74: 0.2, 85: 0.1,
                111: 0.1}

    def set_message_interval(self, msg_id, interval_us):
        if msg_id == 0:
            return M.MAV_RESULT_FAILED  # PX4: HEARTBEAT's rate is fixed (captured)
        return super().set_message_interval(msg_id, interval_us)

    def generators(self):
        g = super().generators()
        g.update({331: self.msg_odometry, 436: self.msg_current_mode, 411: self.msg_event_sequence,
                  111: self.msg_timesync_request})
        return g

    def personality_boot(self):
        self.mode = "AUTO.LOITER"
        self.intended_mode = self.mode
        self.failsafe = False
        self.airborne = False
        self.event_seq = 0
        self.stream_start = None
        self.prev_sp = None
        self.last_sp_target = None
        self.landed_since = None
        self.landing_detected_at = None
        self.rtl_phase = None
        self.loss_detected_at = None
        self.takeoff_alt_m = None
        self.model.target = Target("idle")

    # ------------------------------------------------------------------ heartbeat
    def offboard_signal(self):
        now = self.clock.now()
        if self.last_setpoint_sim is None or now - self.last_setpoint_sim > self.param("COM_OF_LOSS_T"):
            return False
        return self.stream_start is not None and now - self.stream_start >= self.opts.offboard_prestream_s

    def heartbeat_fields(self):
        base = M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED
        status = M.MAV_STATE_ACTIVE if self.armed else M.MAV_STATE_STANDBY
        if self.mode == "OFFBOARD":
            if self.offboard_signal() or self.armed:
                base |= M.MAV_MODE_FLAG_STABILIZE_ENABLED
            else:
                status = M.MAV_STATE_UNINIT  # as captured: OFFBOARD selected with no signal
        elif self.mode.startswith("AUTO."):
            base |= M.MAV_MODE_FLAG_AUTO_ENABLED | M.MAV_MODE_FLAG_GUIDED_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
            if self.mode == "AUTO.LAND" and not self.armed and self.landing_detected_at is not None:
                status = M.MAV_STATE_UNINIT  # as captured after an auto-disarm in AUTO.LAND
        else:
            base |= M.MAV_MODE_FLAG_MANUAL_INPUT_ENABLED | M.MAV_MODE_FLAG_STABILIZE_ENABLED
        if self.armed:
            base |= M.MAV_MODE_FLAG_SAFETY_ARMED
            if self.failsafe:
                status = M.MAV_STATE_CRITICAL
        return base, custom_mode_of(self.mode), status

    def mode_name(self):
        return self.mode

    def extra_state(self):
        return {"offboard_signal": self.offboard_signal(), "failsafe": self.failsafe,
                "intended_mode": self.intended_mode}

    def in_external_control(self):
        return self.mode == "OFFBOARD"

    # ------------------------------------------------------------------ events
    def event(self, name, args=b""):
        eid, levels = EVENTS[name]
        self.event_seq = (self.event_seq + 1) & 0xFFFF
        self.send(EventMsg(0, 0, eid, self.boot_ms(), self.event_seq, levels, args))
        self.note("event", name, id=eid, sequence=self.event_seq)

    def msg_timesync_request(self):
        """PX4 asks its peers for time sync at 10 Hz (tc1 = 0, ts1 = its time in ns)."""
        return M.MAVLink_timesync_message(0, self.boot_us() * 1000)

    def msg_event_sequence(self):
        return CurrentEventSequenceMsg(self.event_seq, 0)

    def msg_current_mode(self):
        return CurrentModeMsg(STANDARD_MODE.get(self.mode, 0), custom_mode_of(self.mode),
                              custom_mode_of(self.intended_mode))

    def msg_odometry(self):
        """As captured: frame_id and child_frame_id LOCAL_NED (velocity in NED), estimator 8."""
        b = self.model.body
        n, e, d, vn, ve, vd = self._ned_state()
        nan = float("nan")
        pose_cov = [nan] * 21
        vel_cov = [nan] * 21
        for i, v in zip((0, 6, 11, 15, 18, 20), (0.04, 0.04, 0.09, 0.0004, 0.0004, 0.036)):
            pose_cov[i] = v
        for i, v in zip((0, 6, 11), (0.017, 0.017, 0.014)):
            vel_cov[i] = v
        return M.MAVLink_odometry_message(self.boot_us(), M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_NED,
                                          n, e, d + self.opts.px4_z_offset_m, self.quaternion(), vn, ve, vd,
                                          0.0, 0.0, -b.yaw_rate_rps, pose_cov, vel_cov, 0,
                                          M.MAV_ESTIMATOR_TYPE_AUTOPILOT, 0)

    def msg_local_position_ned(self):
        n, e, d, vn, ve, vd = self._ned_state()
        return M.MAVLink_local_position_ned_message(self.boot_ms(), n, e, d + self.opts.px4_z_offset_m, vn, ve, vd)

    def down_sensor(self):
        return (0, M.MAV_DISTANCE_SENSOR_LASER, 0, 10000)

    def range_beams(self):
        if self.opts.rangers == "none":
            return []
        if self.opts.rangers == "prox8":
            return [(10 + k, k, 0, 0, 20000, math.radians(45 * k)) for k in range(8)]
        # Crazyflie multi-ranger style: front, right, back, left; 4 cm .. 4 m
        return [(1, 0, 0, 4, 400, 0.0), (2, 2, 0, 4, 400, math.pi / 2),
                (3, 4, 0, 4, 400, math.pi), (4, 6, 0, 4, 400, -math.pi / 2)]

    # ------------------------------------------------------------------ mode changes
    def set_mode(self, name, reason="command"):
        if name == self.mode:
            return
        prev = self.mode
        self.mode = name
        if reason != "failsafe":
            self.intended_mode = name
            self.failsafe = False
        self.note("mode", f"{prev} -> {name} ({reason})")
        b = self.model.body
        if name == "OFFBOARD":
            if self.armed and self.last_sp_target is not None:
                self.model.target = self.last_sp_target
        elif name == "AUTO.TAKEOFF":
            self.takeoff_xy = (b.pos[0], b.pos[1])
            if self.takeoff_alt_m is None:
                self.takeoff_alt_m = self.home_enu[2] + self.param("MIS_TAKEOFF_ALT")
        elif name == "AUTO.RTL":
            self.rtl_phase = "climb"
        if name != "AUTO.TAKEOFF":
            self.takeoff_alt_m = None
        self.apply_mode_target()
        self.send(self.msg_current_mode())

    def apply_mode_target(self):
        b = self.model.body
        m = self.mode
        if not self.armed:
            self.model.target = Target("idle")
            return
        if m == "OFFBOARD":
            return  # driven by setpoints
        if m in ("AUTO.LOITER", "POSCTL", "ALTCTL", "AUTO.READY", "AUTO.MISSION") and not self.failsafe:
            self.model.target = self.hold_here() if self.airborne else Target("idle")
        elif m == "AUTO.TAKEOFF":
            x, y = getattr(self, "takeoff_xy", (b.pos[0], b.pos[1]))
            self.model.target = Target("position", (x, y, self.takeoff_alt_m), speed_up_mps=self.param("MPC_TKO_SPEED"))
        elif m == "AUTO.LAND" or (self.failsafe and m == "POSCTL"):
            self.land_xy = (b.pos[0], b.pos[1])
            self.model.target = self.land_target()

    def land_target(self):
        x, y = self.land_xy
        fast = self.altitude_agl_m() > 10.0
        spd = self.param("MPC_Z_VEL_MAX_DN") if fast else self.param("MPC_LAND_SPEED")
        if self.failsafe and self.mode == "POSCTL":
            spd = 0.5  # no RC in position mode: slow descent (as captured)
        return Target("position", (x, y, self.model.ground_z_m - 5.0), speed_down_mps=spd)

    # ------------------------------------------------------------------ commands
    def handle_command(self, msg, cmd, p):
        if cmd == M.MAV_CMD_COMPONENT_ARM_DISARM:
            return self.cmd_arm(p)
        if cmd == M.MAV_CMD_DO_SET_MODE:
            if not (pint(p[1]) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED):
                return M.MAV_RESULT_UNSUPPORTED
            main, sub = pint(p[2]), pint(p[3])
            if main != 4:
                sub = 0
            name = BY_NUMBERS.get((main, sub))
            if name is None:
                return M.MAV_RESULT_UNSUPPORTED
            return self.request_mode(name)
        if cmd == M.MAV_CMD_NAV_TAKEOFF:
            alt_amsl = p[7]
            if alt_amsl is None or math.isnan(alt_amsl):
                self.takeoff_alt_m = self.home_enu[2] + self.param("MIS_TAKEOFF_ALT")
            else:
                self.takeoff_alt_m = alt_amsl - self.world.origin["alt_m"]
            alt = self.takeoff_alt_m
            self.set_mode("AUTO.TAKEOFF")
            self.takeoff_alt_m = alt
            self.apply_mode_target()
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_DO_REPOSITION:
            if not (self.armed and self.airborne):
                return M.MAV_RESULT_TEMPORARILY_REJECTED
            target = self.reposition_target(p)
            self.set_mode("AUTO.LOITER")
            self.model.target = target
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_NAV_LAND:
            return self.request_mode("AUTO.LAND")
        if cmd == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return self.request_mode("AUTO.RTL")
        if cmd in (M.MAV_CMD_NAV_LOITER_UNLIM, M.MAV_CMD_DO_PAUSE_CONTINUE):
            return self.request_mode("AUTO.LOITER")
        if cmd == M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            if pint(p[1]) == 1 and not self.armed:
                self.pending_reboot = True
                return M.MAV_RESULT_ACCEPTED
            return M.MAV_RESULT_DENIED
        return M.MAV_RESULT_UNSUPPORTED

    def rc_mode(self, name):
        """The pilot's mode switch: PX4 takes any mode but OFFBOARD without a setpoint stream."""
        if name not in MODES:
            raise ValueError(f"no PX4 mode {name!r}")
        if name == "OFFBOARD" and self.armed and not self.offboard_signal():
            return False
        self.set_mode(name, reason="rc")
        return True

    @staticmethod
    def set_mode_params(name):
        """DO_SET_MODE params 1-3 for a mode, as QGC sends them."""
        if name not in MODES:
            raise ValueError(f"no PX4 mode {name!r}")
        main, sub = MODES[name]
        return [M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, main, sub]

    def request_mode(self, name):
        if name == "OFFBOARD" and self.armed and not self.offboard_signal():
            self.event("check_modes_offboard_signal", bytes([0, 0x40, 0, 0, 0x14]))
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        self.set_mode(name)
        return M.MAV_RESULT_ACCEPTED

    def cmd_arm(self, p):
        force = pint(p[2]) == FORCE_MAGIC
        if pint(p[1]) == 1:
            if self.armed:
                return M.MAV_RESULT_ACCEPTED
            if not force:
                if self.faults.deny_arm_reason:
                    self.event(self.faults.deny_arm_px4_event if self.faults.deny_arm_px4_event in EVENTS
                               else "commander_arm_denied_resolve_failures")
                    self.note("arm_denied", self.faults.deny_arm_reason)
                    return M.MAV_RESULT_TEMPORARILY_REJECTED
                if self.mode == "OFFBOARD" and not self.offboard_signal():
                    self.event("check_modes_offboard_signal", bytes([0, 0x40, 0, 0, 0x14]))
                    self.event("commander_arm_denied_resolve_failures")
                    self.note("arm_denied", "No offboard signal")
                    return M.MAV_RESULT_TEMPORARILY_REJECTED
                if self.mode in ("AUTO.LAND", "AUTO.RTL"):
                    self.event("check_modes_cannot_takeoff")
                    self.event("commander_arm_denied_resolve_failures")
                    self.note("arm_denied", "Mode not suitable for arming")
                    return M.MAV_RESULT_TEMPORARILY_REJECTED
            self.armed = True
            self.armed_time = self.clock.now()
            self.model.liftoff_delay_s = SPOOLUP_S
            self.airborne = False
            self.landing_detected_at = None
            self.landed_since = None
            self.home_enu = tuple(self.model.body.pos)
            self.event("commander_armed_by", bytes([4]))
            if self.mode == "OFFBOARD" and self.last_sp_target is not None:
                self.model.target = self.last_sp_target
            else:
                self.apply_mode_target()
            return M.MAV_RESULT_ACCEPTED
        if not self.armed:
            return M.MAV_RESULT_ACCEPTED
        if self.airborne and not force:
            return M.MAV_RESULT_TEMPORARILY_REJECTED
        self.disarm(4)
        return M.MAV_RESULT_ACCEPTED

    def disarm(self, why):
        self.armed = False
        self.armed_time = None
        self.model.target = Target("idle")
        self.event("commander_disarmed_by", bytes([why]))
        # as captured: a failsafe ends with the user's intended mode back (e.g. OFFBOARD);
        # a user-selected landing/return mode becomes AUTO.LOITER once disarmed
        if self.failsafe:
            self.failsafe = False
            self.set_mode(self.intended_mode, reason="failsafe cleared on disarm")
        elif self.mode in ("AUTO.LAND", "AUTO.RTL", "AUTO.TAKEOFF"):
            self.set_mode("AUTO.LOITER", reason="disarmed")

    # ------------------------------------------------------------------ setpoints
    def on_setpoint_local(self, msg):
        now = self.clock.now()
        if self.prev_sp is None or now - self.prev_sp > 0.6:
            self.stream_start = now
        self.prev_sp = now
        t = self.target_from_local(msg)
        if t is None:
            return
        self.last_sp_target = t
        if self.mode == "OFFBOARD" and self.armed:
            self.model.target = t

    def on_setpoint_global(self, msg):
        self.on_setpoint_any()
        t = self.target_from_global(msg)
        if t is not None:
            self.last_sp_target = t
            if self.mode == "OFFBOARD" and self.armed:
                self.model.target = t

    def on_setpoint_any(self):
        now = self.clock.now()
        if self.prev_sp is None or now - self.prev_sp > 0.6:
            self.stream_start = now
        self.prev_sp = now

    def on_attitude_target(self, msg):
        """Attitude + thrust offboard: tilt -> horizontal velocity, thrust -> climb rate
        (0.5 = hover). A coarse stand-in for PX4's attitude control."""
        self.on_setpoint_any()
        q = msg.q
        roll = math.atan2(2 * (q[0] * q[1] + q[2] * q[3]), 1 - 2 * (q[1] ** 2 + q[2] ** 2))
        pitch = math.asin(max(-1.0, min(1.0, 2 * (q[0] * q[2] - q[3] * q[1]))))
        yaw_ned = math.atan2(2 * (q[0] * q[3] + q[1] * q[2]), 1 - 2 * (q[2] ** 2 + q[3] ** 2))
        k = 9.81 * 0.5  # m/s per rad of tilt held for ~0.5 s
        vf, vr = -math.tan(pitch) * k * 2, math.tan(roll) * k * 2
        vup = (msg.thrust - 0.5) * 6.0
        psi = yaw_ned
        vn = vf * math.cos(psi) - vr * math.sin(psi)
        ve = vf * math.sin(psi) + vr * math.cos(psi)
        t = Target("velocity", (0.0, 0.0, 0.0), (ve, vn, vup), self.yaw_ned_to_enu(yaw_ned), None)
        self.last_sp_target = t
        if self.mode == "OFFBOARD" and self.armed:
            self.model.target = t

    # ------------------------------------------------------------------ per tick
    def update(self, now, dt):
        if getattr(self, "pending_reboot", False):
            self.pending_reboot = False
            self.reboot(self.opts.reboot_gap_s)
            return
        b = self.model.body
        agl = self.altitude_agl_m()
        # offboard loss failsafe: health events at COM_OF_LOSS_T, mode switch ~60 ms later
        # (captured: events 1.01 s, CURRENT_MODE 1.06-1.11 s after the last setpoint)
        if self.mode == "OFFBOARD" and self.armed and not self.offboard_signal():
            if self.loss_detected_at is None:
                self.loss_detected_at = now
                self.note("failsafe", "offboard signal lost")
                self.event("check_modes_offboard_signal", bytes([0, 0x40, 0, 0, 0x14]))
            elif now - self.loss_detected_at >= FAILSAFE_SWITCH_S:
                self.loss_detected_at = None
                self.failsafe = True
                target_mode = "AUTO.LAND" if self.param("COM_OBL_RC_ACT") == 4 else "POSCTL"
                self.event("commander_failsafe_enter_generic", bytes([0, 0, 6, 0, 2]))
                self.set_mode(target_mode, reason="failsafe")
                self.apply_mode_target()
        else:
            self.loss_detected_at = None
        if not self.armed:
            self.landed_state = M.MAV_LANDED_STATE_ON_GROUND if b.on_ground else M.MAV_LANDED_STATE_IN_AIR
            return
        # takeoff detection
        if not self.airborne and agl > 0.3:
            self.airborne = True
            self.event("commander_takeoff_detected")
            if self.mode in ("AUTO.LOITER", "POSCTL") and not self.failsafe:
                self.model.target = self.hold_here()
        # mode behaviours
        if self.mode == "AUTO.TAKEOFF" and self.takeoff_alt_m is not None:
            if abs(b.pos[2] - self.takeoff_alt_m) < 0.25 and abs(b.vel[2]) < 0.3:
                self.set_mode("AUTO.LOITER", reason="takeoff complete")
                self.model.target = self.hold_here()
        elif self.mode == "AUTO.RTL":
            self.update_rtl()
        if self.mode == "AUTO.LAND" or (self.failsafe and self.mode == "POSCTL"):
            if self.model.target.kind == "position":
                self.model.target = self.land_target() if hasattr(self, "land_xy") else self.model.target
        # landed state
        landing = self.mode == "AUTO.LAND" or (self.failsafe and self.mode == "POSCTL") or \
            (self.mode == "AUTO.RTL" and self.rtl_phase == "land")
        if self.airborne:
            if b.on_ground:
                self.landed_since = self.landed_since or now
                if now - self.landed_since >= LAND_DETECT_S and self.landing_detected_at is None:
                    self.landing_detected_at = now
                    self.event("commander_landing_detected")
                    self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
                    self.model.target = Target("idle")
                if self.landing_detected_at is not None and \
                        now - self.landing_detected_at >= self.param("COM_DISARM_LAND"):
                    self.airborne = False
                    self.disarm(6)
                    self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
                    return
            else:
                self.landed_since = None
                if landing:
                    self.landed_state = M.MAV_LANDED_STATE_LANDING
                elif self.mode == "AUTO.TAKEOFF":
                    self.landed_state = M.MAV_LANDED_STATE_TAKEOFF
                else:
                    self.landed_state = M.MAV_LANDED_STATE_IN_AIR
        else:
            self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
            if self.armed_time is not None and now - self.armed_time > self.param("COM_DISARM_PRFLT") \
                    and not (self.model.target.kind != "idle" and self.mode in ("OFFBOARD", "AUTO.TAKEOFF")):
                self.disarm(6)

    def update_rtl(self):
        b = self.model.body
        home = self.home_enu
        alt = max(b.pos[2], home[2] + min(self.param("RTL_RETURN_ALT"), 30.0))
        if self.rtl_phase == "climb":
            self.model.target = Target("position", (b.pos[0], b.pos[1], alt))
            if abs(b.pos[2] - alt) < 0.5:
                self.rtl_phase = "return"
                self.rtl_alt = alt
        elif self.rtl_phase == "return":
            self.model.target = Target("position", (home[0], home[1], self.rtl_alt), speed_xy_mps=10.0)
            if math.hypot(b.pos[0] - home[0], b.pos[1] - home[1]) < 0.5:
                self.rtl_phase = "land"
                self.land_xy = (home[0], home[1])
        elif self.rtl_phase == "land":
            self.model.target = self.land_target()
