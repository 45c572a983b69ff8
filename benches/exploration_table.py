#!/usr/bin/env python3
"""Aggregates the `kestrel explore` reports of benches/exploration_table.sh into runs.csv and a
markdown table beside the thesis's Table 5.4 (standard library only)."""
import csv, glob, json, os, statistics, sys

out, thesis_csv = sys.argv[1], sys.argv[2]
thesis = {}
with open(thesis_csv) as f:
    rows = [l for l in f if not l.startswith('#')]
for r in csv.DictReader(rows):
    thesis[(r['world'], int(r['drones']))] = r

runs = []
for path in sorted(glob.glob(os.path.join(out, '*.report.json'))):
    rep = json.load(open(path))
    m = rep.get('metrics') or {}
    flown = m.get('flown') or {}
    world = os.path.basename(rep['world']).removesuffix('.json')
    # A run that broke a limit (speed, yaw rate, clearance, separation: `kestrel evaluate`'s
    # `flown`) failed, whatever it explored; so did one with a collision.
    held = flown.get('held', False)
    runs.append(dict(world=world, drones=rep['drones'], seed=rep['seed'], allocator=rep['allocator'],
                     ok=bool(rep['succeeded'] and held and m.get('collisions') == 0),
                     explored=rep['succeeded'], limits_held=held,
                     max_speed=flown.get('max_speed_mps'), max_yaw_rate=flown.get('max_yaw_rate_radps'),
                     breaches='; '.join(flown.get('breaches', [])),
                     time_s=m.get('time_s'), area=m.get('area_pct'),
                     area_closed=m.get('area_closed_pct'), observable=m.get('observable_pct'),
                     path=m.get('path_m'), path_l1=m.get('path_l1_m'), overlap=m.get('overlap_pct'),
                     bound=m.get('lower_bound_s'), clearance=m.get('min_obstacle_clearance_m'),
                     separation=m.get('min_separation_m'), collisions=m.get('collisions'),
                     wall_s=rep.get('wall_s'), failures='; '.join(rep.get('failures', []))))
with open(os.path.join(out, 'runs.csv'), 'w', newline='') as f:
    w = csv.DictWriter(f, fieldnames=list(runs[0].keys()) if runs else ['world'])
    w.writeheader()
    w.writerows(runs)

def mean(xs):
    xs = [x for x in xs if x is not None]
    return statistics.mean(xs) if xs else float('nan')

def fmt(x, d=1):
    return '-' if x is None or x != x else f'{x:.{d}f}'

lines = ['| world | N | runs (ok) | T thesis (s) | T ours (s) | ratio | T/T_lb | area thesis % | '
         'area ours % (closed) | observable % | path thesis L1 (m) | path ours L1 / Eucl (m) | '
         'overlap thesis % | overlap ours % | min clearance (m) | min separation (m) | wall (s) |',
         '|' + '---|' * 17]
for world in ['low', 'medium', 'high']:
    for n in [1, 2, 3, 5, 7]:
        rs = [r for r in runs if r['world'] == world and r['drones'] == n and r['allocator'] == 'kestrel']
        if not rs:
            continue
        t = thesis.get((world, n), {})
        tt = float(t['time_s']) if t.get('time_s') else None
        tm = mean(r['time_s'] for r in rs)
        clear = [r['clearance'] for r in rs if r['clearance'] is not None]
        sep = [r['separation'] for r in rs if r['separation'] is not None]
        lines.append('| ' + ' | '.join([
            world, str(n), f"{len(rs)} ({sum(r['ok'] for r in rs)})", fmt(tt), fmt(tm),
            fmt(tm / tt if tt else None, 2), fmt(mean(r['time_s'] / r['bound'] for r in rs if r['bound']), 1),
            t.get('area_pct', '-'), f"{fmt(mean(r['area'] for r in rs), 2)} ({fmt(mean(r['area_closed'] for r in rs), 2)})",
            fmt(mean(r['observable'] for r in rs), 2), t.get('path_m', '-'),
            f"{fmt(mean(r['path_l1'] for r in rs), 0)} / {fmt(mean(r['path'] for r in rs), 0)}",
            t.get('overlap_pct') or '-', fmt(mean(r['overlap'] for r in rs), 1),
            fmt(min(clear) if clear else None, 2), fmt(min(sep) if sep else None, 2),
            fmt(mean(r['wall_s'] for r in rs), 0)]) + ' |')
lines += ['', '| allocator (low, 3 drones, seed 0) | ok | T (s) | area % (closed) | path Eucl (m) | overlap % |',
          '|---|---|---|---|---|---|']
for a in ['kestrel', 'thesis', 'nearest', 'farthest']:
    for r in [r for r in runs if r['world'] == 'low' and r['drones'] == 3 and r['allocator'] == a and r['seed'] == 0]:
        lines.append(f"| {a} | {r['ok']} | {fmt(r['time_s'])} | {fmt(r['area'], 2)} ({fmt(r['area_closed'], 2)}) | "
                     f"{fmt(r['path'], 0)} | {fmt(r['overlap'], 1)} |")
lines += ['', 'Every run (ok: explored, no collision and every limit held):', '',
          '| world | N | seed | allocator | ok | T (s) | area % | closed % | observable % | '
          'path (m) | collisions | max speed (m/s) | max yaw rate (rad/s) | limits broken | failures |',
          '|' + '---|' * 15]
for r in runs:
    lines.append(f"| {r['world']} | {r['drones']} | {r['seed']} | {r['allocator']} | {r['ok']} | {fmt(r['time_s'])} | "
                 f"{fmt(r['area'], 2)} | {fmt(r['area_closed'], 2)} | {fmt(r['observable'], 2)} | {fmt(r['path'], 0)} | "
                 f"{r['collisions']} | {fmt(r['max_speed'], 3)} | {fmt(r['max_yaw_rate'], 3)} | "
                 f"{r['breaches'] or '-'} | {r['failures']} |")
open(os.path.join(out, 'table.md'), 'w').write('\n'.join(lines) + '\n')
print('\n'.join(lines))
