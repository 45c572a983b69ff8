"""Fault injection state and setpoint inter-arrival statistics for one vehicle."""
import random
from collections import deque


class Faults:
    def __init__(self, seed=None):
        self.rng = random.Random(seed)
        self.clear()

    def clear(self):
        self.link_down_until = 0.0          # sim time
        self.loss_probability = 0.0         # both directions, per MAVLink message
        self.latency_s = 0.0                # added one-way delay, both directions (wall s)
        self.jitter_s = 0.0                 # telemetry only: a further 0..jitter_s, order kept
        self.reject = {}                    # command id -> [result, remaining count]
        self.deny_arm_reason = None         # str or None
        self.deny_arm_px4_event = "commander_arm_denied_resolve_failures"

    def link_down(self, now):
        return now < self.link_down_until

    def lose(self):
        return self.loss_probability > 0 and self.rng.random() < self.loss_probability

    def take_reject(self, command):
        rule = self.reject.get(command)
        if not rule:
            return None
        result, remaining = rule
        if remaining is not None:
            if remaining <= 1:
                del self.reject[command]
            else:
                rule[1] = remaining - 1
        return result

    def describe(self, now):
        return {
            "link_down_remaining_s": max(0.0, self.link_down_until - now),
            "loss_probability": self.loss_probability,
            "latency_s": self.latency_s,
            "jitter_s": self.jitter_s,
            "reject": {str(k): {"result": v[0], "remaining": v[1]} for k, v in self.reject.items()},
            "deny_arm_reason": self.deny_arm_reason,
        }


def _percentile(sorted_vals, q):
    if not sorted_vals:
        return None
    k = (len(sorted_vals) - 1) * q
    lo = int(k)
    hi = min(lo + 1, len(sorted_vals) - 1)
    return sorted_vals[lo] + (sorted_vals[hi] - sorted_vals[lo]) * (k - lo)


class SetpointStats:
    """Inter-arrival gaps (wall-clock ms, stamped when the datagram/segment is read) of
    SET_POSITION_TARGET_LOCAL_NED received while the vehicle flies on the setpoint stream
    (PX4 OFFBOARD, ArduPilot GUIDED outside its own NAV_TAKEOFF climb). A gap is counted only
    when the stream was expected from one end to the other: the vehicle's tick breaks the
    stream whenever it is not, so the phases follow the autopilot's own state, not wall-clock
    windows."""

    def __init__(self, keep=100000):
        self.gaps_ms = deque(maxlen=keep)
        self.count = 0
        self.last_wall = None

    def reset(self):
        self.gaps_ms.clear()
        self.count = 0
        self.last_wall = None

    def break_stream(self):
        self.last_wall = None

    def record(self, wall_s, in_control):
        if not in_control:
            self.last_wall = None
            return
        self.count += 1
        if self.last_wall is not None:
            self.gaps_ms.append((wall_s - self.last_wall) * 1000.0)
        self.last_wall = wall_s

    def summary(self):
        vals = sorted(self.gaps_ms)
        r = lambda v: None if v is None else round(v, 3)
        return {
            "count": self.count,
            "gaps": len(vals),
            "p50_ms": r(_percentile(vals, 0.5)),
            "p99_ms": r(_percentile(vals, 0.99)),
            "max_ms": r(vals[-1] if vals else None),
            "mean_ms": r(sum(vals) / len(vals) if vals else None),
            "over_100ms": sum(1 for v in vals if v > 100.0),
            "over_500ms": sum(1 for v in vals if v > 500.0),  # PX4 needs >= 2 Hz
        }


class DelayLine:
    """FIFO of (due_wall_s, item) for added latency. Items leave in the order they came: one
    due earlier than the item before it waits for that one (a link that stalls, then bursts)."""

    def __init__(self):
        self.q = deque()

    def push(self, due, item):
        if self.q:
            due = max(due, self.q[-1][0])
        self.q.append((due, item))

    def pop_due(self, now_wall):
        out = []
        while self.q and self.q[0][0] <= now_wall:
            out.append(self.q.popleft()[1])
        return out

    def clear(self):
        self.q.clear()
