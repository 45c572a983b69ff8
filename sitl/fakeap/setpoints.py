"""Setpoint decoding (SET_POSITION_TARGET_*, DO_REPOSITION) into dynamics targets.
A mixin of Vehicle."""
import math

from .dynamics import Target
from .mav import mavlink as M

# SET_POSITION_TARGET type_mask bits
IGNORE_POS = 0x7
IGNORE_VEL = 0x38
IGNORE_YAW = 0x400
IGNORE_YAW_RATE = 0x800


class SetpointMixin:
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

