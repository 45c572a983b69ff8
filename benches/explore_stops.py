#!/usr/bin/env python3
"""Where explorers stop: reads a `kestrel explore` flight log (pose records, 20 Hz) and, when
given, the run's output with the explorer's debug trace, and tells how long each flying drone
spent below 0.15 m/s, in how many stops, and what the explorer was doing around each stop.

    RUST_LOG=kestrel::behavior::explore=debug kestrel explore --world W --drones N --seed S \
        --log run.jsonl --report run.json > run.out
    python3 benches/explore_stops.py run.jsonl run.out

A stop is classified by the explorer events from 1.5 s before it to its end: `giveway` (the
drone watcher), `done` (no frontier for it: sensing), `arrive` (the path to the goal was flown to
its end), or `fly` (a new goal was taken: before the stop began, or during it; the distance to
that goal then). The turn angle compares the velocity 1 s before and 1 s after the stop.
"""
import collections
import json
import math
import re
import sys

SLOW_MPS = 0.15


def main(log, trace=None):
    poses = collections.defaultdict(list)
    for line in open(log):
        r = json.loads(line)
        if r.get("type") == "pose":
            poses[r["drone"]].append((r["t"], r["x"], r["y"], r["z"], r.get("vx", 0.0), r.get("vy", 0.0)))
    events = collections.defaultdict(list)
    if trace:
        pat = re.compile(r"EXTRACE t=([0-9.]+) d=(\S+) ev=(\S+)(.*)")
        for line in open(trace):
            m = pat.search(line)
            if m:
                events[m.group(2)].append((float(m.group(1)), m.group(3), m.group(4).strip()))
    causes, causes_t = collections.Counter(), collections.Counter()
    angles, angles_t = collections.Counter(), collections.Counter()
    all_air = all_slow = 0.0
    all_stops = 0
    for d, ps in sorted(poses.items()):
        air = [p for p in ps if p[3] > 0.8]
        if not air:
            continue
        stops, cur = [], None
        for i, p in enumerate(air):
            if math.hypot(p[4], p[5]) < SLOW_MPS:
                cur = [i, i] if cur is None else [cur[0], i]
            elif cur is not None:
                stops.append(cur)
                cur = None
        if cur is not None:
            stops.append(cur)
        dt = air[1][0] - air[0][0] if len(air) > 1 else 0.05
        air_t = air[-1][0] - air[0][0]
        slow_t = 0.0
        for a, b in stops:
            ta, tb = air[a][0], air[b][0]
            dur = tb - ta + dt
            slow_t += dur
            before = air[max(0, a - int(1.0 / dt))]
            after = air[min(len(air) - 1, b + int(1.0 / dt))]
            n0, n1 = math.hypot(before[4], before[5]), math.hypot(after[4], after[5])
            if n0 > 0.2 and n1 > 0.2:
                cos = (before[4] * after[4] + before[5] * after[5]) / (n0 * n1)
                k = int(math.degrees(math.acos(max(-1.0, min(1.0, cos)))) // 45) * 45
                bucket = f"{k}-{k + 45} deg"
            else:
                bucket = "slow 1 s before or after"
            angles[bucket] += 1
            angles_t[bucket] += dur
            near = [e for e in events[d] if ta - 1.5 <= e[0] <= tb + 0.05]
            kinds = [e[1] for e in near]
            flies = [e for e in near if e[1] == "fly"]
            if not trace:
                cause = "(no trace)"
            elif "giveway" in kinds:
                cause = "giving way"
            elif "done" in kinds:
                cause = "done / sensing"
            elif "arrive" in kinds:
                cause = "arrived at the goal"
            elif flies:
                f = flies[-1]
                m = re.search(r"dist=([0-9.]+)", f[2])
                dist = float(m.group(1)) if m else float("nan")
                when = "before the stop" if f[0] < ta else "during the stop"
                far = "< 1.5 m" if dist < 1.5 else "< 4 m" if dist < 4 else ">= 4 m"
                cause = f"new goal {when}, {far} away"
            else:
                cause = "other"
            causes[cause] += 1
            causes_t[cause] += dur
        print(f"{d}: airborne {air_t:.1f} s, below {SLOW_MPS} m/s {slow_t:.1f} s "
              f"({100 * slow_t / max(air_t, 1e-9):.1f} %) in {len(stops)} stops")
        all_air += air_t
        all_slow += slow_t
        all_stops += len(stops)
    print(f"all: airborne {all_air:.1f} s, below {SLOW_MPS} m/s {all_slow:.1f} s "
          f"({100 * all_slow / max(all_air, 1e-9):.1f} %) in {all_stops} stops "
          f"(mean {all_slow / max(all_stops, 1):.2f} s)")
    print("by cause:")
    for k, n in causes.most_common():
        print(f"  {k}: {n} stops, {causes_t[k]:.1f} s")
    print("by turn across the stop:")
    for k, n in angles.most_common():
        print(f"  {k}: {n} stops, {angles_t[k]:.1f} s")


if __name__ == "__main__":
    main(*sys.argv[1:3])
