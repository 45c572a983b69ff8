"""World model: obstacles from the world JSON, ray casting for range sensors, geodesy.

World coordinates are ENU (x east, y north, z up), metres. Obstacles are vertical
cylinders (poles) and yawed boxes with a height (poles are infinitely tall).
"""
import json
import math

DEFAULT_ORIGIN = {"lat_deg": 40.4405, "lon_deg": -3.68982, "alt_m": 100.0}
EARTH_RADIUS_M = 6378137.0


class World:
    def __init__(self, data=None):
        data = data or {}
        self.name = data.get("name", "empty")
        bounds = data.get("bounds_m", {"x": [-50.0, 50.0], "y": [-50.0, 50.0]})
        self.bounds_x_m = tuple(bounds["x"])
        self.bounds_y_m = tuple(bounds["y"])
        pole_r = float(data.get("pole_radius_m", 0.25))
        # cylinders: (x, y, radius, height or inf)
        self.cylinders = [(float(p[0]), float(p[1]), pole_r, math.inf) for p in data.get("poles_xy_m", [])]
        for c in data.get("cylinders", []):
            self.cylinders.append((float(c["xy_m"][0]), float(c["xy_m"][1]), float(c["radius_m"]),
                                   float(c.get("height_m", math.inf))))
        # boxes: (cx, cy, half_w, half_d, yaw, height)
        self.boxes = []
        for b in data.get("boxes", []):
            self.boxes.append((float(b["center_xy_m"][0]), float(b["center_xy_m"][1]),
                               float(b["size_xy_m"][0]) / 2, float(b["size_xy_m"][1]) / 2,
                               float(b.get("yaw_rad", 0.0)), float(b.get("height_m", math.inf))))
        self.origin = dict(DEFAULT_ORIGIN)
        self.origin.update(data.get("geodetic_origin", {}))
        self.starts = data.get("starts_xy_yaw", {})

    @classmethod
    def load(cls, path):
        if not path:
            return cls()
        with open(path) as f:
            return cls(json.load(f))

    def start_poses(self, n):
        """n start poses (x, y, yaw_rad) ENU: from starts_xy_yaw[str(n)] or a 3 m spaced row."""
        poses = self.starts.get(str(n))
        if poses and len(poses) >= n:
            return [tuple(map(float, p[:3])) for p in poses[:n]]
        return [(3.0 * i, 0.0, 0.0) for i in range(n)]

    # ---- geodesy (local tangent plane, good to centimetres over a few km) ----
    def enu_to_geo(self, x_m, y_m, z_m):
        lat0 = math.radians(self.origin["lat_deg"])
        lat = self.origin["lat_deg"] + math.degrees(y_m / EARTH_RADIUS_M)
        lon = self.origin["lon_deg"] + math.degrees(x_m / (EARTH_RADIUS_M * math.cos(lat0)))
        return lat, lon, self.origin["alt_m"] + z_m

    def geo_to_enu(self, lat_deg, lon_deg, alt_m):
        lat0 = math.radians(self.origin["lat_deg"])
        y = math.radians(lat_deg - self.origin["lat_deg"]) * EARTH_RADIUS_M
        x = math.radians(lon_deg - self.origin["lon_deg"]) * EARTH_RADIUS_M * math.cos(lat0)
        return x, y, alt_m - self.origin["alt_m"]

    # ---- ray casting ----
    def ray_distance(self, x, y, z, heading_rad, max_range_m):
        """Distance along a horizontal ray from (x, y) at height z with ENU heading
        (0 = east, counter-clockwise). Returns max_range_m if nothing is hit."""
        dx, dy = math.cos(heading_rad), math.sin(heading_rad)
        best = max_range_m
        for cx, cy, r, h in self.cylinders:
            if z > h:
                continue
            fx, fy = x - cx, y - cy
            if abs(fx) > best + r and abs(fy) > best + r:
                continue
            b = fx * dx + fy * dy
            c = fx * fx + fy * fy - r * r
            disc = b * b - c
            if disc < 0:
                continue
            sq = math.sqrt(disc)
            t = -b - sq
            if t < 0:
                t = -b + sq if c < 0 else -1  # inside the cylinder: distance 0
                if c < 0:
                    t = 0.0
            if 0 <= t < best:
                best = t
        for cx, cy, hw, hd, yaw, h in self.boxes:
            if z > h:
                continue
            t = _ray_box(x - cx, y - cy, dx, dy, hw, hd, yaw)
            if t is not None and t < best:
                best = t
        return best

    def down_distance(self, z_up_m, x=None, y=None):
        """Distance to the floor (or to a box/cylinder top below) straight down."""
        floor = 0.0
        if x is not None:
            for cx, cy, r, h in self.cylinders:
                if h != math.inf and h <= z_up_m and (x - cx) ** 2 + (y - cy) ** 2 <= r * r:
                    floor = max(floor, h)
            for cx, cy, hw, hd, yaw, h in self.boxes:
                if h != math.inf and h <= z_up_m:
                    lx, ly = _to_box(x - cx, y - cy, yaw)
                    if abs(lx) <= hw and abs(ly) <= hd:
                        floor = max(floor, h)
        return max(0.0, z_up_m - floor)

    def collides(self, x, y, z, radius_m=0.15):
        for cx, cy, r, h in self.cylinders:
            if z <= h and (x - cx) ** 2 + (y - cy) ** 2 < (r + radius_m) ** 2:
                return True
        for cx, cy, hw, hd, yaw, h in self.boxes:
            if z <= h:
                lx, ly = _to_box(x - cx, y - cy, yaw)
                if abs(lx) < hw + radius_m and abs(ly) < hd + radius_m:
                    return True
        return False


def _to_box(px, py, yaw):
    c, s = math.cos(-yaw), math.sin(-yaw)
    return c * px - s * py, s * px + c * py


def _ray_box(px, py, dx, dy, hw, hd, yaw):
    """Slab test in the box frame; returns entry distance (0 if inside) or None."""
    ox, oy = _to_box(px, py, yaw)
    vx, vy = _to_box(dx, dy, yaw)
    tmin, tmax = -math.inf, math.inf
    for o, v, half in ((ox, vx, hw), (oy, vy, hd)):
        if abs(v) < 1e-12:
            if abs(o) > half:
                return None
            continue
        t1, t2 = (-half - o) / v, (half - o) / v
        if t1 > t2:
            t1, t2 = t2, t1
        tmin, tmax = max(tmin, t1), min(tmax, t2)
    if tmax < 0 or tmin > tmax:
        return None
    return max(tmin, 0.0)
