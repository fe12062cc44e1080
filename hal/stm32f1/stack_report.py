#!/usr/bin/env python3
"""stack_report.py - worst-case stack of the firmware image, per entry point and in
total, against the stack the linker script reserves; fails the build if it does not fit.

Frame sizes come from GCC's -fstack-usage (.su files of the core and the port); library
functions without one (memcpy, the 64-bit division helpers) are sized from their code:
every push and stack-pointer decrement in them, added up. The call graph is the linked
image's own: every direct call and tail jump in the disassembly. An indirect call, recursion or a frame GCC calls "dynamic"
fails the check, since the bound would be unknown. One indirect branch is not a call: the
bootloader's hand-over to the application, `msr msp` (a new stack) right before `bx`.

Interrupts nest as the port sets them up: the main loop (reset_handler -> main), then
USART1 on top, SysTick above USART1, and a fault or NMI above everything; each exception
entry stacks 8 words plus 4 bytes of alignment.

The nested total must also stay within BUDGET_PCT (75 %) of the reserved stack, the margin
for what the analysis cannot see (compiler changes, a later HAL call on the path).

Usage: stack_report.py image.elf build_dir[:build_dir...] [report.txt]
(arm-none-eabi-nm/objdump on the PATH): the .su files are those under the build_dirs
(the image's own objects); report.txt gets the table printed, for `make firmware` and
`make bench`.
"""
import glob
import os
import re
import subprocess
import sys

ENTRIES = (  # (name, root function, exception entry?)
    ("main loop", "reset_handler", False),
    ("USART1 interrupt", "usart1_handler", True),
    ("SysTick", "systick_handler", True),
    ("fault / NMI", "fault_handler", True),
)
EXCEPTION_FRAME = 32 + 4
BUDGET_PCT = 75  # of the reserved stack, for the nested worst case


def run(*cmd):
    return subprocess.run(cmd, check=True, capture_output=True, text=True).stdout


def main(elf, build_dir, report=None):
    su = {}  # function name -> (bytes, qualifier); the largest if a name repeats
    paths = []
    for d in build_dir.split(":"):
        paths += glob.glob(os.path.join(d, "**", "*.su"), recursive=True)
    for path in paths:
        for line in open(path):
            where, size, kind = line.rstrip("\n").split("\t")
            name = where.rsplit(":", 1)[-1]
            if name not in su or int(size) > su[name][0]:
                su[name] = (int(size), kind)

    def su_of(name):
        """The .su entry of a function: under LTO, GCC's clones are named foo.constprop.0
        or foo.isra.0 in the image and foo.constprop or foo.isra in the .su file."""
        if name in su:
            return su[name]
        return su.get(re.sub(r"\.\d+$", "", name))

    funcs = {}  # address -> name
    syms = {}
    for line in run("arm-none-eabi-nm", "--defined-only", elf).splitlines():
        addr, kind, name = line.split()
        if kind in "tTW":
            funcs[int(addr, 16) & ~1] = name
            syms[name] = int(addr, 16) & ~1
        elif name in ("_stack_bottom", "_estack"):
            syms[name] = int(addr, 16)

    calls, frame, problems = {}, {}, {}
    cur, prev = None, ""
    asm = run("arm-none-eabi-objdump", "-D", "--no-show-raw-insn", "-j", ".data", "-j",
              ".text", elf)
    for line in asm.splitlines():
        head = re.match(r"^([0-9a-f]+) <(.+)>:$", line)
        if head:
            addr = int(head.group(1), 16)
            cur = funcs.get(addr)
            if cur:
                calls.setdefault(cur, set())
                frame.setdefault(cur, 0)
            continue
        m = re.match(r"^\s*[0-9a-f]+:\s+(\S+)\s*(.*)$", line)
        if not cur or not m:
            continue
        op, args = m.group(1), m.group(2)
        handover = re.match(r"msr\s+msp,", prev, re.I) is not None  # and this is bx
        prev = op + " " + args
        # Frame of a function GCC did not size (library code): every stack decrement in
        # its body, added up (an upper bound where exit paths repeat a push).
        if su_of(cur) is None:
            if op.startswith("push") or (op.startswith("stmdb") and args.startswith("sp!")):
                regs = re.search(r"\{(.*)\}", args)
                for r in regs.group(1).split(",") if regs else ():
                    span = re.match(r"\s*r(\d+)-r(\d+)", r)
                    n = int(span.group(2)) - int(span.group(1)) + 1 if span else 1
                    frame[cur] += 4 * n
            sub = re.match(r"sub(?:w|\.w)?\s+sp, (?:sp, )?#(\d+)", op + " " + args)
            if sub:
                frame[cur] += int(sub.group(1))
            elif re.match(r"(sub|mov)\S*\s+sp, (sp, )?r", op + " " + args):
                problems.setdefault(cur, []).append(f"stack pointer set from a register ({op} {args})")
            pre = re.search(r"\[sp, #-(\d+)\]!", args)
            if pre:
                frame[cur] += int(pre.group(1))
        if re.fullmatch(r"(b|bl|b[a-z]{2})(\.[nw])?", op):
            t = re.search(r"\b([0-9a-f]+) <([^+>]+)>", args)
            if t and t.group(2) != cur and t.group(2) in syms:
                calls[cur].add(t.group(2))
        elif op == "blx" or (op == "bx" and not args.startswith("lr") and not handover):
            problems.setdefault(cur, []).append(f"indirect call ({op} {args})")

    def own(name):
        if su_of(name) is not None:
            size, kind = su_of(name)
            if "dynamic" in kind and "bounded" not in kind:
                problems.setdefault(name, []).append("dynamic stack frame")
            return size
        return frame.get(name, 0)

    memo, errors = {}, []

    def worst(name, path):
        if name in path:
            errors.append("recursion: " + " -> ".join(path + (name,)))
            return 0, (name,)
        if name in memo:
            return memo[name]
        for p in problems.get(name, []):
            errors.append(f"{name}: {p}")
        best, chain = 0, ()
        for callee in sorted(calls.get(name, ())):
            depth, sub = worst(callee, path + (name,))
            if depth > best:
                best, chain = depth, sub
        memo[name] = (own(name) + best, (name,) + chain)
        return memo[name]

    total, lines = 0, []
    for label, root, exception in ENTRIES:
        if root not in syms:
            errors.append(f"{root} is not in the image")
            continue
        depth, chain = worst(root, ())
        depth += EXCEPTION_FRAME if exception else 0
        total += depth
        lines.append(f"   {label:17} {depth:5} B  {' > '.join(chain)}")
    reserved = syms["_estack"] - syms["_stack_bottom"]
    budget = reserved * BUDGET_PCT // 100
    head = (f"-- worst-case stack, nested: {total} of {reserved} B reserved "
            f"({100 * total / reserved:.0f}%; budget {BUDGET_PCT}% = {budget} B)")
    print(head)
    for line in lines:
        print(line)
    if report:
        with open(report, "w") as f:
            f.write("\n".join([head] + lines) + "\n")
    for e in errors:
        print(f"{elf}: stack bound unknown: {e}", file=sys.stderr)
    if errors:
        return 1
    if total > reserved:
        print(f"{elf}: worst-case stack {total} B exceeds the {reserved} B the linker "
              "script reserves (STACK_BYTES)", file=sys.stderr)
        return 1
    if total > budget:
        print(f"{elf}: worst-case stack {total} B exceeds {BUDGET_PCT}% of the {reserved} B "
              f"reserved ({budget} B)", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2], sys.argv[3] if len(sys.argv) > 3 else None))
