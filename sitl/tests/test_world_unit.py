"""World model and dynamics unit tests (no processes, no sockets)."""
import math

from fakeap.dynamics import Limits, Multirotor, Target
from fakeap.world import World


def test_ray_casting_cylinders_boxes_and_heights():
    w = World({"poles_xy_m": [[5, 0]], "pole_radius_m": 0.25,
               "cylinders": [{"xy_m": [-4, 0], "radius_m": 1.0, "height_m": 2.0}],
               "boxes": [{"center_xy_m": [0, 5], "size_xy_m": [2, 2], "yaw_rad": math.pi / 4, "height_m": 3}]})
    assert abs(w.ray_distance(0, 0, 1, 0.0, 10) - 4.75) < 1e-9                    # pole, east
    assert abs(w.ray_distance(0, 0, 1, math.pi, 10) - 3.0) < 1e-9                 # cylinder, west
    assert w.ray_distance(0, 0, 2.5, math.pi, 10) == 10                           # above the cylinder
    assert abs(w.ray_distance(0, 0, 1, math.pi / 2, 10) - (5 - math.sqrt(2))) < 1e-9  # rotated box corner
    assert w.ray_distance(0, 0, 1, -math.pi / 2, 10) == 10                        # nothing south
    assert w.collides(5.1, 0, 1) and not w.collides(2, 0, 1)
    assert abs(w.down_distance(4.0, 0, 5) - 1.0) < 1e-9 and w.down_distance(4.0, 10, 10) == 4.0


def test_geodesy_round_trip_and_default_origin():
    w = World({})
    assert (w.origin["lat_deg"], w.origin["lon_deg"], w.origin["alt_m"]) == (40.4405, -3.68982, 100.0)
    lat, lon, alt = w.enu_to_geo(120.0, -35.0, 7.0)
    assert lat < 40.4405 and lon > -3.68982 and alt == 107.0
    x, y, z = w.geo_to_enu(lat, lon, alt)
    assert abs(x - 120) < 1e-6 and abs(y + 35) < 1e-6 and abs(z - 7) < 1e-9


def test_start_poses_from_world_or_row():
    w = World({"starts_xy_yaw": {"2": [[1, 2, 0.5], [3, 4, 1.0]]}})
    assert w.start_poses(2) == [(1.0, 2.0, 0.5), (3.0, 4.0, 1.0)]
    assert w.start_poses(3) == [(0.0, 0.0, 0.0), (3.0, 0.0, 0.0), (6.0, 0.0, 0.0)]


def test_dynamics_limits_and_ground():
    m = Multirotor(0, 0, 0, Limits(max_speed_xy_mps=12, max_accel_mps2=4.5, velocity_tau_s=0.3))
    m.body.pos[2], m.body.on_ground = 10.0, False
    m.target = Target("velocity", vel_enu=(30.0, 0.0, 0.0))
    peak_acc = 0.0
    for _ in range(1000):
        m.step(0.01, True)
        peak_acc = max(peak_acc, math.hypot(*m.body.acc[:2]))
    assert abs(m.body.vel[0] - 12.0) < 0.01 and peak_acc <= 4.5 + 1e-9   # speed and accel limits
    assert m.body.pitch_rad < 0 or abs(m.body.vel[0] - 12.0) < 0.01
    m.target = Target("velocity", vel_enu=(0.0, 0.0, -5.0))
    for _ in range(1500):
        m.step(0.01, True)
    assert m.body.on_ground and m.body.pos[2] == 0.0                          # ground contact
    assert min(m.body.vel[2], 0) == 0.0
    m.target = Target("position", pos_enu=(0, 0, 5), yaw_rad=math.pi / 2)
    for _ in range(1000):
        m.step(0.01, True)
    assert abs(m.body.yaw_rad - math.pi / 2) < 0.01 and abs(m.body.pos[2] - 5) < 0.05
