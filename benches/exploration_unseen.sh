#!/usr/bin/env bash
# The exploration target checked on worlds the method was not tuned on: pole worlds generated
# as the thesis's were (`kestrel world generate`, 50 x 50 m, the thesis's three densities) from
# seeds no earlier measurement used, each flown by 1, 2, 3, 5 and 7 drones with the defaults and
# judged from its flight log against the true world. Every run is reported.
#
#   bash benches/exploration_unseen.sh [OUT_DIR]     (WORLD_SEEDS="51 52" SEED=0 JOBS=2 to change)
#
# Writes OUT_DIR/unseen.md: per density and drone count, each world's time over the thesis's
# time for that cell, the mean, the least closed area, the least clearance and any failure.
set -euo pipefail
cd "$(dirname "$0")/.."
out=${1:-target/exploration-unseen}
world_seeds=${WORLD_SEEDS:-"51 52"}
seed=${SEED:-0}
jobs=${JOBS:-2}
mkdir -p "$out"
cargo build --release --quiet
bin=target/release/kestrel

for s in $world_seeds; do
    for d in low:0.06 medium:0.126 high:0.2548; do
        w="$out/${d%%:*}-s$s.json"
        [ -s "$w" ] || "$bin" world generate --size-m 50 --density "${d#*:}" --seed "$s" --out "$w" > /dev/null
    done
done

run() { # world-file drones
    local tag
    tag="$(basename "$1" .json)-$2"
    if [ ! -s "$out/$tag.report.json" ]; then
        "$bin" explore --world "$1" --drones "$2" --seed "$seed" --log "$out/$tag.jsonl" \
            --log-overwrite --report "$out/$tag.report.json" --progress-every-s 100000 \
            > "$out/$tag.out" 2>&1 || true
        rm -f "$out/$tag.jsonl"
    fi
}
export -f run
export out bin seed
for s in $world_seeds; do for d in low medium high; do for n in 1 2 3 5 7; do
    echo "$out/$d-s$s.json $n"; done; done; done | xargs -P "$jobs" -L 1 bash -c 'run "$@"' _

python3 - "$out" benches/thesis-exploration-results.csv <<'PY'
import csv, glob, json, os, statistics, sys
out, thesis_csv = sys.argv[1], sys.argv[2]
with open(thesis_csv) as f:
    thesis = {(r['world'], int(r['drones'])): float(r['time_s'])
              for r in csv.DictReader(l for l in f if not l.startswith('#'))}
cells = {}
for path in sorted(glob.glob(os.path.join(out, '*.report.json'))):
    rep = json.load(open(path))
    density, world_seed = os.path.basename(rep['world']).removesuffix('.json').split('-s')
    m = rep.get('metrics') or {}
    cells.setdefault((density, rep['drones']), []).append((int(world_seed), rep, m))
lines = ['| density | N | time / thesis per world (seed) | mean | least closed area % | '
         'least clearance (m) | failures |', '|' + '---|' * 7]
ratios = []
for density in ['low', 'medium', 'high']:
    for n in [1, 2, 3, 5, 7]:
        rs = sorted(cells.get((density, n), []), key=lambda r: r[0])
        if not rs:
            continue
        q = [m['time_s'] / thesis[(density, n)] for _, _, m in rs]
        ratios += q
        fails = '; '.join(f for _, rep, _ in rs for f in rep.get('failures', []))
        lines.append(f"| {density} | {n} | " + ' / '.join(f'{x:.3f} ({s})' for x, (s, _, _) in zip(q, rs))
                     + f" | {statistics.mean(q):.3f} | {min(m['area_closed_pct'] for _, _, m in rs):.2f}"
                     + f" | {min(m['min_obstacle_clearance_m'] for _, _, m in rs):.2f} | {fails or '-'} |")
lines.append(f'\n{len(ratios)} runs, mean ratio {statistics.mean(ratios):.3f}, '
             f'{sum(x > 0.6 for x in ratios)} above 0.6.')
open(os.path.join(out, 'unseen.md'), 'w').write('\n'.join(lines) + '\n')
print('\n'.join(lines))
PY
