#!/usr/bin/env python3
"""CTest boards.list (issue 28, "a new variant in one place"): the one board list,
cmake/boards.cmake, and everything that goes over every board agree.

- include/board_list.h is what `tools/boards.py header` generates from the list (C code:
  board_all, BOARD_COUNT, and through them every per-board test and fuzzer);
- the boards with a folder (board/<name>/board.c) are exactly the list, each folder has
  board.c, board_pins.h and board.cmake, and board.c defines board_<name> named "<name>"
  with `.photo_switches = BOARD_PHOTO`: the core's fact comes from the port's header, so
  the two cannot disagree (and board/README.md's photo column says the same);
- no other file defines a struct board, and no C, Python or shell file keeps a hand copy
  of the list (every board, in the list's order, as names or board_<name>);
- include/board.h has the model number BOARD_MODEL_<NAME> of each;
- no C file walks the boards by variant: board_all indexed by a VARIANT_ value or by a
  loop bounded by VARIANT_COUNT, or per-board state kept in a [VARIANT_COUNT] array by
  `->variant` (a board is not a variant: a sixth board of an existing variant would be
  skipped, or run on its twin's snapshot);
- `make boards` (the Makefile's BOARDS, make firmware's boards) and tools/fuzz_seeds.py's
  BOARDS are the list; board/README.md's table has one row per board.

--self-test first runs the check on copies of those files: with a sixth board added to
the list only, with its folder only, and with its folder and the list but not `make
docs`, or everywhere but a test's own copy of the list, or a test that walks the boards by
VARIANT_COUNT or keeps their state by variant, it must fail; added everywhere
the recipe says, it must pass."""

import os
import re
import shutil
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(ROOT, "tools"))
import boards  # noqa: E402

SCANNED = ("src", "include", "hal", "tools", "tests", "board")
SKIP_DIRS = {"corpus", "findings", "replay", "__pycache__", "node_modules"}


def read(root, rel):
    with open(os.path.join(root, rel), encoding="utf-8") as fh:
        return fh.read()


def hand_list(names):
    """The whole list in its order, as C addresses (&board_base, &board_foot, ...) or as
    quoted names: a copy that a new board would not reach. (A bus of chosen boards in
    some other order is a test's choice, not a copy.)"""
    sep = r"(?:\s*:\s*\w+)?[\s,]+"  # a list, or a dict of each board's value
    lists = [names, names[:-1]]  # and a copy made before the newest board was added
    alts = []
    for lst in lists:
        alts.append(sep.join(r"&?board_%s\b" % re.escape(n) for n in lst))
        alts.append(sep.join(r"[\"']%s[\"']" % re.escape(n) for n in lst))
    return re.compile("|".join(alts))


