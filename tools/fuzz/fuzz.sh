#!/usr/bin/env bash
# make fuzz: every fuzz target (tests/fuzz/fuzz_*.c) under libFuzzer with ASan and UBSan
# (Debian clang) for FUZZ_SECONDS each (default 600), one target per core (FUZZ_JOBS,
# default nproc), with a progress line per running target every PROGRESS_SECONDS (10);
# then the coverage of src/ by the merged corpora (llvm-cov). Ends with one line per
# target and the coverage line:
#   fuzz TARGET: N executions in S s (R exec/s), findings: K
#   coverage src/: lines X% branches Y%
# Exits 1 if anything was found (the inputs are in build/fuzz/TARGET/findings/: fix, then
# copy them to tests/fuzz/findings/TARGET/ so every `make test` replays them).
#
#   tools/fuzz/fuzz.sh               the session above (FUZZ_TARGETS="fuzz_frame ..." for
#                                    some targets only; FUZZ_NICE=19 for a long run in the
#                                    background on a shared machine)
#   tools/fuzz/fuzz.sh build         build the targets only (build/fuzz/bin/)
#   tools/fuzz/fuzz.sh coverage      only the coverage of src/ by the corpora (and
#                                    build/fuzz/cov-show.txt, line by line)
#   tools/fuzz/fuzz.sh merge [T...]  minimise tests/fuzz/corpus/T/ together with what the
#                                    runs found (build/fuzz/T/corpus/) with -merge=1, and
#                                    replace the checked-in corpus with the result
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${FUZZ_SECONDS:-600}
jobs=${FUZZ_JOBS:-$(nproc 2>/dev/null || echo 2)}
progress=${PROGRESS_SECONDS:-10}
read -r -a targets <<< "${FUZZ_TARGETS:-fuzz_frame fuzz_store fuzz_update fuzz_planner fuzz_bus}"
out=build/fuzz
srcs=(src/*.c board/boards.c hal/host/hal_host.c hal/host/flash_sim.c hal/host/motor_sim.c
      hal/host/image_host.c)
defs=(-DREGS_WITH_TEXT=1 -DSERVO_FW_VERSION=1 -Iinclude -Ihal -Ihal/host)
san=(-fsanitize=address,undefined -fno-sanitize-recover=all)

# Per target: longest input, time-out per input (s).
max_len() {
    case $1 in
    fuzz_bus) echo 10000 ;; fuzz_update) echo 1024 ;; fuzz_planner) echo 256 ;; *) echo 512 ;;
    esac
}
unit_timeout() { [ "$1" = fuzz_bus ] && echo 20 || echo 5; }

# Objects: built once, shared by the targets. Under libFuzzer, code that only loops over
# tables and bits (the register table, the store's scans, the CRCs, the host HAL) is not
# traced at each comparison: that doubles the speed and gives the fuzzer nothing it needs.
compile_fuzz() {
    local src=$1 obj=$2 cov=(-fsanitize=fuzzer-no-link)
    case $src in
    src/regs.c | src/store.c | src/crc.c | hal/* | board/*)
        cov+=(-fno-sanitize-coverage=trace-cmp) ;;
    src/planner.c) # no overflow at all: unsigned wrap and lossy implicit conversions too
        cov+=(-fsanitize=unsigned-integer-overflow,implicit-conversion) ;;
    esac
    clang -std=c11 -g -O2 "${san[@]}" "${cov[@]}" -DFUZZ_LIBFUZZER "${defs[@]}" -c "$src" -o "$obj"
}
compile_cov() {
    clang -std=c11 -O0 -fprofile-instr-generate -fcoverage-mapping "${defs[@]}" -c "$1" -o "$2"
}
export -f compile_fuzz compile_cov
export san_s="${san[*]}" defs_s="${defs[*]}"

build() {
    mkdir -p "$out/obj" "$out/cov-obj" "$out/bin"
    # xargs runs the compilers in parallel; the functions rebuild their arrays.
    printf '%s\n' "${srcs[@]}" | xargs -P "$jobs" -I{} bash -c \
        'san=($san_s); defs=($defs_s); s={}; o=$(echo "$s" | tr / _); o=${o%.c}.o;
         compile_fuzz "$s" '"$out"'/obj/$o && compile_cov "$s" '"$out"'/cov-obj/$o'
    for t in "${targets[@]}"; do
        clang -std=c11 -g -O2 "${san[@]}" -fsanitize=fuzzer -DFUZZ_LIBFUZZER "${defs[@]}" \
            "$out"/obj/*.o "tests/fuzz/$t.c" -lm -o "$out/bin/$t" &
        clang -std=c11 -O0 -fprofile-instr-generate -fcoverage-mapping "${defs[@]}" \
            "$out"/cov-obj/*.o "tests/fuzz/$t.c" tests/fuzz/replay_main.c -lm \
            -o "$out/bin/$t.cov" &
    done
    wait
}

# The progress line of a running target: executions and exec/s from the harness's
# fuzz-progress line (fuzz.h), coverage and corpus from libFuzzer's last status line.
progress_line() {
    local t=$1 log=$out/$1/log line runs secs cpu cov corp
    line=$(grep -a '^fuzz-progress:' "$log" 2>/dev/null | tail -1 || true)
    read -r _ runs _ _ secs _ _ cpu _ <<< "$line" || true
    line=$(grep -aE '^#[0-9]+[[:space:]]' "$log" 2>/dev/null | tail -1 || true)
    cov=$(grep -oE 'cov: [0-9]+' <<< "$line" | awk '{print $2}' || true)
    corp=$(grep -oE 'corp: [0-9]+' <<< "$line" | awk '{print $2}' || true)
    if [ -z "${runs:-}" ]; then # before the harness's first line: libFuzzer's count
        runs=$(grep -oE '^#[0-9]+' <<< "$line" | tr -d '#' || true)
        secs=0 cpu=0
    fi
    printf '  %-13s %11s executions, %7s exec/s (%7s per CPU s), coverage %5s edges, corpus %6s\n' \
        "$t" "${runs:-0}" "$(( ${secs:-0} > 0 ? ${runs:-0} / secs : 0 ))" \
        "$(( ${cpu:-0} > 0 ? ${runs:-0} * 1000 / cpu : 0 ))" "${cov:-?}" "${corp:-?}"
}

run_target() {
    local t=$1 dir=$out/$1
    mkdir -p "$dir/corpus" "$dir/findings" "tests/fuzz/corpus/$t"
    local rc=0
    nice -n "${FUZZ_NICE:-0}" "$out/bin/$t" -max_total_time="$seconds" \
        -max_len="$(max_len "$t")" -timeout="$(unit_timeout "$t")" -rss_limit_mb=2048 \
        -print_final_stats=1 -artifact_prefix="$dir/findings/" \
        "$dir/corpus" "tests/fuzz/corpus/$t" > "$dir/log" 2>&1 || rc=$?
    echo "$rc" > "$dir/rc"
}

merge() {
    [ $# -gt 0 ] || set -- "${targets[@]}"
    for t in "$@"; do
        local new=$out/$t/merged
        rm -rf "$new"
        mkdir -p "$new" "$out/$t/corpus"
        "$out/bin/$t" -merge=1 -max_len="$(max_len "$t")" -timeout="$(unit_timeout "$t")" \
            -rss_limit_mb=2048 "$new" "tests/fuzz/corpus/$t" "$out/$t/corpus" \
            > "$out/$t/merge.log" 2>&1
        rm -rf "tests/fuzz/corpus/$t"
        mv "$new" "tests/fuzz/corpus/$t"
        echo "merge $t: $(ls "tests/fuzz/corpus/$t" | wc -l) inputs," \
             "$(du -sk "tests/fuzz/corpus/$t" | cut -f1) KiB"
    done
}

# Coverage of src/ by every corpus: the checked-in one, what the runs added, and the past
# findings; each target's coverage build replays them once.
coverage() {
    echo "== coverage of src/ by the merged corpora (llvm-cov)"
    rm -f "$out"/cov-*.profraw
    local objs=() t dirs
    for t in "${targets[@]}"; do
        dirs=("tests/fuzz/corpus/$t")
        [ -d "$out/$t/corpus" ] && dirs+=("$out/$t/corpus")
        [ -d "tests/fuzz/findings/$t" ] && dirs+=("tests/fuzz/findings/$t")
        LLVM_PROFILE_FILE="$out/cov-$t.profraw" "$out/bin/$t.cov" "${dirs[@]}" > /dev/null 2>&1 ||
            echo "  $t: the coverage replay failed (its profile is missing)" >&2
        objs+=(-object "$out/bin/$t.cov")
    done
    llvm-profdata-14 merge -sparse "$out"/cov-*.profraw -o "$out/cov.profdata"
    llvm-cov-14 report "${objs[@]:1}" -instr-profile="$out/cov.profdata" src/*.c > "$out/cov.txt"
    awk '$1 ~ /\.c$/ { printf "  %-16s lines %7s  branches %7s\n", $1, $10, $13 }' "$out/cov.txt"
    # What stays uncovered, line by line, for docs/hardening.md.
    llvm-cov-14 show "${objs[@]:1}" -instr-profile="$out/cov.profdata" -show-branches=count \
        src/*.c > "$out/cov-show.txt" 2>/dev/null || true
}

case ${1:-run} in
build) build; exit 0 ;;
coverage) build; coverage
    awk '$1 == "TOTAL" { printf "coverage src/: lines %s branches %s\n", $10, $13 }' "$out/cov.txt"
    exit 0 ;;
merge) shift; build; merge "$@"; exit 0 ;;
run) ;;
*) echo "usage: $0 [build | coverage | merge [TARGET...]]" >&2; exit 2 ;;
esac

echo "== building ${#targets[@]} fuzz targets (clang, libFuzzer, ASan, UBSan)"
build
echo "== libFuzzer: ${seconds} s per target, ${jobs} at a time: ${targets[*]}"
for t in "${targets[@]}"; do rm -f "$out/$t/rc" "$out/$t/log"; done
running=()
monitor() {
    while sleep "$progress"; do
        for t in "${targets[@]}"; do
            [ -f "$out/$t/log" ] && [ ! -f "$out/$t/rc" ] && progress_line "$t"
        done
    done
}
monitor &
mon=$!
trap 'kill $mon 2>/dev/null || true' EXIT
for t in "${targets[@]}"; do
    while [ "$(jobs -rp | grep -vc "^$mon\$")" -ge "$jobs" ]; do wait -n || true; done
    run_target "$t" &
done
while [ "$(jobs -rp | grep -vc "^$mon\$")" -gt 0 ]; do wait -n || true; done
kill $mon 2>/dev/null || true

coverage
# Findings first (on stderr), then the summary: one line per target, the coverage line.
found_any=0
summary=()
for t in "${targets[@]}"; do
    log=$out/$t/log
    runs=$(awk '/stat::number_of_executed_units/ {print $NF}' "$log")
    speed=$(awk '/stat::average_exec_per_sec/ {print $NF}' "$log")
    found=$(find "$out/$t/findings" -type f \( -name 'crash-*' -o -name 'leak-*' \
            -o -name 'timeout-*' -o -name 'oom-*' \) | wc -l)
    if [ "$(cat "$out/$t/rc")" != 0 ] && [ "$found" -eq 0 ]; then found=1; fi
    if [ "$found" -ne 0 ]; then
        found_any=1
        echo "  $t: FINDINGS in $out/$t/findings/ (log: $log)" >&2
        grep -a -A12 -m1 -E 'ERROR|invariant failed' "$log" >&2 || true
    fi
    summary+=("fuzz $t: ${runs:-0} executions in ${seconds} s (${speed:-0} exec/s), findings: $found")
done
printf '%s\n' "${summary[@]}"
awk '$1 == "TOTAL" { printf "coverage src/: lines %s branches %s\n", $10, $13 }' "$out/cov.txt"
exit "$found_any"
