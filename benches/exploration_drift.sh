#!/usr/bin/env bash
# How exploration degrades with what a real drone has: `kestrel explore` with each drone's position
# estimate drifting at 0, 1, 2, 3 and 5 cm/s and 5 % of the range readings returning nothing,
# beside the noise-free run, on seeded generated worlds; every run judged from its flight log's
# truth against the true world, every run reported.
#
#   bash benches/exploration_drift.sh [OUT_DIR]
#   (WORLDS="gen20-61 gen20-62" DRONES="1 3" DRIFTS="0 0.01 0.02 0.03 0.05" JOBS=1 SEED=0 to change;
#    a world named genS-W is `kestrel world generate --size-m S --density 0.1 --seed W`,
#    low50-W, medium50-W and high50-W are 50 x 50 m worlds of the thesis's three densities (0.06,
#    0.126 and 0.2548 poles per m^2) of seed W, to tune on in place of the thesis's own; any
#    other name is sitl/worlds/NAME.json; WAIT_WHILE=FILE holds each run while FILE exists, for
#    a machine shared with real-time flights; EXPLORE_ARGS='{"heading": "align"}' passes the
#    explore behavior's arguments to every run; KEEP_LOGS=1 keeps each run's flight log;
#    NOISE_FREE=0 leaves out the noise-free runs)
#
# Writes OUT_DIR/drift.md: one line a run (world, drones, drift, dropout, time, area, observable
# area, collisions, least clearance and separation, outcome).
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/exploration-drift}
worlds=${WORLDS:-"gen20-61 gen20-62"}
drones=${DRONES:-"1 3"}
drifts=${DRIFTS:-"0 0.01 0.02 0.03 0.05"}
jobs=${JOBS:-1}
explore_seed=${SEED:-0}
mkdir -p "$out"
# KESTREL_BIN=path runs a binary built elsewhere (same sources; the runs are deterministic).
if [ -z "${KESTREL_BIN:-}" ]; then cargo build --release --quiet; fi
bin=${KESTREL_BIN:-target/release/kestrel}

world_file() { # name
    case "$1" in
        gen*-*) local size=${1#gen}; size=${size%-*}; local seed=${1##*-}
            [ -s "$out/$1.json" ] || "$bin" world generate --size-m "$size" --density 0.1 \
                --seed "$seed" --out "$out/$1.json" > /dev/null
            echo "$out/$1.json" ;;
        low50-*|medium50-*|high50-*) local seed=${1##*-} density
            case "$1" in low*) density=0.06 ;; medium*) density=0.126 ;; *) density=0.2548 ;; esac
            [ -s "$out/$1.json" ] || "$bin" world generate --size-m 50 --density "$density" \
                --seed "$seed" --out "$out/$1.json" > /dev/null
            echo "$out/$1.json" ;;
        *) echo "sitl/worlds/$1.json" ;;
    esac
}

run() { # world-name world-file drones drift dropout
    local tag="$1-$3-$4-$5"
    if [ ! -s "$out/$tag.report.json" ]; then
        while [ -n "${WAIT_WHILE:-}" ] && [ -e "$WAIT_WHILE" ]; do sleep 20; done
        "$bin" explore --world "$2" --drones "$3" --seed "$explore_seed" --position-drift-mps "$4" \
            --range-dropout "$5" --log "$out/$tag.jsonl" --log-overwrite \
            --report "$out/$tag.report.json" --progress-every-s 100000 \
            ${EXPLORE_ARGS:+--explore-args "$EXPLORE_ARGS"} > "$out/$tag.out" 2>&1 || true
        [ -n "${KEEP_LOGS:-}" ] || rm -f "$out/$tag.jsonl"
    fi
}
export -f run
export out bin explore_seed EXPLORE_ARGS KEEP_LOGS
{
    for w in $worlds; do
        f=$(world_file "$w")
        for n in $drones; do
            [ "${NOISE_FREE:-1}" = 0 ] || echo "$w $f $n 0 0"
            for d in $drifts; do echo "$w $f $n $d 0.05"; done
        done
    done
} | xargs -P "$jobs" -L 1 bash -c 'run "$@"' _

python3 - "$out" <<'PY' | tee "$out/drift.md"
import glob, json, os, sys
out = sys.argv[1]
print("| world | N | drift (cm/s) | dropout | T (s) | area % | observable % | collisions | min clearance (m) | min separation (m) | outcome |")
print("|---|---|---|---|---|---|---|---|---|---|---|")
rows = []
for p in glob.glob(os.path.join(out, "*.report.json")):
    r = json.load(open(p))
    w, n, drift, dropout = os.path.basename(p)[: -len(".report.json")].rsplit("-", 3)
    m = r["metrics"]
    f = lambda v, d=2: "-" if v is None else f"{v:.{d}f}"
    rows.append(((w, int(n), float(dropout) > 0, float(drift)),
        f"| {w} | {n} | {100 * float(drift):g} | {float(dropout):g} | {m['time_s']:.1f} | {m['area_pct']:.2f} "
        f"| {m['observable_pct']:.2f} | {m['collisions']} | {f(m.get('min_obstacle_clearance_m'))} "
        f"| {f(m.get('min_separation_m'))} | {'ok' if r['succeeded'] else '; '.join(r['failures'])} |"))
for _, line in sorted(rows):
    print(line)
PY
