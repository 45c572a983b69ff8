#!/usr/bin/env bash
# Field check on the real PX4 SITL (SIH quadcopter, built by ../shared/anchors/build-px4.sh): the
# same mission as tests/convergence_e2e.rs (takeoff 3 m, path-facing go_to 5 m, path-facing
# follow_path, go_to, land; 1 m/s) flown RUNS times per way of driving, each on a fresh PX4.
# Prints per run whether the mission succeeded, each item's end time, the fastest horizontal
# speed PX4 reported (its LOCAL_POSITION_NED on the GCS link) against the 1 m/s limit, how far
# from where its landing began PX4 touched down, any (false) pilot takeover, and how far PX4's
# estimate was from SIH's ground truth (benches/field/sih_truth.py).
#
#   bash benches/field/px4_sih_missions.sh [RUNS] [velocity|position_target ...]
#
# Not part of CI (PX4 takes 8-15 min to build here). Needs sitl/.venv (pymavlink) and
# target/debug/kestrel (KESTREL=path to use another).
set -uo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-3}; shift || true
modes=${*:-"velocity position_target"}
anchors=../shared/anchors
bin=${KESTREL:-target/debug/kestrel}
out=${OUT:-target/px4-sih-missions}
mkdir -p "$out"
cat > "$out/mission.json" <<'JSON'
{"target": "drone_0", "plan": [
 {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 5.0, "y": 0.0, "z": 3.0, "speed": 1.0}},
 {"behavior": "follow_path", "method": "follow_path_with_path_facing", "args": {"path": [[5, 4, 3], [1, 4, 3]], "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 1.0, "y": 1.5, "z": 3.0, "speed": 1.0}},
 {"behavior": "land", "args": {"speed": 0.5}}]}
JSON
for mode in $modes; do
    sed "s/^setpoints = .*/setpoints = \"$mode\"/" platforms/px4.toml > "$out/px4-$mode.toml"
    for i in $(seq 1 "$runs"); do
        name="$mode-$i"
        bash "$anchors/run-px4-sih.sh" 0 stop > /dev/null
        bash "$anchors/run-px4-sih.sh" 0 start > /dev/null || { echo "$name: PX4 did not start"; continue; }
        sitl/.venv/bin/python benches/field/listen.py udpin:127.0.0.1:14550 170 "$out/$name.gcs.jsonl" LOCAL_POSITION_NED,HIL_STATE_QUATERNION &
        listener=$!
        sleep 1
        timeout 175 "$bin" run --platform "$out/px4-$mode.toml" --connection udpin:0.0.0.0:14540 \
            --mission "$out/mission.json" --no-api --exit-when-done --max-time-s 160 \
            --log "$out/$name.jsonl" --log-overwrite --state-dir "$out/state-$name" > "$out/$name.out" 2>&1
        rc=$?
        kill "$listener" 2> /dev/null; wait "$listener" 2> /dev/null
        ends=$(grep -oE '\[ *[0-9.]+ s\] drone_0: [a-z_]+ #[0-9] (succeeded|failed[^:]*)' "$out/$name.out" | sed -E 's/\[ *([0-9.]+) s\] drone_0: /\1s /' | paste -sd, -)
        fastest=$(python3 -c "
import json, math, sys
v = [math.hypot(d['vx'], d['vy']) for d in map(json.loads, open(sys.argv[1])) if d['mavpackettype'] == 'LOCAL_POSITION_NED' and d['z'] < -2.5]
print('%.2f' % max(v) if v else 'n/a')" "$out/$name.gcs.jsonl")
        # Touchdown: PX4's last position against Kestrel's at the start of `land` (ENU -> NED).
        touchdown=$(python3 -c "
import json, math, sys
gcs = [d for d in map(json.loads, open(sys.argv[1])) if d['mavpackettype'] == 'LOCAL_POSITION_NED']
began = next((r for r in map(json.loads, open(sys.argv[2])) if r.get('type') == 'pose' and r.get('behavior') == 'land'), None)
print('%.2f' % math.hypot(gcs[-1]['x'] - began['y'], gcs[-1]['y'] - began['x']) if gcs and began else 'n/a')" "$out/$name.gcs.jsonl" "$out/$name.jsonl")
        takeover=$(grep -c 'pilot took over' "$out/$name.out")
        echo "$name: rc=$rc fastest=${fastest} m/s touchdown=${touchdown} m from where landing began, takeovers=$takeover  $ends"
        echo "  $(python3 benches/field/sih_truth.py "$out/$name.gcs.jsonl")"
    done
done
bash "$anchors/run-px4-sih.sh" 0 stop > /dev/null
