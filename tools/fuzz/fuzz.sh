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
#                                    runs found (build/fuzz/T/corpus/; for fuzz_bus also the
#                                    replay transcripts' seeds, tools/fuzz_seeds.py) with
#                                    -merge=1, and replace the checked-in corpus with it
set -euo pipefail
cd "$(dirname "$0")/../.."
seconds=${FUZZ_SECONDS:-600}
jobs=${FUZZ_JOBS:-$(nproc 2>/dev/null || echo 2)}
progress=${PROGRESS_SECONDS:-10}
read -r -a targets <<< "${FUZZ_TARGETS:-fuzz_frame fuzz_store fuzz_update fuzz_planner fuzz_bus}"
out=build/fuzz
srcs=(src/*.c board/boards.c board/*/board.c hal/host/hal_host.c hal/host/flash_sim.c hal/host/motor_sim.c
      hal/host/image_host.c hal/host/image_build.c hal/host/power_on.c)
defs=(-DREGS_WITH_TEXT=1 -DSERVO_FW_VERSION=1 -Iinclude -Ihal -Ihal/host)
# UBSan without the checks ASan makes already (null, object-size) and without
# pointer-overflow (pointer wrap-around, on every pointer step of the byte loops): a
# fifth of the executions for nothing ASan does not catch. Alignment stays: the
# Cortex-M3 faults on unaligned LDRD/LDM.
san=(-fsanitize=address,undefined -fno-sanitize=pointer-overflow,null,object-size
     -fno-sanitize-recover=all)

# Per target: longest input, time-out per input (s).
max_len() {
    case $1 in
    fuzz_bus) echo 10000 ;; fuzz_update) echo 1024 ;; fuzz_planner) echo 256 ;; *) echo 512 ;;
    esac
}
unit_timeout() { [ "$1" = fuzz_bus ] && echo 20 || echo 5; }

# What each target links, source by source: full (edges and comparison tracing), edges
# (edges only) or none (sanitizers, no coverage instrumentation). A target traces fully
# what it attacks. Code it runs hot that another target attacks gets edges only: the
# receiver's byte loop under fuzz_update's 1 KiB data blocks (fuzz_frame attacks the
# receiver), the boot record's page scan after each power-up of fuzz_frame (fuzz_update
# attacks boot.c), and the main loop's and the link's comparisons of virtual times, which
# the inputs set only through gaps. Code a target only passes through gets none (the
# motion layers under fuzz_update's main loop; all but the store under fuzz_store, all
# but the planner under fuzz_planner): libFuzzer scans every counter after every
# execution, so counters it never needs cost each execution too. The coverage figures
# come from separate builds (compile_cov), which none of this touches.
motion_srcs=" src/motion.c src/control.c src/homing.c src/sequence.c src/planner.c src/traj.c
             src/scale.c src/present.c src/command.c src/safety.c "
tier() { # target source
    case $1:$2 in
    fuzz_store:src/store.c | fuzz_store:src/regs.c | fuzz_store:src/loader.c) echo edges ;;
    fuzz_store:*) echo none ;;
    fuzz_planner:src/planner.c) echo full ;;
    fuzz_planner:*) echo none ;;
    *:src/regs.c | *:src/store.c | *:hal/* | *:board/*) echo edges ;;
    fuzz_update:src/frame_rx.c | fuzz_update:src/proto.c | fuzz_update:src/servo.c | \
    fuzz_update:src/link.c | fuzz_frame:src/boot.c | fuzz_frame:src/servo.c | \
    fuzz_frame:src/link.c)
        echo edges ;;
    fuzz_update:*)
        case $motion_srcs in *[[:space:]]$2[[:space:]]*) echo none ;; *) echo full ;; esac ;;
    *) echo full ;;
    esac
}

# Objects: built once in each form, shared by the targets. The register table, the
# store's scans and the host HAL only loop over tables and bits: no target traces their
# comparisons (tier above).
compile_fuzz() { # source object full|edges|none
    local src=$1 obj=$2 cov=()
    case $3 in
    full) cov=(-fsanitize=fuzzer-no-link) ;;
    edges) cov=(-fsanitize=fuzzer-no-link -fno-sanitize-coverage=trace-cmp) ;;
    esac
    case $src in
    src/crc.c) # table lookups with masked indexes over the caller's buffer, whose bounds
        # the callers' own checks and the harnesses' independent CRCs cover: plain, as the
        # sanitizers made it cost 40 instructions a byte (a 26 KiB image at every boot)
        clang -std=c11 -g -O2 -DFUZZ_LIBFUZZER "${defs[@]}" -c "$src" -o "$obj"
        return ;;
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

obj_of() { local o; o=$(tr / _ <<< "$1"); echo "${o%.c}.o"; }

build() {
    mkdir -p "$out/obj-full" "$out/obj-edges" "$out/obj-none" "$out/cov-obj" "$out/bin"
    # xargs runs the compilers in parallel; the functions rebuild their arrays.
    printf '%s\n' "${srcs[@]}" | xargs -P "$jobs" -I{} bash -c \
        'san=($san_s); defs=($defs_s); s={}; o=$(echo "$s" | tr / _); o=${o%.c}.o;
         for k in full edges none; do compile_fuzz "$s" '"$out"'/obj-$k/$o $k || exit 1; done
         compile_cov "$s" '"$out"'/cov-obj/$o'
    local t src objs
    for t in "${targets[@]}"; do
        objs=()
        for src in "${srcs[@]}"; do
            objs+=("$out/obj-$(tier "$t" "$src")/$(obj_of "$src")")
        done
        # The harness itself: edges only (its decoding of the input needs no more).
        clang -std=c11 -g -O2 "${san[@]}" -fsanitize=fuzzer -fno-sanitize-coverage=trace-cmp \
            -DFUZZ_LIBFUZZER "${defs[@]}" "${objs[@]}" "tests/fuzz/$t.c" -lm -o "$out/bin/$t" &
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
        local new=$out/$t/merged extra=()
        rm -rf "$new"
        mkdir -p "$new" "$out/$t/corpus"
        if [ "$t" = fuzz_bus ]; then # the replay transcripts as they are now (fuzz_seeds.py)
            rm -rf "$out/$t/seeds"
            mkdir -p "$out/$t/seeds"
            /usr/bin/python3 tools/fuzz_seeds.py tests/replay "$out/$t/seeds" > /dev/null
            extra=("$out/$t/seeds")
        fi
        "$out/bin/$t" -merge=1 -max_len="$(max_len "$t")" -timeout="$(unit_timeout "$t")" \
            -rss_limit_mb=2048 "$new" "tests/fuzz/corpus/$t" "$out/$t/corpus" "${extra[@]}" \
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
