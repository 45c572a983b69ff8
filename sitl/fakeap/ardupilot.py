"""ArduPilot (ArduCopter 4.x) personality, as seen in the ArduCopter SITL captures."""
import math

from .dynamics import Limits, Target
from .mav import mavlink as M
from .vehicle import Vehicle, pint

MODES = {0: "STABILIZE", 1: "ACRO", 2: "ALT_HOLD", 3: "AUTO", 4: "GUIDED", 5: "LOITER", 6: "RTL",
         7: "CIRCLE", 9: "LAND", 16: "POSHOLD", 17: "BRAKE", 21: "SMART_RTL"}
NEEDS_POSITION = {3, 4, 5, 6, 7, 16, 17, 21}
GUIDED_FLAG_MODES = {3, 4, 5, 6, 7, 9, 16, 17, 21}
NOT_ARMABLE = {6, 9, 21}
FORCE_MAGICS = (2989, 21196)
# REQUEST_DATA_STREAM groups -> message ids we generate
DATA_STREAMS = {1: [], 2: [1, 24, 245], 3: [], 4: [], 6: [33, 32], 10: [30], 11: [74], 12: [2, 132, 147, 193]}
EKF_FLAGS_NO_POSITION = 0xA7   # attitude, velocities, vertical abs, const-pos mode (captured 167)
EKF_FLAGS_GPS = 0x33F          # + horizontal rel/abs position, predicted positions (captured 831)
BOOT_S = 2.0
TAKEOFF_SPOOL_S = 2.0   # NAV_TAKEOFF to leaving the ground (captured takeoff: 7.1 s to 4.76 m)


