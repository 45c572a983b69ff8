#!/usr/bin/env bash
# Benchmark (BENCHMARKS.md, "MCAP flight logs"): bytes per minute of flight of the two log
# formats, on real simulator flights. Each flight is flown once with `--log-format jsonl`
# and once with `--log-format mcap` (seeded: the same flight), and the JSON-lines log is also
# converted with `kestrel log convert` (the same records exactly). Prints one line per flight:
# minutes flown (the last record's t), bytes and bytes per minute of each, the CPU time
# (user + sys) of each run, and what the maps take: the `map` records' bytes in the JSON-lines
# log and the `foxglove.Grid` messages' in the MCAP log (read with sitl/.venv's `mcap`).
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

explore() { # name, drones: an exploration of a generated 30 m world, 120 s at most
  local name="$1" drones="$2" format
  [ -e world.json ] || "$kestrel" world generate --size-m 30 --poles 30 --seed 1 --out world.json >/dev/null
  for format in jsonl mcap; do
    /usr/bin/time -f "%U %S" -o "$name.$format.time" \
      "$kestrel" explore --world world.json --drones "$drones" --seed 1 --max-sim-time-s 120 \
      --log "$name.$format" --log-format "$format" >/dev/null 2>&1 || true
  done
  sizes "$name"
}

row() { # name, args...
  local name="$1"
  shift
  fly "$name" jsonl "$@"
  fly "$name" mcap "$@"
  sizes "$name"
}

sizes() { # name
  local name="$1"
  "$kestrel" log convert "$name.jsonl" --out "$name.converted.mcap" >/dev/null
  "$repo/sitl/.venv/bin/python" - "$name" <<'PY'
import json, os, sys
from mcap.reader import make_reader
name = sys.argv[1]
last_t = 0.0
map_bytes = 0
with open(f"{name}.jsonl") as f:
    for line in f:
        record = json.loads(line)
        last_t = max(last_t, record.get("t") or 0.0)
        if record.get("type") == "map":
            map_bytes += len(line)
grid_bytes = 0
with open(f"{name}.mcap", "rb") as f:
    for schema, _, message in make_reader(f).iter_messages():
        if schema.name == "foxglove.Grid":
            grid_bytes += len(message.data)
minutes = last_t / 60.0
def cpu(fmt):
    u, s = open(f"{name}.{fmt}.time").read().split()[-2:]
    return float(u) + float(s)
sizes = {k: os.path.getsize(f"{name}.{k}") for k in ("jsonl", "mcap", "converted.mcap")}
print(f"{name}: {minutes:.2f} min flown; " + "; ".join(
    f"{k} {v} B = {v / minutes / 1e3:.0f} kB/min" for k, v in sizes.items())
    + f"; CPU jsonl {cpu('jsonl'):.2f} s, mcap {cpu('mcap'):.2f} s"
    + f"; map records {map_bytes / minutes / 1e3:.0f} kB/min, grids {grid_bytes / minutes / 1e3:.0f} kB/min")
PY
}

row demo sim
row solar_park_3 sim --scenario "$repo/missions/scenarios/solar_park.json" --drones 3
explore explore_1 1
explore explore_3 3