def check(root):
    findings = []
    names = boards.names(root)
    if len(set(names)) != len(names):
        findings.append("cmake/boards.cmake: a board is listed twice")
    if read(root, "include/board_list.h") != boards.header(root):
        findings.append("include/board_list.h is not what `tools/boards.py header` makes of "
                        "cmake/boards.cmake: run `make docs`")
    folders = sorted(d for d in os.listdir(os.path.join(root, "board"))
                     if os.path.isdir(os.path.join(root, "board", d)))
    for d in folders:
        if d not in names:
            findings.append("board/%s/ is a board folder but not in cmake/boards.cmake" % d)
    board_h = read(root, "include/board.h")
    readme = read(root, "board/README.md")
    rows = dict(re.findall(r"^\| (\w+) \| 0x[0-9A-Fa-f]{4} \|(.*)$", readme, re.M))
    for n in names:
        for f in ("board.c", "board_pins.h", "board.cmake"):
            if not os.path.exists(os.path.join(root, "board", n, f)):
                findings.append("board/%s/%s is missing (cmake/boards.cmake lists %s)" %
                                (n, f, n))
        if not os.path.exists(os.path.join(root, "board", n, "board.c")):
            continue
        c = read(root, "board/%s/board.c" % n)
        if not re.search(r"const struct board board_%s\s*=" % n, c):
            findings.append("board/%s/board.c does not define board_%s" % (n, n))
        if '.name = "%s"' % n not in c:
            findings.append('board/%s/board.c: .name is not "%s"' % (n, n))
        if not re.search(r"\.photo_switches\s*=\s*BOARD_PHOTO\b", c):
            findings.append("board/%s/board.c: .photo_switches must be BOARD_PHOTO (its "
                            "board_pins.h), not a second copy" % n)
        if not re.search(r"#define BOARD_MODEL_%s\b" % n.upper(), board_h):
            findings.append("include/board.h: no BOARD_MODEL_%s" % n.upper())
        if n not in rows:
            findings.append("board/README.md: no row for %s in the board table" % n)
        else:
            pins = read(root, "board/%s/board_pins.h" % n)
            m = re.search(r"#define BOARD_PHOTO (\d)", pins)
            photo_doc = rows[n].split("|")[1].strip() not in ("–", "-", "")
            if m and photo_doc != (m.group(1) == "1"):
                findings.append("board/README.md: %s's photo switches disagree with its "
                                "board_pins.h" % n)
    for r in rows:
        if r not in names:
            findings.append("board/README.md: a row for %s, which is not a board" % r)
    make = subprocess.run(["make", "-s", "--no-print-directory", "-C", root, "boards"],
                          capture_output=True, text=True)
    if make.stdout.split() != names:
        findings.append("Makefile: BOARDS is %r, not the list" % make.stdout.strip())
    seeds = subprocess.run([sys.executable, "-c", "import fuzz_seeds; print(' '.join("
                            "fuzz_seeds.BOARDS))"], cwd=os.path.join(root, "tools"),
                           capture_output=True, text=True)
    if seeds.stdout.split() != names:
        findings.append("tools/fuzz_seeds.py: BOARDS is %r, not the list" %
                        (seeds.stdout.strip() or seeds.stderr.strip()))
    pattern = hand_list(names)
    by_variant = re.compile(r"board_all\[[^\]]*VARIANT_")
    loop = re.compile(r"for\s*\([^;]*;\s*(\w+)\s*<\s*VARIANT_COUNT\s*;")
    state = re.compile(r"\w+\[VARIANT_COUNT\](?:\[\w+\])?\s*;")
    struct = re.compile(r"^\s*const struct board board_\w+\s*=", re.M)
    for top in SCANNED:
        for dirpath, dirs, files in os.walk(os.path.join(root, top)):
            dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
            for f in files:
                if not f.endswith((".c", ".h", ".py", ".sh", ".cmake", ".txt")):
                    continue
                path = os.path.join(dirpath, f)
                rel = os.path.relpath(path, root).replace(os.sep, "/")
                text = read(root, rel)
                if rel not in ("tools/boards.py", "tests/boards_check.py",
                               "include/board_list.h") and \
                        pattern.search(text):
                    findings.append("%s: a hand copy of the board list (use board_all and "
                                    "BOARD_COUNT, or tools/boards.py)" % rel)
                if f.endswith(".c") and (by_variant.search(text) or any(
                        re.search(r"board_all\[\s*%s\s*\]" % v, text)
                        for v in loop.findall(text))):
                    findings.append("%s: walks the boards by VARIANT_COUNT (use BOARD_COUNT: "
                                    "a board is not a variant)" % rel)
                if f.endswith(".c") and state.search(text) and "->variant]" in text:
                    findings.append("%s: keeps per-board state by variant ([VARIANT_COUNT] "
                                    "indexed by ->variant; use the board's index)" % rel)
                if struct.search(text) and not re.fullmatch(r"board/\w+/board\.c", rel):
                    findings.append("%s defines a struct board outside board/<name>/board.c"
                                    % rel)
    return findings