class ArduPilotVehicle(Vehicle):
    autopilot = M.MAV_AUTOPILOT_ARDUPILOTMEGA
    name = "ardupilot"
    capabilities = 64495        # as captured (4.7.0-dev)
    flight_sw_version = 67567616
    sensors_present_enabled_health = (1399979023, 1380031503, 1196530703)
    battery_mv = 12600

    def limits(self):
        return Limits(max_speed_xy_mps=5.0, max_speed_up_mps=2.5, max_speed_down_mps=1.5,
                      max_accel_mps2=2.5, max_accel_z_mps2=0.8, velocity_tau_s=0.8, pos_gain_xy=1.0, pos_gain_z=1.0,
                      max_yaw_rate_rps=math.radians(90))

    def default_params(self):
        f, i = M.MAV_PARAM_TYPE_REAL32, M.MAV_PARAM_TYPE_INT8
        return {"GUID_TIMEOUT": (3.0, f), "WPNAV_SPEED": (500.0, f), "WPNAV_SPEED_UP": (250.0, f),
                "WPNAV_SPEED_DN": (150.0, f), "LAND_SPEED": (50.0, f), "RTL_ALT": (1500.0, f),
                "DISARM_DELAY": (10, i), "SYSID_THISMAV": (self.sysid, i), "FRAME_CLASS": (1, i)}

    def default_streams(self):
        return {0: 1.0}  # nothing useful until asked

    def generators(self):
        g = super().generators()
        g[193] = self.msg_ekf_status
        return g

    def unknown_stream_result(self, msg_id):
        self.statustext(6, f"No ap_message for mavlink id ({msg_id})")
        return M.MAV_RESULT_DENIED

    def personality_boot(self):
        self.mode = 0
        self.airborne = False
        self.taking_off = False
        self.takeoff_alt_m = None
        self.vel_target_time = None
        self.landed_since = None
        self.landing_detected_at = None
        self.rtl_phase = None
        self.origin_set = False
        self.gps_ok = False
        self.pos_ok = False
        self.gps_detected = False
        self.model.target = Target("idle")

    # ------------------------------------------------------------------ identity
    def heartbeat_fields(self):
        if self.clock.now() - self.boot_time < BOOT_S:
            return 89, 0, M.MAV_STATE_BOOT  # as captured during the first seconds
        base = 81 | (8 if self.mode in GUIDED_FLAG_MODES else 0) | (128 if self.armed else 0)
        flying = self.armed and self.airborne and self.landed_state != M.MAV_LANDED_STATE_ON_GROUND
        status = M.MAV_STATE_ACTIVE if flying else M.MAV_STATE_STANDBY
        return base, self.mode, status

    def mode_name(self):
        return MODES.get(self.mode, str(self.mode))

    def extra_state(self):
        return {"ekf_position_ok": self.pos_ok, "origin_set": self.origin_set}

    def in_external_control(self):
        return self.mode == 4

    def setpoints_expected(self):
        return self.mode == 4 and not self.taking_off

    def statustext(self, severity, text):
        self.send(M.MAVLink_statustext_message(severity, text.encode()[:50], 0, 0))
        self.note("statustext", text, severity=severity)

    def position_valid(self):
        return self.pos_ok

    def gps_fix(self):
        if self.opts.no_gps or not self.gps_detected:
            return 0, 0
        return 6, 10

    def msg_ekf_status(self):
        flags = EKF_FLAGS_GPS if self.pos_ok else EKF_FLAGS_NO_POSITION
        return M.MAVLink_ekf_status_report_message(flags, 0.01, 0.01, 0.01, 0.01, 0.0, 0.0)

    def msg_extended_sys_state(self):
        return M.MAVLink_extended_sys_state_message(M.MAV_VTOL_STATE_MC, self.landed_state)  # as captured

    def down_sensor(self):
        return (0, M.MAV_DISTANCE_SENSOR_UNKNOWN, 20, 4000)

    def range_beams(self):
        if self.opts.rangers == "none":
            return []
        if self.opts.rangers == "cf4":
            return [(1, 0, 0, 4, 400, 0.0), (2, 2, 0, 4, 400, math.pi / 2),
                    (3, 4, 0, 4, 400, math.pi), (4, 6, 0, 4, 400, -math.pi / 2)]
        return [(10 + k, k, 0, 0, 20000, math.radians(45 * k)) for k in range(8)]

    def msg_distance_sensors(self):
        out = super().msg_distance_sensors()
        if self.opts.rangers == "prox8":  # the lidar's upward sector, nothing above
            out.append(M.MAVLink_distance_sensor_message(self.boot_ms(), 0, 20000, 10000, 0, 19,
                                                         M.MAV_SENSOR_ROTATION_PITCH_90, 0))
        return out

    # ------------------------------------------------------------------ modes
    def set_mode(self, number, source):
        """Returns True if the mode changed (or was already set)."""
        if number not in MODES:
            return False
        if number == 3:
            self.statustext(6, "Mode change to AUTO failed: no mission")
            return False
        if self.armed and number in NEEDS_POSITION and not self.pos_ok:
            self.statustext(6, f"Mode change to {MODES[number]} failed: requires position")
            return False
        if number != self.mode:
            self.note("mode", f"{self.mode_name()} -> {MODES[number]} ({source})")
            self.mode = number
            self.enter_mode()
            self.send(self.msg_heartbeat())  # ArduPilot announces a mode change at once
        return True

    def rc_mode(self, name):
        """The pilot's flight-mode switch (RC channel 5): the same checks as any mode change."""
        return self.set_mode(self.mode_number(name), "RC")

    @staticmethod
    def mode_number(name):
        numbers = {v: k for k, v in MODES.items()}
        if name not in numbers:
            raise ValueError(f"no ArduCopter mode {name!r}")
        return numbers[name]

    @classmethod
    def set_mode_params(cls, name):
        """DO_SET_MODE params 1-2 for a mode, as a ground station sends them."""
        return [M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED, cls.mode_number(name)]

    def enter_mode(self):
        b = self.model.body
        self.vel_target_time = None
        if not self.armed:
            self.model.target = Target("idle")
            return
        if self.mode == 9:
            self.land_xy = (b.pos[0], b.pos[1])
            self.model.target = self.land_target()
        elif self.mode == 6:
            self.rtl_phase = "climb"
        elif self.airborne:
            self.model.target = self.hold_here()
        else:
            self.model.target = Target("idle")
        self.taking_off = False

    def land_target(self):
        x, y = self.land_xy
        spd = self.param("WPNAV_SPEED_DN") / 100 if self.altitude_agl_m() > 10 else self.param("LAND_SPEED") / 100
        return Target("position", (x, y, self.model.ground_z_m - 5.0), speed_down_mps=spd)

    # ------------------------------------------------------------------ messages
    def handle_other(self, msg):
        t = msg.get_type()
        if t == "SET_MODE":
            if msg.target_system == self.sysid and msg.base_mode & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                self.set_mode(msg.custom_mode, "SET_MODE")  # legacy message: no COMMAND_ACK
        elif t == "REQUEST_DATA_STREAM":
            if msg.target_system in (0, self.sysid):
                ids = sorted({i for k, v in DATA_STREAMS.items() for i in v}) if msg.req_stream_id == 0 \
                    else DATA_STREAMS.get(msg.req_stream_id, [])
                for mid in ids:
                    on = msg.start_stop and msg.req_message_rate > 0
                    self.streams[mid] = 1.0 / msg.req_message_rate if on else 0.0
                    self.next_due.pop(mid, None)
        elif t == "SET_GPS_GLOBAL_ORIGIN":
            if msg.target_system in (0, self.sysid):
                self.set_origin(msg.latitude / 1e7, msg.longitude / 1e7, msg.altitude / 1000.0, "SET_GPS_GLOBAL_ORIGIN")

    def set_origin(self, lat, lon, alt, source):
        if self.origin_set:
            self.note("origin", f"{source} ignored: origin already set")
            return
        self.origin_set = True
        x, y, z = self.world.geo_to_enu(lat, lon, alt)
        self.origin_enu = (x, y, z)
        self.origin_geo = (lat, lon, alt)
        self.home_enu = tuple(self.model.body.pos)
        self.statustext(6, "EKF3 IMU0 origin set")
        self.statustext(6, "EKF3 IMU1 origin set")
        self.send(self.msg_gps_global_origin())
        if self.opts.no_gps:
            self.pos_ok = True

    def msg_gps_global_origin(self):
        lat, lon, alt = getattr(self, "origin_geo", self.world.enu_to_geo(*self.origin_enu))
        return M.MAVLink_gps_global_origin_message(int(lat * 1e7), int(lon * 1e7), int(alt * 1000), self.boot_us())

    def on_setpoint_local(self, msg):
        if self.mode != 4:
            return
        if msg.coordinate_frame not in (M.MAV_FRAME_LOCAL_NED, M.MAV_FRAME_LOCAL_OFFSET_NED,
                                        M.MAV_FRAME_BODY_NED, M.MAV_FRAME_BODY_OFFSET_NED):
            return
        t = self.target_from_local(msg)
        if t is None or not self.armed or not self.airborne or self.taking_off and t.kind != "position":
            return
        self.taking_off = False
        self.model.target = t
        self.vel_target_time = self.clock.now() if t.kind == "velocity" else None

    def on_setpoint_global(self, msg):
        if self.mode != 4 or not self.armed or not self.airborne:
            return
        t = self.target_from_global(msg)
        if t is not None:
            self.taking_off = False
            self.model.target = t
            self.vel_target_time = None

    # ------------------------------------------------------------------ commands
    def handle_command(self, msg, cmd, p):
        if cmd == M.MAV_CMD_DO_SET_MODE:
            if not pint(p[1]) & M.MAV_MODE_FLAG_CUSTOM_MODE_ENABLED:
                return M.MAV_RESULT_UNSUPPORTED
            return M.MAV_RESULT_ACCEPTED if self.set_mode(pint(p[2]), "DO_SET_MODE") else M.MAV_RESULT_FAILED
        if cmd == M.MAV_CMD_COMPONENT_ARM_DISARM:
            return self.cmd_arm(p)
        if cmd == M.MAV_CMD_NAV_TAKEOFF:
            if self.mode != 4 or not self.armed or self.airborne:
                return M.MAV_RESULT_FAILED
            b = self.model.body
            self.takeoff_alt_m = self.model.ground_z_m + max(0.0, p[7])
            self.taking_off = True
            self.model.liftoff_delay_s = TAKEOFF_SPOOL_S
            self.model.target = Target("position", (b.pos[0], b.pos[1], self.takeoff_alt_m),
                                       speed_up_mps=self.param("WPNAV_SPEED_UP") / 100)
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_DO_REPOSITION:
            if pint(p[2]) & 1 and self.mode != 4:
                if not self.set_mode(4, "DO_REPOSITION"):
                    return M.MAV_RESULT_FAILED
            if self.mode != 4 or not self.armed or not self.airborne:
                return M.MAV_RESULT_FAILED
            self.taking_off = False
            self.model.target = self.reposition_target(p)
            self.vel_target_time = None
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_CONDITION_YAW:
            if self.mode != 4 or not self.armed:
                return M.MAV_RESULT_FAILED
            b = self.model.body
            angle = math.radians(p[1] or 0.0)
            if pint(p[4]):  # relative, p3 direction: 1 clockwise, -1 counter-clockwise
                yaw_ned = self.yaw_enu_to_ned(b.yaw_rad) + (angle if pint(p[3]) >= 0 else -angle)
            else:
                yaw_ned = angle
            t = self.model.target
            if t.kind == "idle" or not self.airborne:
                return M.MAV_RESULT_FAILED
            t.yaw_rad = self.yaw_ned_to_enu(yaw_ned)
            t.yaw_rate_rps = None
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_NAV_LAND:
            return M.MAV_RESULT_ACCEPTED if self.set_mode(9, "NAV_LAND") else M.MAV_RESULT_FAILED
        if cmd == M.MAV_CMD_NAV_RETURN_TO_LAUNCH:
            return M.MAV_RESULT_ACCEPTED if self.set_mode(6, "NAV_RTL") else M.MAV_RESULT_FAILED
        if cmd == M.MAV_CMD_REQUEST_MESSAGE and pint(p[1]) == 49:
            self.send(self.msg_gps_global_origin())
            return M.MAV_RESULT_ACCEPTED
        if cmd == M.MAV_CMD_PREFLIGHT_REBOOT_SHUTDOWN:
            if pint(p[1]) == 1 and not self.armed:
                self.pending_reboot = True
                return M.MAV_RESULT_ACCEPTED
            return M.MAV_RESULT_FAILED
        return M.MAV_RESULT_UNSUPPORTED

    def request_message(self, msg_id, req):
        if msg_id == 49:
            if not self.origin_set:
                return M.MAV_RESULT_FAILED
            self.ack(req, M.MAV_CMD_REQUEST_MESSAGE, M.MAV_RESULT_ACCEPTED)
            self.send(self.msg_gps_global_origin())
            return None
        gen = self.generators().get(msg_id)
        if msg_id != 148 and gen is None:
            return M.MAV_RESULT_UNSUPPORTED
        # ArduPilot acknowledges first, then sends the message
        self.ack(req, M.MAV_CMD_REQUEST_MESSAGE, M.MAV_RESULT_ACCEPTED)
        for m in self._as_list(self.autopilot_version() if msg_id == 148 else gen()):
            self.send(m)
        return None

    def cmd_arm(self, p):
        force = pint(p[2]) in FORCE_MAGICS
        if pint(p[1]) == 1:
            if self.armed:
                return M.MAV_RESULT_ACCEPTED
            if not force:
                reason = None
                if self.faults.deny_arm_reason:
                    reason = self.faults.deny_arm_reason
                elif self.mode in NOT_ARMABLE:
                    reason = "Mode not armable"
                elif self.mode in NEEDS_POSITION and not self.pos_ok:
                    reason = "Need Position Estimate"
                if reason:
                    self.statustext(M.MAV_SEVERITY_CRITICAL, f"Arm: {reason}")
                    self.note("arm_denied", reason)
                    return M.MAV_RESULT_FAILED
            self.armed = True
            self.armed_time = self.clock.now()
            self.airborne = False
            self.landing_detected_at = None
            self.landed_since = None
            self.home_enu = tuple(self.model.body.pos)
            self.statustext(6, "Arming motors")
            if self.origin_set:
                self.send(self.msg_gps_global_origin())
            self.enter_mode()
            return M.MAV_RESULT_ACCEPTED
        if not self.armed:
            return M.MAV_RESULT_ACCEPTED
        if self.airborne and not force:
            return M.MAV_RESULT_FAILED
        self.disarm()
        return M.MAV_RESULT_ACCEPTED

    def disarm(self):
        self.armed = False
        self.armed_time = None
        self.taking_off = False
        self.model.target = Target("idle")
        self.statustext(6, "Disarming motors")

    # ------------------------------------------------------------------ per tick
    def update(self, now, dt):
        if getattr(self, "pending_reboot", False):
            self.pending_reboot = False
            self.reboot(self.opts.reboot_gap_s)
            return
        self.update_ekf(now)
        b = self.model.body
        agl = self.altitude_agl_m()
        if not self.armed:
            self.landed_state = M.MAV_LANDED_STATE_ON_GROUND if b.on_ground else M.MAV_LANDED_STATE_IN_AIR
            return
        if not self.airborne and agl > 0.3:
            self.airborne = True
        if self.taking_off and self.takeoff_alt_m is not None and abs(b.pos[2] - self.takeoff_alt_m) < 0.1:
            self.taking_off = False
            self.model.target = self.hold_here()
        # GUID_TIMEOUT: velocity targets must be refreshed
        if self.mode == 4 and self.vel_target_time is not None and \
                now - self.vel_target_time > self.param("GUID_TIMEOUT"):
            self.vel_target_time = None
            self.model.target = Target("velocity", (0.0, 0.0, 0.0), (0.0, 0.0, 0.0))
            self.note("guided", "velocity target timed out (GUID_TIMEOUT): stopping")
        if self.mode == 9 and self.model.target.kind == "position":
            self.model.target = self.land_target()
        elif self.mode == 6:
            self.update_rtl()
        landing = self.mode == 9 or (self.mode == 6 and self.rtl_phase == "land")
        if self.airborne:
            if b.on_ground:
                self.landed_since = self.landed_since or now
                if now - self.landed_since >= 1.0 and self.landing_detected_at is None:
                    self.landing_detected_at = now
                    self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
                    self.model.target = Target("idle")
                if self.landing_detected_at is not None and now - self.landing_detected_at >= 0.2:
                    self.airborne = False
                    self.disarm()
                    self.landed_state = M.MAV_LANDED_STATE_ON_GROUND
                    return
            else:
                self.landed_since = None
                if landing:
                    self.landed_state = M.MAV_LANDED_STATE_LANDING
                elif self.taking_off:
                    self.landed_state = M.MAV_LANDED_STATE_TAKEOFF
                else:
                    self.landed_state = M.MAV_LANDED_STATE_IN_AIR
        else:
            self.landed_state = M.MAV_LANDED_STATE_TAKEOFF if self.taking_off else M.MAV_LANDED_STATE_ON_GROUND
            if not self.taking_off and self.armed_time is not None and \
                    now - self.armed_time > self.param("DISARM_DELAY"):
                self.note("auto_disarm", "armed on the ground for DISARM_DELAY")
                self.disarm()

    def update_ekf(self, now):
        since = now - self.boot_time
        d = self.opts.ekf_delay
        if self.opts.no_gps:
            return
        if not self.gps_detected and since >= 0.22 * d:
            self.gps_detected = True
            self.statustext(6, "GPS 1: detected u-blox")
        if not self.origin_set and since >= 0.45 * d:
            self.set_origin(*self.world.enu_to_geo(*self.origin_enu), source="GPS")
        if not self.pos_ok and since >= d:
            self.pos_ok = True
            self.statustext(6, "EKF3 IMU0 is using GPS")
            self.statustext(6, "EKF3 IMU1 is using GPS")

    def update_rtl(self):
        b = self.model.body
        home = self.home_enu
        if self.rtl_phase == "climb":
            self.rtl_alt = max(b.pos[2], home[2] + self.param("RTL_ALT") / 100)
            self.model.target = Target("position", (b.pos[0], b.pos[1], self.rtl_alt))
            if abs(b.pos[2] - self.rtl_alt) < 0.5:
                self.rtl_phase = "return"
        elif self.rtl_phase == "return":
            self.model.target = Target("position", (home[0], home[1], self.rtl_alt))
            if math.hypot(b.pos[0] - home[0], b.pos[1] - home[1]) < 0.5:
                self.rtl_phase = "land"
                self.land_xy = (home[0], home[1])
        elif self.rtl_phase == "land":
            self.model.target = self.land_target()
