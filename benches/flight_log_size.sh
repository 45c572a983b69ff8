#!/usr/bin/env bash
# Benchmark (BENCHMARKS.md, "MCAP flight logs"): bytes per minute of flight of the two log
# formats, on real simulator flights. Each flight is flown once with `--log-format jsonl`
# and once with `--log-format mcap` (seeded: the same flight), and the JSON-lines log is also
# converted with `kestrel log convert` (the same records exactly). Prints one line per flight:
# minutes flown (the last record's t), bytes and bytes per minute of each, and the CPU time
# (user + sys) of each run.
#
#     cargo build --release && bash benches/flight_log_size.sh target/release/kestrel
set -euo pipefail
kestrel="$(realpath "${1:-target/release/kestrel}")"
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT
cd "$work"

fly() { # name, format, args...
  local name="$1" format="$2"
  shift 2
  /usr/bin/time -f "%U %S" -o "$name.$format.time" \
    "$kestrel" "$@" --speedup max --exit-when-done --listen 127.0.0.1:0 --seed 1 \
    --log-format "$format" --log "$name.$format" >/dev/null
}

row() { # name, args...
  local name="$1"
  shift
  fly "$name" jsonl "$@"
  fly "$name" mcap "$@"
  "$kestrel" log convert "$name.jsonl" --out "$name.converted.mcap" >/dev/null
  python3 - "$name" <<'PY'
import json, os, sys
name = sys.argv[1]
last_t = 0.0
with open(f"{name}.jsonl") as f:
    for line in f:
        last_t = max(last_t, json.loads(line).get("t") or 0.0)
minutes = last_t / 60.0
def cpu(fmt):
    u, s = open(f"{name}.{fmt}.time").read().split()[-2:]
    return float(u) + float(s)
sizes = {k: os.path.getsize(f"{name}.{k}") for k in ("jsonl", "mcap", "converted.mcap")}
print(f"{name}: {minutes:.2f} min flown; " + "; ".join(
    f"{k} {v} B = {v / minutes / 1e3:.0f} kB/min" for k, v in sizes.items())
    + f"; CPU jsonl {cpu('jsonl'):.2f} s, mcap {cpu('mcap'):.2f} s")
PY
}

row demo sim
row solar_park_3 sim --scenario "$repo/missions/scenarios/solar_park.json" --drones 3