def sixth(root, list_it=True, folder=True, docs=True, stale_copy=False, planted=None,
          stale_dict=False):
    """A copy of the files the check reads, with a sixth board added where asked."""
    tmp = tempfile.mkdtemp(prefix="boards_check.")
    for rel in ("cmake/boards.cmake", "include/board_list.h", "include/board.h",
                "Makefile", "board/README.md", "tools/boards.py", "tools/fuzz_seeds.py"):
        os.makedirs(os.path.dirname(os.path.join(tmp, rel)), exist_ok=True)
        shutil.copy(os.path.join(root, rel), os.path.join(tmp, rel))
    for n in boards.names(root):
        shutil.copytree(os.path.join(root, "board", n), os.path.join(tmp, "board", n))
    if list_it:
        p = os.path.join(tmp, "cmake/boards.cmake")
        text = read(tmp, "cmake/boards.cmake").replace("set(SERVO_BOARDS ", "set(SERVO_BOARDS ")
        text = re.sub(r"(set\(SERVO_BOARDS [^)]*)\)", r"\1 thumb)", text)
        with open(p, "w", encoding="utf-8") as fh:
            fh.write(text)
    if folder:
        shutil.copytree(os.path.join(root, "board", "arm"), os.path.join(tmp, "board", "thumb"))
        c = read(tmp, "board/thumb/board.c").replace("board_arm", "board_thumb")
        c = c.replace('"arm"', '"thumb"').replace("BOARD_MODEL_ARM", "BOARD_MODEL_THUMB")
        with open(os.path.join(tmp, "board/thumb/board.c"), "w", encoding="utf-8") as fh:
            fh.write(c)
        h = read(tmp, "include/board.h").replace(
            "#define BOARD_MODEL_FINGER", "#define BOARD_MODEL_THUMB 0x5206u\n"
            "#define BOARD_MODEL_FINGER")
        with open(os.path.join(tmp, "include/board.h"), "w", encoding="utf-8") as fh:
            fh.write(h)
        r = read(tmp, "board/README.md")
        r = re.sub(r"^(\| finger \| .*)$", r"\1\n| thumb | 0x5206 | encoder, TIM2 | PB12, PB13 "
                   r"| 5.5 A |", r, count=1, flags=re.M)
        with open(os.path.join(tmp, "board/README.md"), "w", encoding="utf-8") as fh:
            fh.write(r)
    if stale_copy:  # a test that kept its own list of the five
        os.makedirs(os.path.join(tmp, "tests"), exist_ok=True)
        with open(os.path.join(tmp, "tests", "test_x.c"), "w", encoding="utf-8") as fh:
            fh.write("static const struct board *const b[] = {%s};\n" % ", ".join(
                "&board_%s" % n for n in boards.names(root)))
    if stale_dict:  # a tool's own board -> model number map (as image.py's MODELS was)
        os.makedirs(os.path.join(tmp, "tools"), exist_ok=True)
        with open(os.path.join(tmp, "tools", "x.py"), "w", encoding="utf-8") as fh:
            fh.write("MODELS = {%s}\n" % ", ".join(
                '"%s": 0x%04X' % (n, 0x5201 + i) for i, n in enumerate(boards.names(root))))
    if planted:  # a test of its own that goes over the boards by variant
        os.makedirs(os.path.join(tmp, "tests"), exist_ok=True)
        with open(os.path.join(tmp, "tests", "test_y.c"), "w", encoding="utf-8") as fh:
            fh.write(planted)
    if docs and list_it:
        with open(os.path.join(tmp, "include/board_list.h"), "w", encoding="utf-8") as fh:
            fh.write(boards.header(tmp))
    return tmp


def self_test(root):
    failed = 0
    cases = [("the list only", dict(folder=False), True),
             ("its folder only", dict(list_it=False), True),
             ("folder and list, no make docs", dict(docs=False), True),
             ("everywhere but a test's own list", dict(stale_copy=True), True),
             ("everywhere but a tool's map of the boards", dict(stale_dict=True), True),
             ("everywhere, but a test walks VARIANT_COUNT", dict(planted=(
                 "for (unsigned v = 0; v < VARIANT_COUNT; v++)\n    run(board_all[v]);\n")),
              True),
             ("everywhere, but a test picks board_all[VARIANT_ARM]", dict(
                 planted="run(board_all[VARIANT_ARM]);\n"), True),
             ("everywhere, but a test keeps a snapshot per variant", dict(planted=(
                 "static struct servo snap[VARIANT_COUNT];\n"
                 "void keep(const struct board *b) { snap[b->variant] = s; }\n")), True),
             ("everywhere the recipe says", {}, False)]
    for what, how, must_fail in cases:
        tmp = sixth(root, **how)
        try:
            found = check(tmp)
        finally:
            shutil.rmtree(tmp)
        if bool(found) != must_fail:
            print("self-test: a sixth board added to %s: %s" % (
                what, "not found" if must_fail else "reported %s" % found))
            failed += 1
    return failed


def main(argv):
    if "--self-test" in argv and self_test(ROOT):
        return 1
    findings = check(ROOT)
    for f in findings:
        print(f)
    print("boards.list: %d finding(s); boards: %s" % (len(findings),
                                                     " ".join(boards.names(ROOT))))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
