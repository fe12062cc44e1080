#!/usr/bin/env python3
"""CTest docs.paths (issue 28, "a map that is true"): every file the docs name exists, and
every test and function they name is still there.

Scans the project's Markdown (every *.md under the repository, build/ and the fuzz
corpora aside) for:
- file paths: a token starting with src/, include/, hal/, tests/, tools/, board/, docs/ or
  cmake/ (in backquotes, a link, or plain text), or a Markdown link to a relative file.
  `<name>` stands for any one path part, `*` and `?` are globs; a path with neither must
  exist as written, one with them must match at least one file;
- CTest names (`unit.store`, `replay.resync*`): must match a test that
  `ctest -N` lists in the build directory given as argument 1;
- links to a relative file, and to a heading's anchor in a Markdown file;
- file names (`store.c`, `qemu_cost.py`) in backquotes: some file of that name exists;
- functions (`store_sync()`, in backquotes with parentheses) and test cases (a backquoted
  snake_case name of four words or more: `a_trajectory_write_never_splices_the_running_one`):
  must be an identifier defined or used in the C, Python or JavaScript sources;
- include/write.h's list of who acts on which register (a comment, by hand) is what
  docs/registers.md's "Who acts on a register" (generated from the hooks, and held to
  them by docs.registers) says;
- every instruction rule (`INS_*` flag, include/dispatch.h) and ERR bit (`ERR_*`,
  include/proto.h) has its entry in tools/protocol_json.c, which names them for
  protocol.json (else a new one never reaches the SDK, and docs.protocol_json, comparing
  the JSON with what the generator prints, cannot see it);
- README.md's `make docs` row names every file the Makefile's `docs` target writes (a
  generated copy the row leaves out is one a reader does not know to regenerate).
Prints each finding as file:line and exits 1 on any; `--self-test` plants one of each
kind of false statement and checks that each is found."""

import fnmatch
import glob
import json
import os
import re
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
SKIP_DIRS = {"build", ".git", "corpus", "node_modules"}
TOPS = ("src", "include", "hal", "tests", "tools", "board", "docs", "cmake")
CTEST_PREFIXES = ("unit", "replay", "docs", "python", "lint", "qemu", "fuzz", "port", "sim",
                  "demo", "corruption", "boards", "short")
SOURCE_EXT = (".c", ".h", ".py", ".js")

PATH = re.compile(r"(?<![\w./-])((?:%s)/[\w.<>*?/+-]*[\w>*?])" % "|".join(TOPS))
LINK = re.compile(r"\]\(([^)#\s]*)(?:#([^)\s]*))?\)")
CTEST = re.compile(r"`((?:%s)\.[\w.*]+)`" % "|".join(CTEST_PREFIXES))
FILE_EXT = (".c", ".h", ".py", ".md", ".txt", ".json", ".cmake", ".ld", ".sh", ".js", ".html")
BARE = re.compile(r"`([\w-]+\.(?:%s))`" % "|".join(e[1:] for e in FILE_EXT))
PLACEHOLDER = re.compile(r"<[^>/]*>|\b[A-Z][A-Z0-9_]*[A-Z0-9]\b")
FUNC = re.compile(r"`([A-Za-z_]\w*)\([^`]*\)`")
CASE = re.compile(r"`([a-z][a-z0-9]*(?:_[a-z0-9]+)+)`")
IDENT = re.compile(r"[A-Za-z_]\w*")
# Names the docs cite that are not this project's: C11 Annex K (docs/lint.md).
FOREIGN = {"memcpy_s"}


def markdown_files(root):
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = sorted(d for d in dirs if d not in SKIP_DIRS)
        for f in sorted(files):
            if f.endswith(".md"):
                yield os.path.join(dirpath, f)


def source_identifiers(root):
    names = set()
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
        for f in files:
            path = os.path.join(dirpath, f)
            if os.path.abspath(path) == os.path.abspath(__file__):
                continue  # its self-test's planted names are not the sources'
            if f.endswith(SOURCE_EXT):
                with open(path, encoding="utf-8", errors="replace") as fh:
                    names.update(IDENT.findall(fh.read()))
    return names | FOREIGN


def ctest_names(build):
    out = subprocess.run([os.environ.get("CTEST", "ctest"), "-N"], cwd=build,
                         capture_output=True, text=True, check=True).stdout
    return set(re.findall(r"Test\s+#\d+: (\S+)", out))


def path_exists(root, path, here):
    """Relative to the repository, or to the folder of the doc that names it."""
    path = path.rstrip(".,;:")
    pattern = PLACEHOLDER.sub("*", path)
    for base in (root, os.path.join(root, here)):
        if pattern != path or "*" in path or "?" in path:
            if glob.glob(os.path.join(base, pattern)) or \
                    glob.glob(os.path.join(base, pattern + "*")):
                return True
        elif os.path.exists(os.path.join(base, path)):
            return True
    return False


