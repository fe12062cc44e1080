#!/usr/bin/env python3
"""check_isr_ram.py - fail the build if code that must run while the flash is busy is not
all in RAM.

During a page erase every flash read stalls the CPU for up to 40 ms; the USART1 and
SysTick handlers (and the FPEC wait loop) run from RAM so no received byte is lost. The
linker script places them, and the core's receive path (frame_rx.c, servo_rx_isr), in
RAM by name; this check walks the disassembly from those roots through every direct
call or jump and fails if it reaches a function in flash, an indirect call, a long-branch
veneer (what the linker adds to reach flash from RAM), or a literal that points into
flash (a constant table the code would read). A change in the core that
makes the receive path call something new shows up here, not as lost bytes on a bench.

Usage: check_isr_ram.py image.elf  (arm-none-eabi-nm/objdump on the PATH)
"""
import bisect
import re
import subprocess
import sys

ROOTS = ("usart1_handler", "systick_handler", "fpec_run")
# The QEMU build's RAM flash (qemu_flash.c) has no FPEC to wait for: no fpec_run there.
OPTIONAL_ROOTS = ("fpec_run",)
RAM = (0x20000000, 0x20010000)
FLASH = (0x08000000, 0x08100000)


def run(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def main(elf):
    funcs = {}  # start address -> (name, size)
    for line in run("arm-none-eabi-nm", "-S", "--defined-only", elf).splitlines():
        parts = line.split()
        if len(parts) == 4 and parts[2] in "tTW":
            funcs[int(parts[0], 16) & ~1] = (parts[3], int(parts[1], 16))
    starts = sorted(funcs)
    # Linker-made veneers have no size: they run up to the next symbol.
    for i, a in enumerate(starts):
        if funcs[a][1] == 0 and i + 1 < len(starts):
            funcs[a] = (funcs[a][0], starts[i + 1] - a)
    by_name = {name: addr for addr, (name, _) in funcs.items()}

    def owner(addr):
        i = bisect.bisect_right(starts, addr) - 1
        if i >= 0 and addr < starts[i] + funcs[starts[i]][1]:
            return starts[i]
        return None

    # Per function: branch targets out of it, indirect calls, literals into flash.
    calls, problems = {}, {}
    asm = run("arm-none-eabi-objdump", "-D", "--no-show-raw-insn", "-j", ".data", "-j",
              ".text", elf)
    insn = re.compile(r"^\s*([0-9a-f]+):\s+(\S+)\s*(.*)$")
    for line in asm.splitlines():
        m = insn.match(line)
        if not m:
            continue
        addr, op, args = int(m.group(1), 16), m.group(2), m.group(3)
        f = owner(addr)
        if f is None:
            continue
        if re.fullmatch(r"(b|bl|b[a-z]{2})(\.[nw])?|cbn?z", op):
            t = re.search(r"\b([0-9a-f]+) <", args)
            if t:
                target = owner(int(t.group(1), 16))
                if target is None:
                    problems.setdefault(f, []).append(f"jumps to {t.group(1)} (no function)")
                elif target != f:
                    calls.setdefault(f, set()).add(target)
        elif op in ("blx", "bx") and not args.startswith("lr"):
            problems.setdefault(f, []).append(f"indirect {op} {args}")
        elif op.startswith("ldr") and args.startswith("pc,"):
            # A long-branch veneer: RAM code never needs one except to reach flash.
            problems.setdefault(f, []).append(f"long branch into flash ({op} {args})")
        elif op == ".word":
            w = re.match(r"0x([0-9a-f]+)", args)
            if w and FLASH[0] <= int(w.group(1), 16) < FLASH[1]:
                problems.setdefault(f, []).append(f"literal 0x{w.group(1)} points into flash")

    errors, seen = [], set()
    todo = []
    for root in ROOTS:
        if root not in by_name:
            if root not in OPTIONAL_ROOTS:
                errors.append(f"{root}: not in the image")
        else:
            todo.append((by_name[root], root))
    while todo:
        f, path = todo.pop()
        if f in seen:
            continue
        seen.add(f)
        name = funcs[f][0]
        if not RAM[0] <= f < RAM[1]:
            errors.append(f"{path}: {name} is in flash (0x{f:08x})")
            continue
        for p in problems.get(f, []):
            errors.append(f"{path}: {p}")
        for t in sorted(calls.get(f, ())):
            todo.append((t, f"{path} -> {funcs[t][0]}"))
    if errors:
        print(f"{elf}: code that runs during a flash erase is not all in RAM:", file=sys.stderr)
        for e in errors:
            print("  " + e, file=sys.stderr)
        return 1
    names = sorted(funcs[f][0] for f in seen)
    print(f"-- interrupt path in RAM ({len(names)} functions): {' '.join(names)}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1]))
