"""Multirotor point-mass model following position/velocity targets.

State is kept in the world ENU frame (x east, y north, z up). Targets given to the
controller are ENU too (personalities convert from local NED). The model is a cascaded
P position loop -> limited velocity command -> first-order velocity response with an
acceleration limit, plus a rate-limited yaw. Good enough to reproduce the timings seen
in the captures (takeoff, go-to, braking), not a rigid-body simulation.
"""
import math
from dataclasses import dataclass, field

GRAVITY_MPS2 = 9.80665


@dataclass
class Limits:
    max_speed_xy_mps: float = 12.0
    max_speed_up_mps: float = 3.0
    max_speed_down_mps: float = 1.5
    max_accel_mps2: float = 4.5
    max_accel_z_mps2: float = 4.5          # vertical cap (takeoff ramps / jerk limits)
    velocity_tau_s: float = 0.3
    pos_gain_xy: float = 1.0
    pos_gain_z: float = 1.0
    max_yaw_rate_rps: float = math.radians(90.0)


@dataclass
class Target:
    """What the controller tracks. kind: 'idle' | 'position' | 'velocity'."""
    kind: str = "idle"
    pos_enu: tuple = (0.0, 0.0, 0.0)
    vel_enu: tuple = (0.0, 0.0, 0.0)       # command, or feed-forward with a position
    yaw_rad: float = None                  # ENU yaw (0 = east, CCW); None keeps heading
    yaw_rate_rps: float = None
    speed_xy_mps: float = None             # optional tighter limits for this target
    speed_up_mps: float = None
    speed_down_mps: float = None


@dataclass
class Body:
    pos: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    vel: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    acc: list = field(default_factory=lambda: [0.0, 0.0, 0.0])
    yaw_rad: float = 0.0
    yaw_rate_rps: float = 0.0
    roll_rad: float = 0.0
    pitch_rad: float = 0.0
    on_ground: bool = True


def _clip(v, lo, hi):
    return lo if v < lo else hi if v > hi else v


def wrap_pi(a):
    return (a + math.pi) % (2 * math.pi) - math.pi


class Wander:
    """The autopilot's own velocity-tracking error in the air: a seeded Ornstein-Uhlenbeck
    process per axis (horizontal and vertical), standard deviation sigma_mps, correlation time
    tau_s. Real PX4 SIH holds its own position only to p50 0.2-0.3 m, p95 0.5 m, at up to
    0.65 m/s (BENCHMARKS.md, "Driving PX4"); sigma 0 (the default) turns it off."""

    def __init__(self, sigma_mps=0.0, tau_s=3.0, seed=1, in_estimate=False):
        import random
        self.sigma, self.tau = sigma_mps, tau_s
        # In the estimate (as real PX4 SIH's, by its ground truth): the velocity loop holds the
        # *estimate* at the command, so the vehicle flies command + wander while the reported
        # velocity shows the command; the position stays true (telemetry.estimated_vel).
        self.in_estimate = in_estimate
        self.rng = random.Random(seed)
        self.v = [0.0, 0.0, 0.0]

    def step(self, dt):
        if self.sigma <= 0:
            return self.v
        a = math.exp(-dt / self.tau)
        b = self.sigma * math.sqrt(1.0 - a * a)
        self.v = [a * v + b * self.rng.gauss(0.0, 1.0) * (0.5 if i == 2 else 1.0)
                  for i, v in enumerate(self.v)]
        return self.v