def file_names(root):
    """Every file's name, and the Debian packages install-deps.sh installs (libjs-chart.js
    is a package, not a file of ours)."""
    with open(os.path.join(root, "tools", "install-deps.sh"), encoding="utf-8") as fh:
        names = set(re.findall(r"[\w.+-]+", fh.read()))
    for dirpath, dirs, files in os.walk(root):
        dirs[:] = [d for d in dirs if d not in SKIP_DIRS]
        names.update(files)
    return names


def anchors(path):
    """GitHub's anchors of a Markdown file's headings: lower case, punctuation but - and _
    dropped, spaces to -, a repeated heading numbered."""
    seen, out = {}, set()
    with open(path, encoding="utf-8") as fh:
        for line in fh:
            m = re.match(r"#+\s+(.*?)\s*$", line)
            if not m:
                continue
            slug = re.sub(r"[^\w\- ]", "", m.group(1).lower().replace("`", "")).replace(" ", "-")
            n = seen.get(slug, 0)
            seen[slug] = n + 1
            out.add(slug if n == 0 else "%s-%d" % (slug, n))
    return out


def check_doc(root, rel, text, tests, idents, files):
    findings = []
    here = os.path.dirname(rel)
    in_code = False
    for n, line in enumerate(text.splitlines(), 1):
        if line.startswith("```"):
            in_code = not in_code
        for m in PATH.finditer(line):
            if not path_exists(root, m.group(1), here):
                findings.append("%s:%d: no file %s" % (rel, n, m.group(1)))
        for m in LINK.finditer(line):
            target, anchor = m.group(1), m.group(2)
            if re.match(r"[a-z]+:", target) or target.startswith("/"):
                continue
            full = os.path.join(root, os.path.normpath(os.path.join(here, target or
                                                                    os.path.basename(rel))))
            if not os.path.exists(full):
                findings.append("%s:%d: link to a missing file %s" % (rel, n, target))
            elif anchor and full.endswith(".md") and anchor not in anchors(full):
                findings.append("%s:%d: link to a missing section %s#%s" % (rel, n, target,
                                                                             anchor))
        for m in BARE.finditer(line):
            if m.group(1) not in files and not path_exists(root, m.group(1), here):
                findings.append("%s:%d: no file named %s" % (rel, n, m.group(1)))
        for m in CTEST.finditer(line):
            name = PLACEHOLDER.sub("*", m.group(1).rstrip("."))
            if name.endswith(FILE_EXT):
                continue
            if not any(fnmatch.fnmatchcase(t, name) for t in tests):
                findings.append("%s:%d: no CTest %s" % (rel, n, name))
        for m in FUNC.finditer(line):
            if m.group(1) not in idents:
                findings.append("%s:%d: no function %s()" % (rel, n, m.group(1)))
        for m in CASE.finditer(line):
            if m.group(1) not in idents:
                findings.append("%s:%d: no test or name %s" % (rel, n, m.group(1)))
    return findings


def make_docs_outputs(root):
    """The files the Makefile's docs target writes (`... > path`)."""
    with open(os.path.join(root, "Makefile"), encoding="utf-8") as fh:
        recipe = re.search(r"^docs:.*\n((?:\t.*\n)+)", fh.read(), flags=re.M)
    return re.findall(r">\s*(\S+)", recipe.group(1)) if recipe else []


def check_make_docs_row(root, readme):
    row = next((l for l in readme.splitlines() if l.startswith("| `make docs`")), None)
    if row is None:
        return ["README.md: no `make docs` row"]
    return ["README.md: the `make docs` row does not name %s, which make docs writes" % out
            for out in make_docs_outputs(root)
            if out not in row and "`%s`" % os.path.basename(out) not in row]


def hooks_in_registers_md(root):
    """{module: set of register addresses it acts on}, from the generated table."""
    with open(os.path.join(root, "docs", "registers.md"), encoding="utf-8") as fh:
        text = fh.read()
    section = text.split("## Who acts on a register", 1)[-1]
    rows = re.findall(r"^\| (\w+) \| ([\d, ]+|-) \|", section, flags=re.M)
    return {m: {int(a) for a in re.findall(r"\d+", acts)} for m, acts in rows}


def check_write_h(root, text):
    """include/write.h's comment rows (`link    3 4 5 16 18 20`, ranges `6-9` in bytes)
    against the generated table; a range counts the registers that start in it."""
    hooks = hooks_in_registers_md(root)
    with open(os.path.join(root, "tools", "python", "servobus", "registers.json"),
              encoding="ascii") as fh:
        starts = {r["address"] for r in json.load(fh)["registers"]}
    listed = {}
    for m, nums in re.findall(r"^ \*\s+(%s)\s+([\d][\d -]*)" % "|".join(hooks), text, flags=re.M):
        addrs = set()
        for tok in nums.split():
            lo, _, hi = tok.partition("-")
            addrs |= set(range(int(lo), int(hi or lo) + 1))
        listed[m] = addrs & starts
    findings = []
    for m, acts in hooks.items():
        if listed.get(m) != acts:
            findings.append("include/write.h: lists %s acting on %s; the hooks say %s" % (
                m, sorted(listed.get(m, ())), sorted(acts)))
    return findings


