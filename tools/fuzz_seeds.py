#!/usr/bin/env python3
"""fuzz_seeds.py - the seed corpus of the bus fuzzer (tests/fuzz/fuzz_bus.c) from the
replay transcripts: one file per transcript, tests/fuzz/corpus/fuzz_bus/<name>.bin.

The first `servo` line gives the board (byte 0) and ID (byte 1); every `send` line's bytes
follow (CHK resolved as the replay runner does, FF escaped as FF FF), `+N` becomes an idle
gap, `expect`/`silence`/`wait` become a gap long enough for the answer, `power-cycle` a
reboot (FF FE). See the input format at the top of fuzz_bus.c.

Usage: tools/fuzz_seeds.py [tests/replay] [tests/fuzz/corpus/fuzz_bus]
"""
import math
import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import boards  # noqa: E402  (tools/boards.py: the one board list, cmake/boards.cmake)

BOARDS = boards.names()


def escape(data):
    return [b for x in data for b in ([0xFF, 0xFF] if x == 0xFF else [x])]


def gap(us):
    """FF g: idle for (g + 1)^2 x 10 us, g <= 0xFC (0.64 s; longer waits repeat it)."""
    out = []
    while us > 640_000:
        out += [0xFF, 0xFC]
        us -= 640_000
    g = max(0, min(0xFC, round(math.sqrt(max(us, 10) / 10)) - 1))
    return out + [0xFF, g]


def convert(path):
    head, body = None, []
    for raw in open(path):
        words = raw.split("#", 1)[0].split()
        if not words:
            continue
        op, args = words[0], words[1:]
        if op == "servo" and head is None:
            head = [BOARDS.index(args[1]), int(args[0]) & 0xFF]
        elif op == "send":
            line, emitted = [], 0  # the line's bytes (for CHK), how many are in body
            for w in args:
                if w.startswith("+"):
                    body += escape(line[emitted:]) + gap(int(w[1:]))
                    emitted = len(line)
                elif w.upper() == "CHK":
                    line.append(sum(line[2:]) & 0xFF if len(line) >= 3 else 0)
                else:
                    line.append(int(w, 16))
            body += escape(line[emitted:])
        elif op in ("expect", "silence", "wait"):
            us = int(args[0]) if op != "expect" and args else 30000
            body += gap(min(us, 3_000_000))
        elif op == "power-cycle":
            body += [0xFF, 0xFE]
    return bytes((head or [1, 0]) + body)


def main():
    src = sys.argv[1] if len(sys.argv) > 1 else "tests/replay"
    dst = sys.argv[2] if len(sys.argv) > 2 else "tests/fuzz/corpus/fuzz_bus"
    os.makedirs(dst, exist_ok=True)
    n = 0
    for name in sorted(os.listdir(src)):
        if name.endswith(".txt"):
            data = convert(os.path.join(src, name))
            with open(os.path.join(dst, name[:-4] + ".bin"), "wb") as f:
                f.write(data)
            n += 1
    print(f"fuzz_seeds: {n} seeds in {dst}")


if __name__ == "__main__":
    main()
