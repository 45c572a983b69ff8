"""Telemetry common to both personalities: message generators and range sensors.
A mixin of Vehicle; personalities override what differs."""
import math
import time

from .mav import mavlink as M


class TelemetryMixin:
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

    def estimated_vel(self):
        """The velocity the estimator reports (ENU): the truth, or with the wander in the
        estimate (`--velocity-wander-in-estimate`) the truth less the horizontal wander."""
        b, w = self.model.body, self.model.wander
        if not w.in_estimate:
            return list(b.vel)
        return [b.vel[0] - w.v[0], b.vel[1] - w.v[1], b.vel[2]]

    def _ned_state(self):
        b = self.model.body
        n, e, d = self.enu_to_ned(b.pos)
        v = self.estimated_vel()
        vn, ve, vd = v[1], v[0], -v[2]
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
        v = self.estimated_vel()
        lat, lon, alt = self.geo()
        rel = b.pos[2] - self.home_enu[2]
        hdg = int((math.degrees(self.yaw_enu_to_ned(b.yaw_rad)) % 360) * 100)
        return M.MAVLink_global_position_int_message(self.boot_ms(), int(lat * 1e7), int(lon * 1e7),
                                                     int(alt * 1000), int(rel * 1000),
                                                     int(v[1] * 100), int(v[0] * 100), int(-v[2] * 100), hdg)

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

