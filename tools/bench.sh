#!/usr/bin/env bash
# make bench: instructions per received byte and per dispatched instruction (callgrind,
# counting only inside the function under test, on the optimised host build), reply
# latency in virtual time, and the size of the Cortex-M3 image.
set -euo pipefail
build=${1:-build/bench}
bench=$build/tools/bench
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT

# Instructions executed inside function $2 while running `bench $1 $3`, divided by $3.
per_call() {
    valgrind --tool=callgrind --toggle-collect="$2" --callgrind-out-file="$out/cg" \
        "$bench" "$1" "$3" >/dev/null 2>&1
    local total
    total=$(awk '/^summary:/ {print $2}' "$out/cg")
    awk -v t="$total" -v n="$3" 'BEGIN { printf "%.1f", t / n }'
}

echo "== receive path (UART ISR -> frame_rx_byte), host x86-64 instructions, -O2"
echo "instructions per received byte: $(per_call rx frame_rx_byte 100000)   (target <= 60)"
echo
echo "== dispatch (main loop -> dispatch_frame), instructions per frame"
for w in read write sync; do
    n=$(per_call "$w" dispatch_frame 10000)
    printf '%-6s %6s   (~%s us on a 72 MHz Cortex-M3 at 1.5 cycles per instruction)\n' "$w" "$n" \
        "$(awk -v n="$n" 'BEGIN { printf "%.1f", n * 1.5 / 72 }')"
done
echo "(read = READ of 6 bytes, write = WRITE of goal + speed, sync = SYNC WRITE to 8 servos)"
echo
echo "== reply latency with return delay 0 (virtual time; the host build runs the"
echo "   dispatch in zero virtual time, so this is scheduling latency)"
"$bench" latency
echo
if [ -f build/stm32/servo-arm.elf ]; then
    echo "== Cortex-M3 arm image (build/stm32), bytes"
    arm-none-eabi-size build/stm32/servo-arm.elf
    for fn in frame_rx_byte dispatch_frame; do
        hex=$(arm-none-eabi-nm -S build/stm32/servo-arm.elf | awk -v f="$fn" '$4==f {print $2}')
        [ -n "$hex" ] && echo "$fn: $((16#$hex)) bytes of Thumb-2 code"
    done
fi
echo
if [ -f build/qemu/servo-qemu.elf ]; then
    echo "== on target: the arm image under QEMU (build/qemu; hal/stm32f1/qemu_cost.py),"
    echo "   Cortex-M3 instructions counted by single-stepping (~1 min)"
    timeout 300 /usr/bin/python3 hal/stm32f1/qemu_cost.py build/qemu/servo-qemu.elf ||
        echo "!! on-target figures: over budget (100 per byte, 3,600 per tick) or QEMU failed"
    echo
fi
if ls build/stm32-*/servo-*.stack >/dev/null 2>&1; then
    echo "== worst-case stack per entry point, STM32 images (make firmware; budget 75% of reserved)"
    for f in build/stm32-*/servo-*.stack; do
        basename "$f" .stack
        cat "$f"
    done
fi
echo
"$build/tools/bench_store"
echo
echo "== motion layer, host x86-64 instructions (callgrind; own ideal-motor HAL)"
for w in tick replan; do
    fn=motion_poll
    [ "$w" = replan ] && fn=command_written
    valgrind --tool=callgrind --toggle-collect="$fn" --callgrind-out-file="$out/cg" \
        "$build/tools/bench_motion" "$w" 20000 >/dev/null 2>&1
    awk -v w="$w" '/^summary:/ { printf "per %-7s %6.0f   (target %s)\n", w, $2 / 20000,
        w == "tick" ? "<= 1,500: planner + controller + registers" : "<= 8,000" }' "$out/cg"
done
echo
"$build/tools/motion_trace"
echo
"$build/tools/bench_safety"
/usr/bin/python3 tools/bench_sim.py "$build"
echo
# Issue 27 (tools/bench_ids.py): the coordinated start on a mixed bus (host nodes and
# two QEMU images), then a homing and the trajectory end skew (~40 s together), then 10,
# 50 and 253 factory-fresh servos enumerated and separated at 9600 and 921600 baud, in
# real time: about 7 min in all, the 253 runs 165 s (9600) and 110 s (921600) of it.
# IDS_BENCH_N=10,50 leaves 253 out.
/usr/bin/python3 tools/bench_ids.py "$build"
/usr/bin/python3 tools/bench_studio.py "$build"
echo
"$build/tests/corruption" 1000000
