#!/usr/bin/env bash
# Benchmark (BENCHMARKS.md, "Release binary size"): the stripped size and sections of two
# release binaries, and the simulator's speed of both side by side. Each binary is stripped as
# `cargo deb --strip` does; then PAIRS times both fly the same seeded exploration at once (the
# 7-drone high world, as in BENCHMARKS.md), the first started alternating, so each pair sees
# the same load. Prints one line per binary (stripped bytes, .text, .rodata, .eh_frame) and one
# per run (wall s, user CPU s, simulated s), and checks that both flew the same flight (the header line names the log, so it is left out).
#
#     bash benches/binary_size.sh BASELINE CANDIDATE [PAIRS]
set -euo pipefail
base="$(realpath "$1")"
cand="$(realpath "$2")"
pairs="${3:-4}"
repo="$(cd "$(dirname "$0")/.." && pwd)"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

for name in base cand; do
  bin="$base"
  [ "$name" = cand ] && bin="$cand"
  strip -o "$work/$name" "$bin"
  size -A "$work/$name" | awk -v n="$name" -v s="$(stat -c %s "$work/$name")" '
    $1 == ".text" { t = $2 } $1 == ".rodata" { r = $2 } $1 == ".eh_frame" { e = $2 }
    END { printf "%s: stripped %.2f MB, .text %.2f MB, .rodata %.2f MB, .eh_frame %.2f MB\n",
          n, s / 1e6, t / 1e6, r / 1e6, e / 1e6 }'
done

fly() { # name, pair
  /usr/bin/time -f "%e %U" -o "$work/$1.$2.time" "$work/$1" explore \
    --world "$repo/sitl/worlds/high.json" --drones 7 --seed 1 \
    --log "$work/$1.$2.jsonl" --log-overwrite >"$work/$1.$2.out" 2>&1
}

for pair in $(seq 1 "$pairs"); do
  if [ $((pair % 2)) = 1 ]; then first=base second=cand; else first=cand second=base; fi
  fly "$first" "$pair" &
  sleep 0.2
  fly "$second" "$pair" &
  wait
  for name in base cand; do
    read -r wall user <"$work/$name.$pair.time"
    simulated=$(python3 -c "import json,sys; print(max((json.loads(l).get('t') or 0) for l in open(sys.argv[1])))" "$work/$name.$pair.jsonl")
    echo "pair $pair $name: wall $wall s, user $user s, simulated $simulated s"
  done
  if cmp -s <(tail -n +2 "$work/base.$pair.jsonl") <(tail -n +2 "$work/cand.$pair.jsonl"); then
    echo "pair $pair: the same flight (the logs' records after the header, byte for byte)"
  else
    echo "pair $pair: the flight logs differ"
  fi
done
