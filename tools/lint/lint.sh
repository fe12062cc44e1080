#!/usr/bin/env bash
# make lint: static analysis with zero findings allowed (docs/lint.md).
#   0. module ownership (tools/lint/ownership.py: regs.mem written only by regs, a
#      servo's parts reached into only by their owners)
#   1. cppcheck (warning, style, performance, portability) on the core, both HALs, boards
#   2. cppcheck's MISRA C:2012 addon on the core (src/), deviations in tools/lint/misra.txt
#   3. clang-tidy (.clang-tidy) on src/ and hal/ through build/host/compile_commands.json
#   4. gcc -fanalyzer on the host build of src/ and hal/host/ (build/analyzer)
# Needs the host preset configured (make host). Exit status 1 on any finding.
set -uo pipefail
cd "$(dirname "$0")/../.."
jobs=${JOBS:-$(nproc 2>/dev/null || echo 2)}
out=build/lint
mkdir -p "$out"
fail=0
step() { printf '== %-50s' "$1"; }
verdict() { # $1 = log file; prints "ok" or the findings
    if [ -s "$1" ]; then echo "FINDINGS"; cat "$1"; fail=1; else echo "ok"; fi
}

step "ownership: module state (tools/lint/ownership.py)"
/usr/bin/python3 tools/lint/ownership.py . | grep -v '^ownership: 0 finding' > "$out/ownership.log"
verdict "$out/ownership.log"

common=(--quiet --std=c11 --inline-suppr --error-exitcode=0 -DSERVO_FW_VERSION=1
        --suppress=missingIncludeSystem
        --suppressions-list=tools/lint/cppcheck-suppress.txt)
step "cppcheck: src/ hal/host/ board/"
cppcheck "${common[@]}" --enable=warning,style,performance,portability \
    -Iinclude -Ihal -Ihal/host -DREGS_WITH_TEXT=1 src hal/host board/boards.c board/*/board.c \
    --template='{file}:{line}: {severity}: {message} [{id}]' 2>"$out/cppcheck.log"
verdict "$out/cppcheck.log"

step "cppcheck: hal/stm32f1/ (arm board)"
cppcheck "${common[@]}" --enable=warning,style,performance,portability \
    -Iinclude -Ihal -Ihal/stm32f1 -Iboard/arm -DSERVO_BOARD=board_arm -DSERVO_MODEL=BOARD_MODEL_ARM hal/stm32f1 \
    --template='{file}:{line}: {severity}: {message} [{id}]' 2>"$out/cppcheck-stm32.log"
verdict "$out/cppcheck-stm32.log"

step "cppcheck MISRA C:2012 addon: src/"
sup=()
while read -r rule; do
    case "$rule" in ''|'#'*) ;; *) sup+=("--suppress=$rule") ;; esac
done < tools/lint/misra.txt
cppcheck "${common[@]}" --addon=misra -Iinclude -Ihal "${sup[@]}" src \
    --template='{file}:{line}: {severity}: {message} [{id}]' 2>"$out/misra.log"
verdict "$out/misra.log"

step "clang-tidy: src/ hal/ (host compile_commands)"
[ -f build/host/compile_commands.json ] || { echo "run make host first" >&2; exit 1; }
/usr/bin/python3 - > "$out/tidy-files" <<'PY'
import json
for f in sorted({e["file"] for e in json.load(open("build/host/compile_commands.json"))}):
    if "/src/" in f or "/hal/" in f:
        print(f)
PY
xargs -a "$out/tidy-files" -P "$jobs" -n 1 clang-tidy -p build/host --quiet \
    --use-color=false >"$out/tidy.out" 2>/dev/null
grep -E ': (warning|error):' "$out/tidy.out" > "$out/tidy.log"
verdict "$out/tidy.log"

step "gcc -fanalyzer: src/ hal/host/ (build/analyzer)"
if [ ! -f build/analyzer/CMakeCache.txt ]; then
    cmake -S . -B build/analyzer -DCMAKE_BUILD_TYPE=Debug -DSERVO_SANITIZE=OFF \
        -DCMAKE_C_FLAGS=-fanalyzer >/dev/null || exit 1
fi
cmake --build build/analyzer -j "$jobs" --target servo_bus servo_motion hal_host vbus wire \
    -- --no-print-directory >"$out/analyzer.out" 2>&1 || fail=1
grep -E 'warning:|error:' "$out/analyzer.out" > "$out/analyzer.log"
verdict "$out/analyzer.log"

[ $fail -eq 0 ] && echo "lint: zero findings" || echo "lint: FAILED (logs in $out/)" >&2
exit $fail
