#!/usr/bin/env bash
# Reproduces the exploration table of BENCHMARKS.md (thesis Table 5.4 side by side) in one go:
# every (world, drone count, seed) run of `kestrel explore` with the thesis's parameters, each
# judged from its flight log against the true world, every run reported (none dropped), then the
# allocator ablation (Figure 6.1) on the low world with 3 drones.
#
#   bash benches/exploration_table.sh [OUT_DIR]        (SEEDS="0 1 2" JOBS=2 to change)
#
# Writes OUT_DIR/runs.csv (one line a run), OUT_DIR/table.md (means, ratios, thesis rows) and
# OUT_DIR/speeds.md (the horizontal speed flown in every run against the 0.75 m/s limit). A run
# is ok only if it explored, had no collision and held every limit `kestrel evaluate` judges.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/exploration-table}
seeds=${SEEDS:-"0 1"}
jobs=${JOBS:-2}
mkdir -p "$out"
# KESTREL_BIN=path runs a binary built elsewhere (same sources; the runs are deterministic).
if [ -z "${KESTREL_BIN:-}" ]; then cargo build --release --quiet; fi
bin=${KESTREL_BIN:-target/release/kestrel}

run() { # world drones seed allocator
    local tag="$1-$2-$3-$4"
    if [ ! -s "$out/$tag.report.json" ]; then
        "$bin" explore --world "sitl/worlds/$1.json" --drones "$2" --seed "$3" --allocator "$4" \
            --log "$out/$tag.jsonl" --report "$out/$tag.report.json" --progress-every-s 100000 \
            > "$out/$tag.out" 2>&1 || true
        python3 benches/flown_speed.py "$out/$tag.jsonl" > "$out/$tag.speed.json" || true
        rm -f "$out/$tag.jsonl"
    fi
}
export -f run
export out bin
{
    for w in low medium high; do for n in 1 2 3 5 7; do for s in $seeds; do
        echo "$w $n $s kestrel"; done; done; done
    for a in thesis nearest farthest; do echo "low 3 0 $a"; done
} | xargs -P "$jobs" -L 1 bash -c 'run "$@"' _

python3 benches/exploration_table.py "$out" benches/thesis-exploration-results.csv
python3 benches/flown_speed.py --summary "$out" | tee "$out/speeds.md"
