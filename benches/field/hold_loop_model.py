"""A model of Kestrel's position hold over a drifting autopilot, to compare loop designs fast.

What it models (the wander test of tests/convergence_e2e.rs, without processes): Kestrel's
position PI (kp 1.2, ki 0.4, integral within 0.5 m and limited to 1.5, conditional integration)
at 100 Hz commanding velocities capped at `speed`; commands reach the autopilot 50 ms later,
its telemetry (50 Hz) reaches Kestrel 50-100 ms later, in order; the autopilot follows the
command with a first-order lag `tau` (acceleration within 4.5 m/s^2) plus its own wander (the
fake's `--velocity-wander-mps`: an Ornstein-Uhlenbeck velocity, `sigma` per horizontal axis, half
vertically, 3 s correlation). Optionally the disturbance observer of src/control/disturbance.rs
(`observer_s`: its low-pass; `lag_model`: the profile's velocity lag; horizontal only unless
`vertical`). One run is a go_to from 5 m away: it succeeds within 0.1 m of the goal, or fails
`no_progress` as behavior/progress.rs decides it (20 s without a step closer).

    python3 benches/field/hold_loop_model.py '{"observer_s": 0.7}' 200
prints the runs that failed and the time to the goal (median, p90).
"""
import json
import math
import random
import sys


def add(a, b):
    return [x + y for x, y in zip(a, b)]


def sub(a, b):
    return [x - y for x, y in zip(a, b)]


def scale(a, k):
    return [x * k for x in a]


def norm(a):
    return math.sqrt(sum(x * x for x in a))


def fly(seed, kp=1.2, ki=0.4, zone=0.5, integral_limit=1.5, observer_s=None, vertical=False,
        lag_model=0.6, tau=0.6, sigma=0.25, wander_tau=3.0, speed=1.0, threshold=0.1,
        timeout=20.0, max_time=60.0):
    rng = random.Random(seed)
    dt, control_dt = 0.001, 0.01
    pos, vel, wander = [-5.0, 0.0, 0.0], [0.0] * 3, [0.0] * 3
    decay = math.exp(-dt / wander_tau)
    spread = sigma * math.sqrt(1 - decay * decay)
    commands, telemetry = [], []
    command, integral = [0.0] * 3, [0.0] * 3
    predicted, estimate, last_sent = None, [0.0] * 3, None
    seen = (pos[:], vel[:])
    best, best_at = math.inf, 0.0
    t, next_control, next_telemetry, last_arrival = 0.0, 0.0, 0.0, 0.0
    while t < max_time:
        if t >= next_telemetry:
            last_arrival = max(t + 0.05 + rng.uniform(0, 0.05), last_arrival)
            telemetry.append((last_arrival, pos[:], vel[:]))
            next_telemetry += 0.02
        while telemetry and telemetry[0][0] <= t:
            seen = telemetry.pop(0)[1:]
        if t >= next_control:
            next_control += control_dt
            p, v = seen
            error = scale(p, -1.0)
            distance = norm(error)
            if distance < threshold:
                return "reached", t
            step = min(max((best - threshold) / 2, 0.01), 0.1)
            if distance < best - step:
                best, best_at = distance, t
            if t - best_at > timeout:
                return "no_progress", t
            before = integral[:]
            for i in range(3):
                if abs(error[i]) <= zone:
                    integral[i] += error[i] * control_dt
                integral[i] = max(-integral_limit, min(integral_limit, integral[i]))
            u = add(scale(error, kp), scale(integral, ki))
            if observer_s and last_sent is not None:
                if predicted is None:
                    predicted = v[:]
                else:
                    predicted = add(predicted, scale(sub(last_sent, predicted), control_dt / lag_model))
                residual = sub(v, predicted)
                if not vertical:
                    residual[2] = 0.0
                estimate = add(estimate, scale(sub(residual, estimate), control_dt / observer_s))
                u = sub(u, estimate)
            n = norm(u)
            if n > speed:
                u = scale(u, speed / n)
                for i in range(3):
                    if abs(integral[i]) > abs(before[i]):
                        integral[i] = before[i]
            last_sent = u
            commands.append((t + 0.05, u))
        while commands and commands[0][0] <= t:
            command = commands.pop(0)[1]
        wander = [decay * w + spread * rng.gauss(0, 1) * (0.5 if i == 2 else 1.0)
                  for i, w in enumerate(wander)]
        acceleration = scale(sub(add(command, wander), vel), 1.0 / tau)
        a = norm(acceleration)
        if a > 4.5:
            acceleration = scale(acceleration, 4.5 / a)
        vel = add(vel, scale(acceleration, dt))
        pos = add(pos, scale(vel, dt))
        t += dt
    return "timeout", t


if __name__ == "__main__":
    settings = json.loads(sys.argv[1]) if len(sys.argv) > 1 else {}
    runs = int(sys.argv[2]) if len(sys.argv) > 2 else 40
    results = [fly(seed, **settings) for seed in range(runs)]
    failed = sum(1 for outcome, _ in results if outcome != "reached")
    times = sorted(t for outcome, t in results if outcome == "reached")
    median = times[len(times) // 2] if times else float("nan")
    p90 = times[int(len(times) * 0.9)] if times else float("nan")
    print(f"{settings}: {failed} of {runs} failed, to the goal median {median:.1f} s, p90 {p90:.1f} s")
