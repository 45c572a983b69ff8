#!/usr/bin/env bash
# How fast the simulator explores: the thesis's high world with 7 drones (seed 1), timed whole
# (`kestrel explore`, flight log written), RUNS times one after another. Target: under 30 s wall
# on the 2-core reference machine (issue "Exploration, honestly twice as fast", item 5).
#
#   bash benches/explore_speed.sh [RUNS]          (KESTREL_BIN=path to time another build)
#
# Prints per run the wall and user CPU seconds and what was simulated; BENCHMARKS.md,
# "Simulation speed: seven drones on the high world".
set -euo pipefail
cd "$(dirname "$0")/.."
runs=${1:-3}
if [ -z "${KESTREL_BIN:-}" ]; then cargo build --release --quiet --bin kestrel; fi
bin=${KESTREL_BIN:-target/release/kestrel}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for run in $(seq 1 "$runs"); do
    /usr/bin/time -f "%e %U" -o "$work/time" "$bin" explore --world sitl/worlds/high.json \
        --drones 7 --seed 1 --log "$work/flight.jsonl" --log-overwrite > "$work/out" 2>&1
    read -r wall user < "$work/time"
    echo "run $run: ${wall} s wall, ${user} s user CPU; $(grep -m1 '^simulated' "$work/out")"
done