def check_protocol_json_c(root, dispatch_h, proto_h):
    with open(os.path.join(root, "tools", "protocol_json.c"), encoding="utf-8") as fh:
        gen = fh.read()
    findings = []
    for header, text, prefix in (("include/dispatch.h", dispatch_h, "INS"),
                                 ("include/proto.h", proto_h, "ERR")):
        for name in re.findall(r"^#define (%s_\w+) 0x[0-9A-Fa-f]+u\b" % prefix, text, flags=re.M):
            if not re.search(r"\{\s*%s\s*," % name, gen):
                findings.append("tools/protocol_json.c: %s (%s) has no entry, so protocol.json "
                                "and the SDK never see it" % (name, header))
    return findings


def read_root(root, rel):
    with open(os.path.join(root, rel), encoding="utf-8") as fh:
        return fh.read()


def check(root, build):
    tests = ctest_names(build)
    idents = source_identifiers(root)
    files = file_names(root)
    findings = []
    for path in markdown_files(root):
        rel = os.path.relpath(path, root).replace(os.sep, "/")
        with open(path, encoding="utf-8") as fh:
            findings += check_doc(root, rel, fh.read(), tests, idents, files)
    with open(os.path.join(root, "README.md"), encoding="utf-8") as fh:
        findings += check_make_docs_row(root, fh.read())
    with open(os.path.join(root, "include", "write.h"), encoding="utf-8") as fh:
        findings += check_write_h(root, fh.read())
    findings += check_protocol_json_c(root, read_root(root, "include/dispatch.h"),
                                      read_root(root, "include/proto.h"))
    return findings, len(tests)


def self_test(build):
    """Each kind of false statement, planted in a copy of one doc, must be found."""
    tests = ctest_names(build)
    idents = source_identifiers(ROOT)
    files = file_names(ROOT)
    planted = {
        "no file named motion_none.c": "the fake in `motion_none.c`",
        "src/motion_loop.c": "`src/motion_loop.c` runs the loop",
        "link to a missing file": "see [the map](no_such_page.md)",
        "link to a missing section": "see [the loop](motion.md#control-loop-srcmotionc)",
        "no CTest unit.crcs": "tested by `unit.crcs`",
        "no CTest boards.seventh": "tested by `boards.seventh`",
        "no function store_commit_now()": "`store_commit_now()` writes it",
        "no test or name a_test_that_was_never_written": "(`a_test_that_was_never_written`)",
    }
    failed = 0
    for expect, line in planted.items():
        found = check_doc(ROOT, "docs/planted.md", "# t\n\n" + line + "\n", tests, idents, files)
        if not any(expect in f for f in found):
            print("self-test: %r not found in %r" % (expect, line))
            failed += 1
    good = "`src/store.c`, `board/<name>/board_pins.h`, `unit.store`, `replay.*`, " \
           "`boards.sixth`, `short.props`, " \
           "`tests/fuzz/corpus/TARGET/`, `fuzz.corpus.TARGET`, `store.c`, `demo.py`, " \
           "`store_sync()`, [arch](architecture.md), [rx](architecture.md#the-receiver)"
    found = check_doc(ROOT, "docs/planted.md", good, tests, idents, files)
    if found:
        print("self-test: true statements reported: %s" % found)
        failed += 1
    outputs = make_docs_outputs(ROOT)
    row = "| `make docs` | regenerate %s |" % ", ".join("`%s`" % o for o in outputs)
    if len(outputs) < 4 or check_make_docs_row(ROOT, row) or \
            not check_make_docs_row(ROOT, row.replace(outputs[0], "")):
        print("self-test: the make docs row check (Makefile writes %s)" % outputs)
        failed += 1
    with open(os.path.join(ROOT, "include", "write.h"), encoding="utf-8") as fh:
        write_h = fh.read()
    stale = re.sub(r"(^ \*\s+link\s+[\d ]*?) 20\b", r"\1", write_h, count=1, flags=re.M)
    if check_write_h(ROOT, write_h) or stale == write_h or not check_write_h(ROOT, stale):
        print("self-test: include/write.h's hook list check")
        failed += 1
    dispatch_h, proto_h = read_root(ROOT, "include/dispatch.h"), read_root(ROOT, "include/proto.h")
    if check_protocol_json_c(ROOT, dispatch_h, proto_h) or \
            not check_protocol_json_c(ROOT, dispatch_h + "#define INS_NEW_RULE 0x80u\n", proto_h) or \
            not check_protocol_json_c(ROOT, dispatch_h, proto_h + "#define ERR_NEW_BIT 0x80u\n"):
        print("self-test: tools/protocol_json.c's rules and ERR bits check")
        failed += 1
    return failed


def main(argv):
    if len(argv) < 2:
        print("usage: docs_check.py BUILD_DIR [--self-test]")
        return 2
    build = argv[1]
    if "--self-test" in argv and self_test(build):
        return 1
    findings, count = check(ROOT, build)
    for f in findings:
        print(f)
    print("docs.paths: %d finding(s) (%d CTest names known)" % (len(findings), count))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
