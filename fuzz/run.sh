#!/usr/bin/env bash
# Fuzzes one target (or `all`, one after another) with AFL++ through cargo-afl for SECONDS each.
#
#   fuzz/run.sh TARGET SECONDS       TARGET: mavlink | mission | scans | config | fleet_wire | fleet_intake | all
#
# Installs cargo-afl (which builds AFL++) if missing, builds the instrumented targets, starts
# from fuzz/corpus/TARGET, writes AFL's state to fuzz/out/TARGET (not committed), then prints
# the executions done and exits 1 if AFL saved any crash or hang. Limits per input: 1 GiB of
# memory (-m), 2 s of time (-t). Runs under `nice -n 19` (FUZZ_NICE to change).
# FUZZ_RESUME=1 continues from fuzz/out/TARGET instead: its queue, and AFL's counts go on.
set -euo pipefail
cd "$(dirname "$0")"

targets=(mavlink mission scans config fleet_wire fleet_intake)
if [ $# -ne 2 ] || ! [[ $2 =~ ^[0-9]+$ ]]; then
    echo "usage: fuzz/run.sh {${targets[*]// /|}|all} SECONDS" >&2
    exit 2
fi
if [ "$1" = all ]; then
    chosen=("${targets[@]}")
elif [[ " ${targets[*]} " == *" $1 "* ]]; then
    chosen=("$1")
else
    echo "unknown target '$1' (known: ${targets[*]})" >&2
    exit 2
fi
seconds=$2

# cargo-afl 0.18 matches the afl crate in Cargo.toml; installing it also builds AFL++.
if ! cargo afl --version >/dev/null 2>&1; then
    cargo install cargo-afl --locked --version '^0.18'
fi
if ! config_log=$(cargo afl config --build 2>&1) && ! grep -q "already built" <<<"$config_log"; then
    echo "$config_log" >&2
    exit 1
fi

cargo afl build --release --quiet

export AFL_SKIP_CPUFREQ=1 AFL_NO_AFFINITY=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1
export AFL_NO_UI=1 AFL_QUIET=1
status=0
for t in "${chosen[@]}"; do
    out="out/$t"
    input="corpus/$t"
    if [ "${FUZZ_RESUME:-0}" = 1 ] && [ -f "$out/default/fuzzer_stats" ]; then
        input=-
    else
        rm -rf "$out" "out/$t.log"
    fi
    mkdir -p out
    echo "== fuzz $t for ${seconds}s (input: $input, state: fuzz/$out)"
    dict=()
    if [ -f "dict/$t.dict" ]; then dict=(-x "dict/$t.dict"); fi
    nice -n "${FUZZ_NICE:-19}" cargo afl fuzz -i "$input" -o "$out" "${dict[@]}" -m 1024 \
        -t 2000 -V "$seconds" "target/release/$t" >>"out/$t.log" 2>&1 || {
        tail -30 "out/$t.log" >&2
        status=1
        continue
    }
    stat() { awk -v k="$1" '$1 == k { print $3 }' "$out/default/fuzzer_stats"; }
    crashes=$(stat saved_crashes)
    hangs=$(stat saved_hangs)
    echo "$t: $(stat execs_done) executions in $(stat run_time) s ($(stat execs_per_sec)/s)," \
        "$(stat corpus_count) inputs in the queue, $crashes crashes, $hangs hangs"
    if [ "$crashes" != 0 ] || [ "$hangs" != 0 ]; then
        echo "$t: inputs saved in fuzz/$out/default/crashes and hangs:" >&2
        ls "$out"/default/crashes "$out"/default/hangs >&2
        status=1
    fi
done
exit $status
