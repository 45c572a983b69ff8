#!/usr/bin/env bash
# Benchmark (BENCHMARKS.md, "ROS 2 bridge: its CPU cost"): the CPU time of the ROS 2 publisher
# (`[ros2] enabled`, pose/odom/path/tf at `rate_hz` = 10 Hz per drone, /map at most 1 Hz).
# The same `kestrel sim` demo flight (seeded, real time: the publisher runs on the wall clock)
# is flown with the bridge off and on, for N drones; the process's CPU time (user + sys, from
# /proc/<pid>/stat) is read after SECONDS_RUN wall-clock seconds, and the process is then
# killed. With the bridge on, a Zenoh router (eclipse-zenoh in sitl/.venv, standing in for
# rmw_zenohd) and a subscriber to every key through it receive what Kestrel publishes, so the
# samples are really sent; their count is printed.
#
#     bash benches/ros2_cpu.sh target/release/kestrel [SECONDS_RUN] [DRONES...]
set -euo pipefail
kestrel="$(realpath "${1:-target/release/kestrel}")"
seconds="${2:-30}"
if [ $# -gt 2 ]; then drones=("${@:3}"); else drones=(1 3); fi
repo="$(cd "$(dirname "$0")/.." && pwd)"
python="$repo/sitl/.venv/bin/python"
work="$(mktemp -d)"
pids=()
cleanup() {
  for p in "${pids[@]}"; do kill "$p" 2>/dev/null || true; done
  rm -rf "$work"
}
trap cleanup EXIT
cd "$work"
ticks="$(getconf CLK_TCK)"
port="$("$python" -c 'import socket; s=socket.socket(); s.bind(("127.0.0.1",0)); print(s.getsockname()[1])')"

cat >router.py <<'PY'
import json, sys, threading, time, zenoh
endpoint = sys.argv[1]
scouting = {"multicast": {"enabled": False}, "gossip": {"enabled": True, "multihop": False}}
router = zenoh.open(zenoh.Config.from_json5(json.dumps(
    {"mode": "router", "listen": {"endpoints": [endpoint]}, "scouting": scouting})))
node = zenoh.open(zenoh.Config.from_json5(json.dumps(
    {"mode": "peer", "connect": {"endpoints": [endpoint]}, "scouting": scouting})))
count = [0]
lock = threading.Lock()
def on_sample(_):
    with lock:
        count[0] += 1
sub = node.declare_subscriber("**", on_sample)
print("ready", flush=True)
for line in sys.stdin:  # one line per question: how many samples so far
    with lock:
        print(count[0], flush=True)
PY
coproc ROUTER { exec "$python" router.py "tcp/127.0.0.1:$port"; }
pids+=("$ROUTER_PID")
read -r ready <&"${ROUTER[0]}"
[ "$ready" = ready ]
samples() {
  echo >&"${ROUTER[1]}"
  read -r n <&"${ROUTER[0]}"
  echo "$n"
}

printf '[ros2]\nenabled = true\nconnect = ["tcp/127.0.0.1:%s"]\n' "$port" >on.toml
: >off.toml

for n in "${drones[@]}"; do
  for mode in off on; do
    before="$(samples)"
    "$kestrel" sim --drones "$n" --seed 1 --listen 127.0.0.1:0 --config "$mode.toml" \
      --log "flight-$n-$mode.jsonl" >/dev/null 2>&1 &
    pid=$!
    pids+=("$pid")
    sleep "$seconds"
    read -r -a stat <"/proc/$pid/stat"
    # Fields 14 and 15 of /proc/<pid>/stat: user and system time, in clock ticks.
    cpu="$(echo "(${stat[13]} + ${stat[14]}) / $ticks" | bc -l)"
    # Measured: stopped at once (a clean stop is not what is measured).
    kill -KILL "$pid"
    wait "$pid" 2>/dev/null || true
    after="$(samples)"
    printf '%s drone(s), ros2 %-3s: CPU %.2f s in %s s wall (%.1f %% of a core); %s samples through the router\n' \
      "$n" "$mode" "$cpu" "$seconds" "$(echo "100 * $cpu / $seconds" | bc -l)" "$((after - before))"
  done
done
