"""Horizontal speed flown in exploration runs, against the thesis's 0.75 m/s limit (+3 %).

    python3 flown_speed.py FLIGHT.jsonl        -> one run's JSON: samples, max, p99, share over the limit
    python3 flown_speed.py --summary DIR       -> a Markdown table of every DIR/*.speed.json

Reads the flight log's pose records (each drone's velocity as its platform reported it, ENU m/s),
only while the drone flies.
"""
import glob
import json
import math
import os
import sys

LIMIT_MPS = 0.75
TOLERANCE = 1.03


def one(path):
    speeds = []
    with open(path) as f:
        for line in f:
            if '"pose"' not in line:
                continue
            r = json.loads(line)
            if r.get("type") != "pose" or r.get("flight") != "flying":
                continue
            speeds.append(math.hypot(r.get("vx", 0.0), r.get("vy", 0.0)))
    speeds.sort()
    n = len(speeds)
    over = sum(1 for v in speeds if v > LIMIT_MPS * TOLERANCE)
    return {
        "samples": n,
        "max_mps": round(speeds[-1], 4) if n else None,
        "p99_mps": round(speeds[int(0.99 * (n - 1))], 4) if n else None,
        "over_limit_pct": round(100.0 * over / n, 3) if n else None,
    }


def summary(folder):
    rows = []
    for p in sorted(glob.glob(os.path.join(folder, "*.speed.json"))):
        try:
            rows.append((os.path.basename(p)[: -len(".speed.json")], json.load(open(p))))
        except (OSError, ValueError):
            continue
    print(f"| run | samples | max flown (m/s) | p99 (m/s) | over {LIMIT_MPS * TOLERANCE:.4f} m/s |")
    print("|---|---|---|---|---|")
    for tag, s in rows:
        print(f"| {tag} | {s['samples']} | {s['max_mps']} | {s['p99_mps']} | {s['over_limit_pct']} % |")
    worst = max((s["max_mps"] or 0.0 for _, s in rows), default=0.0)
    bad = [t for t, s in rows if (s["max_mps"] or 0.0) > LIMIT_MPS * TOLERANCE]
    print(f"\n{len(rows)} runs; fastest flown {worst:.3f} m/s; runs over {LIMIT_MPS} m/s + 3 %: {len(bad)} {bad}")


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "--summary":
        summary(sys.argv[2])
    elif len(sys.argv) == 2:
        print(json.dumps(one(sys.argv[1])))
    else:
        sys.exit(__doc__)
