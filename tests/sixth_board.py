#!/usr/bin/env python3
"""sixth_board.py - a sixth board, added by following architecture.md's recipe, builds and
is covered by the per-board tests (issue 28).

In a scratch copy of the source tree (under the build directory given), as a developer
would: board/thumb/ copied from board/foot/ with its names changed, its model number in
include/board.h, its name in cmake/boards.cmake (the one list), its row in
board/README.md, then `tools/boards.py header` (what `make docs` runs) for
include/board_list.h. Then:
  1. tests/boards_check.py finds nothing in the copy (every list followed);
  2. the copy configures and builds the host tests that go over every board
     (test_regs, test_scale, test_loader, test_motion, and test_props in its short mode),
     which
  3. pass, and
  4. link board_thumb: board_all holds six boards (the binary carries the sixth's name
     and model);
  5. regdoc --json (what make docs writes to the SDK's registers.json) lists it among
     the boards, with its model number and its variant; written there, as make docs does,
  6. the firmware builds for it (the STM32 application, bootloader and combined image,
     within the size goals the build enforces), and the stamp names it: the SDK knows
     its model number.
Usage: sixth_board.py <scratch dir>. Exit 1 with the step that failed."""

import os
import re
import shutil
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
sys.path.insert(0, os.path.join(ROOT, "tests"))
import boards  # noqa: E402
import boards_check  # noqa: E402

NAME, MODEL = "thumb", "0x5206u"
TESTS = ("test_regs", "test_scale", "test_loader", "test_motion", "test_props")
ENV = dict(os.environ, PROPS_SEQUENCES="200")  # short.props' count


def edit(path, old, new, count=1):
    with open(path, encoding="utf-8") as fh:
        text = fh.read()
    if old not in text:
        raise SystemExit("sixth_board: %s has no %r" % (path, old))
    with open(path, "w", encoding="utf-8") as fh:
        fh.write(text.replace(old, new, count))


def add_board(src):
    """The recipe of docs/architecture.md ("A new board") on the copy at src."""
    folder = os.path.join(src, "board", NAME)
    shutil.copytree(os.path.join(src, "board", "foot"), folder)
    c = os.path.join(folder, "board.c")
    for old, new in (("board_foot", "board_" + NAME), ('"foot"', '"%s"' % NAME),
                     ("BOARD_MODEL_FOOT", "BOARD_MODEL_" + NAME.upper())):
        edit(c, old, new, -1)
    edit(os.path.join(src, "include", "board.h"), "#define BOARD_MODEL_FINGER",
         "#define BOARD_MODEL_%s %s\n#define BOARD_MODEL_FINGER" % (NAME.upper(), MODEL))
    cm = os.path.join(src, "cmake", "boards.cmake")
    with open(cm, encoding="utf-8") as fh:
        text = fh.read()
    with open(cm, "w", encoding="utf-8") as fh:
        fh.write(re.sub(r"(set\(SERVO_BOARDS [^)]*)\)", r"\1 %s)" % NAME, text, count=1))
    readme = os.path.join(src, "board", "README.md")
    with open(readme, encoding="utf-8") as fh:
        rows = fh.read()
    foot = re.search(r"^\| foot \|.*$", rows, flags=re.M)
    if not foot:
        raise SystemExit("sixth_board: board/README.md has no foot row")
    row = foot.group(0).replace("| foot |", "| %s |" % NAME, 1).replace("0x5202", MODEL[:-1])
    with open(readme, "w", encoding="utf-8") as fh:
        fh.write(rows.replace(foot.group(0), foot.group(0) + "\n" + row, 1))
    with open(os.path.join(src, "include", "board_list.h"), "w", encoding="utf-8") as fh:
        fh.write(boards.header(src))  # make docs


def run(step, cmd, **kw):
    r = subprocess.run(cmd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, **kw)
    if r.returncode:
        print(r.stdout[-3000:])
        raise SystemExit("sixth_board: %s failed (%s)" % (step, " ".join(cmd)))
    return r.stdout


def main(argv):
    if len(argv) != 2:
        raise SystemExit(__doc__)
    scratch = os.path.abspath(argv[1])
    src, build = os.path.join(scratch, "src"), os.path.join(scratch, "build")
    if os.path.isdir(src):
        shutil.rmtree(src)
    shutil.copytree(ROOT, src, ignore=shutil.ignore_patterns(
        ".git", "build", "corpus", "findings", "__pycache__"))
    add_board(src)
    found = boards_check.check(src)
    if found:
        print("\n".join(found))
        raise SystemExit("sixth_board: 1. the lists did not all follow")
    names = boards.names(src)
    assert names[-1] == NAME and len(names) == 6, names
    run("2. configure", ["cmake", "-S", src, "-B", build, "-G", "Unix Makefiles",
                         "-DCMAKE_BUILD_TYPE=Debug", "-DSERVO_SANITIZE=OFF"])
    run("2. build", ["cmake", "--build", build, "-j2", "--target", "regdoc"] + list(TESTS))
    for t in TESTS:
        exe = os.path.join(build, "tests", t)
        run("3. " + t, [exe], env=ENV)
        with open(exe, "rb") as fh:
            blob = fh.read()
        if b"\0" + NAME.encode() + b"\0" not in blob:
            raise SystemExit("sixth_board: 4. %s does not link board_%s" % (t, NAME))
    out = run("5. regdoc --json", [os.path.join(build, "tools", "regdoc"), "--json"])
    want = '{"name": "%s", "variant": "foot", "model_number": %d}' % (NAME, int(MODEL[:-1], 16))
    if want not in out:
        raise SystemExit("sixth_board: 5. regdoc --json does not list %s" % want)
    with open(os.path.join(src, "tools", "python", "servobus", "registers.json"), "w",
              encoding="ascii") as fh:
        fh.write(out)  # make docs
    fw = os.path.join(scratch, "stm32")
    run("6. configure the firmware", ["cmake", "-S", src, "-B", fw, "-G", "Unix Makefiles",
                                      "--toolchain", os.path.join(src, "cmake",
                                                                  "arm-none-eabi.cmake"),
                                      "-DBOARD=" + NAME, "-DCMAKE_BUILD_TYPE=MinSizeRel"])
    out = run("6. build the firmware", ["cmake", "--build", fw, "-j2"])
    stamp = "model 0x%04X (%s)" % (int(MODEL[:-1], 16), NAME)
    if stamp not in out or not os.path.isfile(os.path.join(fw, "servo-%s-full.bin" % NAME)):
        print(out[-2000:])
        raise SystemExit("sixth_board: 6. no servo-%s-full.bin stamped %s" % (NAME, stamp))
    print("sixth_board: board %s (from foot) listed everywhere, built, %s pass with "
          "board_all of %d boards; its firmware builds (%s)" % (
              NAME, ", ".join(TESTS), len(names), stamp))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
