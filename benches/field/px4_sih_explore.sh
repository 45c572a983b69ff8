#!/usr/bin/env bash
# Field check on the real PX4 SITL (SIH quadcopter, built by ../shared/anchors/build-px4.sh):
# three PX4 SIH instances explore WORLD from one `kestrel run --virtual-world WORLD`, started
# with `POST /api/exploration/start` (every `explore` argument at its default but a 2.0 m
# height, unless ARGS says otherwise). Each instance is put at the world's start for three drones (`origin_enu_m`).
# Prints how each drone's exploration ended, the least clearance to the world's obstacles it
# flew (from the flight log, `kestrel evaluate`), the area seen, the tracking margin each
# explorer added to its safety distance, and each drone's true horizontal speed (SIH's ground
# truth, HIL_STATE_QUATERNION, recorded from PX4's GCS link) against the exploring speed.
#
#   bash benches/field/px4_sih_explore.sh [WORLD] [RUN_NAME]     (ARGS='{"safety_distance":0.5}')
#
# Not part of CI (PX4 takes 8-15 min to build here). Needs target/debug/kestrel (KESTREL=path to
# use another). An exploration still going after LIMIT_S (default 900) s is stopped and reported.
set -uo pipefail
cd "$(dirname "$0")/../.."
world=${1:-sitl/worlds/room10_fleet.json}
name=${2:-explore-1}
anchors=../shared/anchors
bin=${KESTREL:-target/debug/kestrel}
out=${OUT:-target/px4-sih-explore}
limit=${LIMIT_S:-900}
# PX4's profile refuses flight below 2.0 m (its barometric height may be 1.5 m off).
args=${ARGS:-'{"height": 2.0}'}
port=18091
mkdir -p "$out"
python3 - "$world" > "$out/$name.toml" <<'PY'
import json, sys
w = json.load(open(sys.argv[1]))
starts = w["starts_xy_yaw"]["3"]
lo = [min(w["bounds_m"]["x"]), min(w["bounds_m"]["y"])]
hi = [max(w["bounds_m"]["x"]), max(w["bounds_m"]["y"])]
size = max(hi[0] - lo[0], hi[1] - lo[1]) + 2.0
# The grid: the world's bounds and 1 m round them (origin_enu_m is its south-west corner).
print(f'[map]\nsize_m = [{size:.1f}, {size:.1f}]\norigin_enu_m = [{lo[0] - 1.0:.2f}, {lo[1] - 1.0:.2f}]\n')
print('[mavlink]\nplatform = "platforms/px4.toml"\n')
for i, (x, y, _yaw) in enumerate(starts):
    # PX4 SIH starts facing north whatever the world says; the explorer turns anyway.
    print(f'[[vehicle]]\nid = "drone_{i}"\nconnection = "udpin:0.0.0.0:{14540 + i}"\n'
          f'target_system = {i + 1}\norigin_enu_m = [{x}, {y}, 0.0]\n')
PY
for i in 0 1 2; do
    bash "$anchors/run-px4-sih.sh" "$i" stop > /dev/null
    bash "$anchors/run-px4-sih.sh" "$i" start > /dev/null || { echo "PX4 $i did not start"; exit 1; }
done
sleep 2
rm -rf "$out/state-$name"
# Every PX4's GCS link sends to 14550: one witness records their ground truth.
sitl/.venv/bin/python benches/field/listen.py udpin:127.0.0.1:14550 $((limit + 300)) "$out/$name.gcs.jsonl" \
    HIL_STATE_QUATERNION &
listener=$!
"$bin" run --config "$out/$name.toml" --virtual-world "$world" --listen "127.0.0.1:$port" \
    --log "$out/$name.jsonl" --log-overwrite --state-dir "$out/state-$name" > "$out/$name.out" 2>&1 &
kestrel=$!
python3 - "$port" "$args" "$limit" <<'PY'
import json, sys, time, urllib.request
port, args, limit = sys.argv[1], json.loads(sys.argv[2]), float(sys.argv[3])
base = f"http://127.0.0.1:{port}"
def call(path, body=None):
    req = urllib.request.Request(base + path, data=None if body is None else json.dumps(body).encode(),
                                 headers={"Content-Type": "application/json"})
    try:
        with urllib.request.urlopen(req, timeout=10) as r:
            return r.status, json.loads(r.read() or b"null")
    except urllib.error.HTTPError as e:
        return e.code, json.loads(e.read() or b"null")
    except OSError as e:
        return None, str(e)
drones = ["drone_0", "drone_1", "drone_2"]
deadline = time.time() + 120
while True:  # every PX4 ready (position and link) before starting
    code, s = call("/api/status")
    if code == 200 and all(d.get("has_position") and d.get("ready_to_fly") for d in s["drones"]):
        break
    if time.time() > deadline:
        sys.exit(f"not ready after 120 s: {s}")
    time.sleep(1)
time.sleep(5)
code, answer = call("/api/exploration/start", {"drones": drones, "args": args})
print("start:", code, json.dumps(answer)[:300])
start = time.time()
while time.time() - start < limit:
    code, s = call("/api/status")
    missions = [d.get("mission") or {} for d in s["drones"]] if code == 200 else []
    if missions and all(m.get("done_items") == 1 or m.get("last_error") for m in missions):
        break
    time.sleep(2)
else:
    print(f"still exploring after {limit:.0f} s: stopped", call("/api/exploration/stop", {"drones": drones})[0])
for d in s["drones"]:
    m = d.get("mission") or {}
    fb = m.get("feedback_current") or {}
    print(f'{d["drone"]}: done_items {m.get("done_items")}, error {m.get("last_error_code")}: '
          f'{m.get("last_error")}, tracking_margin_m {fb.get("tracking_margin_m")}')
print(f"wall {time.time() - start:.0f} s")
PY
sleep 3
kill -INT "$kestrel" 2> /dev/null; wait "$kestrel" 2> /dev/null
kill "$listener" 2> /dev/null; wait "$listener" 2> /dev/null
for i in 0 1 2; do bash "$anchors/run-px4-sih.sh" "$i" stop > /dev/null; done
python3 - "$out/$name.gcs.jsonl" "$args" <<'PY'
import json, math, sys
speed = json.loads(sys.argv[2]).get("speed", 0.75)
by = {}
for line in open(sys.argv[1]):
    h = json.loads(line)
    by.setdefault(h["_src"][0], []).append(h)
for sysid, rows in sorted(by.items()):
    ground = rows[0]["alt"] / 1000
    v = sorted(math.hypot(h["vx"], h["vy"]) / 100 for h in rows if h["alt"] / 1000 - ground > 0.6)
    if not v:
        print(f"truth, system {sysid}: never above 0.6 m")
        continue
    over = sum(x > speed * 1.03 for x in v) / len(v)
    print(f"truth, system {sysid}: horizontal speed p50 {v[len(v) // 2]:.2f} p99 {v[int(0.99 * len(v))]:.2f} "
          f"max {v[-1]:.2f} m/s; {100 * over:.1f} % over {speed} m/s + 3 %")
PY
"$bin" evaluate --world "$world" --log "$out/$name.jsonl" --out "$out/$name.eval.json" 2>&1 | grep -E "area|clearance|collision|time|flown|limits" | head -8
grep -E "strays up to|virtual collision" "$out/$name.out" | sed -E 's/^[^ ]+ +//' | head -12
