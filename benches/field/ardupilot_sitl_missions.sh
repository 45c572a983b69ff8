#!/usr/bin/env bash
# Field check on the real ArduCopter SITL (built by ../shared/anchors/build-ardupilot.sh): the
# mission of tests/convergence_e2e.rs (takeoff 3 m, path-facing go_to 5 m, path-facing
# follow_path, go_to, land; 1 m/s) flown RUNS times with the built-in `ardupilot-copter` profile,
# each on a fresh SITL (its EKF takes about 40 s before it can arm; Kestrel waits for it).
# Prints per run whether the mission succeeded, each item's end time, the fastest horizontal
# speed ArduPilot reported (LOCAL_POSITION_NED on an observer port) against the 1 m/s limit, how
# far from where its landing began it touched down, and any (false) pilot takeover.
#
#   bash benches/field/ardupilot_sitl_missions.sh [RUNS]
#
# Not part of CI. Needs sitl/.venv (pymavlink) and target/debug/kestrel (KESTREL=path to use
# another).
set -uo pipefail
cd "$(dirname "$0")/../.."
runs=${1:-3}
anchors=../shared/anchors
bin=${KESTREL:-target/debug/kestrel}
out=${OUT:-target/ardupilot-sitl-missions}
mkdir -p "$out"
cat > "$out/mission.json" <<'JSON'
{"target": "drone_0", "plan": [
 {"behavior": "takeoff", "args": {"height": 3.0, "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 5.0, "y": 0.0, "z": 3.0, "speed": 1.0}},
 {"behavior": "follow_path", "method": "follow_path_with_path_facing", "args": {"path": [[5, 4, 3], [1, 4, 3]], "speed": 1.0}},
 {"behavior": "go_to", "method": "go_to_path_facing", "args": {"x": 1.0, "y": 1.5, "z": 3.0, "speed": 1.0}},
 {"behavior": "land", "args": {"speed": 0.5}}]}
JSON
for i in $(seq 1 "$runs"); do
    name="run-$i"
    bash "$anchors/run-ardupilot-sitl.sh" stop 0 > /dev/null
    bash "$anchors/run-ardupilot-sitl.sh" start 0 > /dev/null || { echo "$name: ArduCopter SITL did not start"; continue; }
    # SERIAL1 (tcp 5762) as an observer; ask it for LOCAL_POSITION_NED at 20 Hz.
    sitl/.venv/bin/python - "$out/$name.gcs.jsonl" <<'PY' &
import json, sys, time
from pymavlink import mavutil
m = mavutil.mavlink_connection('tcp:127.0.0.1:5762')
out = open(sys.argv[1], 'w'); t0 = time.time(); asked = 0
while time.time() - t0 < 230:
    msg = m.recv_match(blocking=True, timeout=1)
    if msg is None: continue
    if msg.get_type() == 'HEARTBEAT' and asked < 5 and msg.get_srcComponent() == 1:
        m.mav.command_long_send(msg.get_srcSystem(), 1, 511, 0, 32, 50000, 0, 0, 0, 0, 0); asked += 1
    if msg.get_type() == 'LOCAL_POSITION_NED':
        d = msg.to_dict(); d['_t'] = time.time() - t0; out.write(json.dumps(d) + '\n'); out.flush()
PY
    listener=$!
    sleep 1
    timeout 235 "$bin" run --platform ardupilot-copter --connection tcpout:127.0.0.1:5760 \
        --mission "$out/mission.json" --no-api --exit-when-done --max-time-s 220 \
        --log "$out/$name.jsonl" --log-overwrite --state-dir "$out/state-$name" > "$out/$name.out" 2>&1
    rc=$?
    kill "$listener" 2> /dev/null; wait "$listener" 2> /dev/null
    ends=$(grep -oE '\[ *[0-9.]+ s\] drone_0: [a-z_]+ #[0-9] (succeeded|failed[^:]*)' "$out/$name.out" | sed -E 's/\[ *([0-9.]+) s\] drone_0: /\1s /' | paste -sd, -)
    fastest=$(python3 -c "
import json, math, sys
v = [math.hypot(d['vx'], d['vy']) for d in map(json.loads, open(sys.argv[1])) if d['z'] < -2.5]
print('%.2f' % max(v) if v else 'n/a')" "$out/$name.gcs.jsonl")
    touchdown=$(python3 -c "
import json, math, sys
gcs = [d for d in map(json.loads, open(sys.argv[1]))]
began = next((r for r in map(json.loads, open(sys.argv[2])) if r.get('type') == 'pose' and r.get('behavior') == 'land'), None)
print('%.2f' % math.hypot(gcs[-1]['x'] - began['y'], gcs[-1]['y'] - began['x']) if gcs and began else 'n/a')" "$out/$name.gcs.jsonl" "$out/$name.jsonl")
    takeover=$(grep -c 'pilot took over' "$out/$name.out")
    echo "$name: rc=$rc fastest=${fastest} m/s touchdown=${touchdown} m from where landing began, takeovers=$takeover  $ends"
done
bash "$anchors/run-ardupilot-sitl.sh" stop 0 > /dev/null