class Multirotor:
    def __init__(self, x, y, yaw_rad, limits=None, ground_z_m=0.0, wander=None):
        self.body = Body(pos=[x, y, ground_z_m], yaw_rad=yaw_rad)
        self.limits = limits or Limits()
        self.ground_z_m = ground_z_m
        self.target = Target(kind="idle")
        self.wander = wander or Wander()
        self.liftoff_delay_s = 0.0   # motors spooling up: stay on the ground this long more

    def step(self, dt, armed):
        b, lim, t = self.body, self.limits, self.target
        if not armed or t.kind == "idle":
            # motors off (or idling on the ground): fall to and rest on the ground
            if b.on_ground:
                b.vel, b.acc = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            else:
                b.acc = [-0.5 * b.vel[0], -0.5 * b.vel[1], -GRAVITY_MPS2]
                b.vel = [b.vel[i] + b.acc[i] * dt for i in range(3)]
            self._integrate(dt)
            b.yaw_rate_rps = 0.0
            self._attitude(armed)
            return
        sxy = min(lim.max_speed_xy_mps, t.speed_xy_mps or math.inf)
        sup = min(lim.max_speed_up_mps, t.speed_up_mps or math.inf)
        sdn = min(lim.max_speed_down_mps, t.speed_down_mps or math.inf)
        if t.kind == "position":
            vc = [lim.pos_gain_xy * (t.pos_enu[0] - b.pos[0]) + t.vel_enu[0],
                  lim.pos_gain_xy * (t.pos_enu[1] - b.pos[1]) + t.vel_enu[1],
                  lim.pos_gain_z * (t.pos_enu[2] - b.pos[2]) + t.vel_enu[2]]
        else:
            vc = list(t.vel_enu)
        h = math.hypot(vc[0], vc[1])
        if h > sxy:
            vc[0], vc[1] = vc[0] * sxy / h, vc[1] * sxy / h
        vc[2] = _clip(vc[2], -sdn, sup)
        if not b.on_ground:
            w = self.wander.step(dt)
            vc = [vc[i] + w[i] for i in range(3)]
        # first-order response with acceleration limit
        a = [(vc[i] - b.vel[i]) / lim.velocity_tau_s for i in range(3)]
        an = math.sqrt(a[0] ** 2 + a[1] ** 2 + a[2] ** 2)
        if an > lim.max_accel_mps2:
            a = [ai * lim.max_accel_mps2 / an for ai in a]
        a[2] = _clip(a[2], -lim.max_accel_z_mps2, lim.max_accel_z_mps2)
        if b.on_ground and self.liftoff_delay_s > 0:
            self.liftoff_delay_s -= dt
            a = [0.0, 0.0, 0.0]
        b.acc = a
        b.vel = [b.vel[i] + a[i] * dt for i in range(3)]
        self._integrate(dt)
        # yaw
        if t.yaw_rate_rps is not None:
            rate = _clip(t.yaw_rate_rps, -lim.max_yaw_rate_rps, lim.max_yaw_rate_rps)
        elif t.yaw_rad is not None:
            rate = _clip(2.0 * wrap_pi(t.yaw_rad - b.yaw_rad), -lim.max_yaw_rate_rps, lim.max_yaw_rate_rps)
        else:
            rate = 0.0
        if b.on_ground:
            rate = 0.0
        b.yaw_rate_rps = rate
        b.yaw_rad = wrap_pi(b.yaw_rad + rate * dt)
        self._attitude(armed)

    def _integrate(self, dt):
        b = self.body
        b.pos = [b.pos[i] + b.vel[i] * dt for i in range(3)]
        if b.pos[2] <= self.ground_z_m:
            b.pos[2] = self.ground_z_m
            if b.vel[2] < 0:
                b.vel[2] = 0.0
            b.vel[0] *= 0.5 if b.on_ground else 1.0
            b.vel[1] *= 0.5 if b.on_ground else 1.0
            b.on_ground = True
        elif b.pos[2] > self.ground_z_m + 0.05:
            b.on_ground = False
        if b.on_ground and b.vel[2] <= 0.0:
            b.vel = [0.0, 0.0, 0.0]

    def _attitude(self, armed):
        """Tilt that produces the horizontal acceleration (small-angle, ENU->body)."""
        b = self.body
        if b.on_ground:
            b.roll_rad = b.pitch_rad = 0.0
            return
        c, s = math.cos(b.yaw_rad), math.sin(b.yaw_rad)
        a_fwd = c * b.acc[0] + s * b.acc[1]
        a_left = -s * b.acc[0] + c * b.acc[1]
        b.pitch_rad = -math.atan2(a_fwd, GRAVITY_MPS2)  # nose down to accelerate forward (FRD pitch)
        b.roll_rad = -math.atan2(a_left, GRAVITY_MPS2)  # roll right (positive) to go right
