#!/usr/bin/env bash
# Field check on the real PX4 SITL (SIH quadcopter, built by ../shared/anchors/build-px4.sh): two
# Kestrels, each with its own PX4, joined as one fleet over the bus on loopback, configured as the
# README's "Two drones, step by step" says (each node's own key from `kestrel fleet-key`, the same
# roster on both, drone B's frame 4 m east of drone A's). Each flies takeoff 3 m, a path-facing
# go_to 5 m north (side by side, 4 m apart), a go_to back and land, from `--mission`, RUNS times,
# each on fresh PX4s. Prints per run and drone whether the mission succeeded, each item's end
# time, how close the vehicle came to each goal (Kestrel's log), the least separation of the
# two in the shared frame, and any pilot takeover.
#
#   bash benches/field/px4_sih_fleet.sh [RUNS]
#
# Not part of CI (PX4 takes 8-15 min to build here). Needs target/debug/kestrel (KESTREL=path
# to use another).
set -uo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-2}
anchors=../shared/anchors
bin=${KESTREL:-target/debug/kestrel}
out=${OUT:-target/px4-sih-fleet}
mkdir -p "$out"
for n in a b; do
    [ -f "$out/$n.key" ] || "$bin" fleet-key "$out/$n.key" > /dev/null
done
key_a=$("$bin" fleet-key --public "$out/a.key" | sed -n "s/^public key: //p")
key_b=$("$bin" fleet-key --public "$out/b.key" | sed -n "s/^public key: //p")
# node name, drone id, PX4 instance, origin east (m), bus port, connect line
node_config() {
    cat <<TOML
[map]
size_m = [40.0, 40.0]

[mavlink]
platform = "px4"

[[vehicle]]
id = "drone_$2"
connection = "udpin:0.0.0.0:$((14540 + $3))"
target_system = $(($3 + 1))
origin_enu_m = [$4, 0.0, 0.0]

[fleet]
enabled = true
name = "field"
node = "kestrel-$1"
listen = ["tcp/127.0.0.1:$5"]
$6
key_file = "$out/$1.key"

[fleet.roster.kestrel-a]
keys = ["$key_a"]
drones = ["drone_a"]

[fleet.roster.kestrel-b]
keys = ["$key_b"]
drones = ["drone_b"]
TOML
}
node_config a a 0 0.0 7461 "" > "$out/a.toml"
node_config b b 1 4.0 7462 'connect = ["tcp/127.0.0.1:7461"]' > "$out/b.toml"
# Missions in each drone's shared-frame coordinates.
mission() {
    cat <<JSON
{"target": "drone_$1", "plan": [
 {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": $2, "y": 5.0, "z": 3.0, "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": $2, "y": 0.0, "z": 3.0, "speed": 1.0}},
 {"behavior": "land", "args": {"speed": 0.5}}]}
JSON
}
mission a 0.0 > "$out/mission-a.json"
mission b 4.0 > "$out/mission-b.json"
for i in $(seq 1 "$runs"); do
    for k in 0 1; do
        bash "$anchors/run-px4-sih.sh" "$k" stop > /dev/null
        bash "$anchors/run-px4-sih.sh" "$k" start > /dev/null || { echo "run $i: PX4 $k did not start"; continue 2; }
    done
    pids=()
    for n in a b; do
        rm -rf "$out/state-$n-$i"
        timeout 200 "$bin" run --config "$out/$n.toml" --mission "$out/mission-$n.json" --no-api \
            --exit-when-done --max-time-s 180 --log "$out/$n-$i.jsonl" --log-overwrite \
            --state-dir "$out/state-$n-$i" > "$out/$n-$i.out" 2>&1 &
        pids+=($!)
    done
    rcs=()
    for p in "${pids[@]}"; do wait "$p"; rcs+=($?); done
    for k in 0 1; do bash "$anchors/run-px4-sih.sh" "$k" stop > /dev/null; done
    python3 - "$out" "$i" "${rcs[@]}" <<'PY'
import json, math, re, sys
out, run, rcs = sys.argv[1], sys.argv[2], sys.argv[3:]
goals = {"a": [(0.0, 5.0), (0.0, 0.0)], "b": [(4.0, 5.0), (4.0, 0.0)]}
tracks = {}
for n, rc in zip("ab", rcs):
    text = open(f"{out}/{n}-{run}.out").read()
    ends = re.findall(r"\[ *([0-9.]+) s\] drone_\w: (\w+ #\d (?:succeeded|failed[^:\n]*))", text)
    poses = [r for r in map(json.loads, open(f"{out}/{n}-{run}.jsonl"))
             if r.get("type") == "pose" and r.get("drone") == f"drone_{n}" and r.get("flight") == "flying"]
    tracks[n] = {round(r["t"], 1): r for r in poses}
    closest = [min((math.hypot(r["x"] - gx, r["y"] - gy) for r in poses if r["z"] > 2.5), default=math.inf)
               for gx, gy in goals[n]]
    print(f"run {run} drone_{n}: rc={rc} takeovers={text.count('pilot took over')} closest to goals "
          + " / ".join(f"{c:.3f}" for c in closest) + " m; " + ", ".join(f"{t}s {e}" for t, e in ends))
common = sorted(set(tracks["a"]) & set(tracks["b"]))
sep = min((math.dist([tracks["a"][t][k] for k in "xyz"], [tracks["b"][t][k] for k in "xyz"]) for t in common),
          default=math.inf)
print(f"run {run}: least separation {sep:.2f} m (both flying, log samples matched to 0.1 s)")
PY
done
