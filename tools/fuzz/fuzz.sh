#!/usr/bin/env bash
# make fuzz: the bus fuzzer (tests/fuzz/fuzz_bus.c) under libFuzzer with ASan and UBSan
# (Debian clang), for FUZZ_SECONDS (default 600); then the coverage of src/ reached by
# the corpus. Prints executions, executions per second, coverage and findings; exits 1 if
# anything was found (the inputs are in build/fuzz/findings/: fix, then copy them to
# tests/fuzz/findings/ so every `make test` replays them).
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${FUZZ_SECONDS:-600}
out=build/fuzz
mkdir -p "$out/corpus" "$out/findings" "$out/cov"
srcs=(src/*.c board/boards.c hal/host/hal_host.c hal/host/flash_sim.c hal/host/motor_sim.c
      hal/host/image_host.c)
defs=(-DREGS_WITH_TEXT=1 -DSERVO_FW_VERSION=1 -Iinclude -Ihal -Ihal/host)

clang -std=c11 -g -O1 -fsanitize=fuzzer,address,undefined -fno-sanitize-recover=all \
    -DFUZZ_LIBFUZZER "${defs[@]}" "${srcs[@]}" tests/fuzz/fuzz_bus.c -lm -o "$out/fuzz_bus"

echo "== libFuzzer: ${seconds} s on $(basename "$out")/fuzz_bus (seeds: tests/fuzz/corpus)"
rc=0
"$out/fuzz_bus" -max_total_time="$seconds" -max_len=10000 -timeout=20 -rss_limit_mb=2048 \
    -print_final_stats=1 -artifact_prefix="$out/findings/" \
    "$out/corpus" tests/fuzz/corpus > "$out/fuzz.log" 2>&1 || rc=$?
grep -E "^#[0-9]+ +(INITED|DONE)" "$out/fuzz.log" | tail -2 || true
runs=$(awk '/stat::number_of_executed_units/ {print $NF}' "$out/fuzz.log")
speed=$(awk '/stat::average_exec_per_sec/ {print $NF}' "$out/fuzz.log")
edges=$(grep -oE "cov: [0-9]+" "$out/fuzz.log" | tail -1 | awk '{print $2}')
found=$(find "$out/findings" -type f \( -name 'crash-*' -o -name 'leak-*' -o -name 'timeout-*' \
        -o -name 'oom-*' \) | wc -l)
echo "executions: ${runs:-?} in ${seconds} s (${speed:-?} exec/s), libFuzzer edges: ${edges:-?}," \
     "corpus: $(ls "$out/corpus" | wc -l) inputs, findings: $found"

# Line and branch coverage of src/ by the whole corpus (seeds + what this run kept).
clang -std=c11 -O0 -fprofile-instr-generate -fcoverage-mapping "${defs[@]}" "${srcs[@]}" \
    tests/fuzz/fuzz_bus.c -lm -o "$out/cov/fuzz_cov"
rm -f "$out/cov/"*.profraw
LLVM_PROFILE_FILE="$out/cov/run.profraw" "$out/cov/fuzz_cov" tests/fuzz/corpus "$out/corpus" \
    >/dev/null || true
llvm-profdata-14 merge -sparse "$out/cov/run.profraw" -o "$out/cov/fuzz.profdata"
echo "== coverage of src/ by the corpus (llvm-cov)"
llvm-cov-14 report "$out/cov/fuzz_cov" -instr-profile="$out/cov/fuzz.profdata" src/*.c |
    awk '$1 ~ /\.c$/ || $1 == "TOTAL" { printf "  src/%-12s regions %6s  lines %6s  branches %6s\n", $1, $4, $10, $13 }' |
    sed 's|src/TOTAL|total:    |'
if [ "$rc" -ne 0 ] || [ "$found" -ne 0 ]; then
    echo "make fuzz: FINDINGS in $out/findings/ (log: $out/fuzz.log)" >&2
    tail -40 "$out/fuzz.log" >&2
    exit 1
fi
