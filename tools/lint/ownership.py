#!/usr/bin/env python3
"""Ownership check (issue 28, docs/architecture.md "Who owns what"): every module's state
is touched only by that module.

1. The control table's bytes (`struct regs`, member `mem`) are written only by src/regs.c
   (and include/regs.h): everyone else goes through regs_set(), regs_put8() and the other
   regs_* calls, so the EEPROM change flag and the 16-bit registers' untorn stores hold.
   Reading a byte register (`s->regs.mem[REG_X]`) is allowed everywhere: the table is
   the interface between the modules.
2. A member of `struct servo` that is a module's state (`rx`, `link`, `held`, `traj`,
   `store`, `motion`, `safety`, `update`, `loader`) is reached into (`s->link.state`,
   `n->servo.rx.overruns`) only by its owner; everyone else hands the whole part to the
   owner's functions (`link_state(&s->link)`), as TinyUSB's class drivers keep their
   state to themselves. Whatever the servo is called (`s`, `sv`, `n->servo`, `(x)` in a
   macro), and through a pointer to the part (`struct motion *m = &s->motion;` then
   `m->mode`); the same for a pointer to the table's bytes (`uint8_t *t = r->mem;`).

Scans the firmware (src/, include/) and the host code that runs it (hal/, tools/sim/);
tests may look inside. Prints each finding as file:line and exits 1 on any."""

import os
import re
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCANNED = ("src", "include", "hal", "tools/sim")

# The member of struct servo, and the files that own it.
OWNERS = {
    "rx": {"src/frame_rx.c", "include/frame_rx.h"},
    "link": {"src/link.c", "include/link.h"},
    "held": {"src/dispatch.c"},
    "traj": {"src/traj.c", "include/traj.h"},
    "store": {"src/store.c", "include/store.h"},
    "motion": {"src/motion.c", "include/motion.h", "include/motion_mode.h"},
    "safety": {"src/safety.c", "include/safety.h"},
    "update": {"src/update.c", "include/update.h"},
    "loader": {"src/loader.c", "include/loader.h"},
}
REGS_WRITERS = {"src/regs.c", "include/regs.h"}

# s->link.x, servo.link.x, node.servo.link->x, (s)->link.x in a macro: a servo's part,
# then one of its fields.
PARTS = "|".join(OWNERS)
REACH = re.compile(r"(?:\b\w+|\))\s*(?:->|\.)\s*(%s)\s*(?:\.|->)\s*[A-Za-z_]" % PARTS)
# A pointer to a part (m = &s->motion;), whose fields are then reached through it.
PART_ALIAS = re.compile(r"(\w+)\s*=\s*&\s*\(?[\w.>()-]*?(?:->|\.)\s*(%s)\s*\)?\s*;" % PARTS)
# A write to the table's bytes: assignment (not ==), ++/--, or memcpy/memset into them.
MEM = r"(?:->|\.)\s*mem\s*\[[^\]]*\]"
MEM_WRITE = re.compile(
    MEM + r"\s*(?:[-+*/%&|^]|<<|>>)?=(?!=)|" + MEM + r"\s*(?:\+\+|--)|(?:\+\+|--)\s*[\w.>-]*" +
    MEM + r"|\bmem(?:cpy|set|move)\s*\(\s*&?[\w.>-]*(?:->|\.)mem\b")
# A pointer to the table's bytes (uint8_t *t = r->mem; t = &s->regs.mem[4];), written
# through; a pointer to const bytes is a reader.
MEM_ALIAS = re.compile(r"(?<!const )\buint8_t\s*\*\s*(\w+)\s*=\s*(?:&\s*)?[\w.>()-]*(?:->|\.)\s*mem"
                       r"\s*(?:\[[^\]]*\]\s*)?(?:;|\+)")


def strip_comments(text):
    """Comments and string literals blanked, line breaks kept (line numbers stay)."""
    def blank(m):
        return re.sub(r"[^\n]", " ", m.group(0))
    return re.sub(r'/\*.*?\*/|//[^\n]*|"(?:\\.|[^"\\\n])*"', blank, text, flags=re.S)


def check_file(rel, text):
    findings = []
    code = strip_comments(text)
    aliases = {m.group(1): m.group(2) for m in PART_ALIAS.finditer(code)
               if rel not in OWNERS[m.group(2)]}
    mem_aliases = {m.group(1) for m in MEM_ALIAS.finditer(code)}
    reach = [(REACH, 1)] + [(re.compile(r"\b(%s)\s*->\s*[A-Za-z_]" % re.escape(a)), a)
                            for a in aliases]
    alias_write = [re.compile(r"\b%s\s*\[[^\]]*\]\s*(?:[-+*/%%&|^]|<<|>>)?=(?!=)|\b%s\s*\[[^\]]*\]"
                              r"\s*(?:\+\+|--)|^\s*\*\s*\(?\s*%s\b[^=;]*\)?\s*=(?!=)|"
                              r"\bmem(?:cpy|set|move)\s*\(\s*%s\b" % ((re.escape(a),) * 4))
                   for a in mem_aliases]
    for n, line in enumerate(code.splitlines(), 1):
        if rel.startswith(("src/", "include/")) and rel not in REGS_WRITERS:
            if MEM_WRITE.search(line) or any(w.search(line) for w in alias_write):
                findings.append("%s:%d: writes the control table's bytes; use regs_set() or "
                                "regs_put8() (src/regs.c)" % (rel, n))
        for pattern, alias in reach:
            for m in pattern.finditer(line):
                part = m.group(1) if alias == 1 else aliases[alias]
                if rel in OWNERS[part]:
                    continue
                findings.append("%s:%d: reaches into the servo's `%s`, owned by %s; hand "
                                "it to the owner's functions" % (
                                    rel, n, part, " and ".join(sorted(OWNERS[part]))))
                break
    return findings


def main(argv):
    root = argv[1] if len(argv) > 1 else ROOT
    findings = []
    for top in SCANNED:
        for dirpath, _, files in os.walk(os.path.join(root, top)):
            for f in sorted(files):
                if f.endswith((".c", ".h")):
                    path = os.path.join(dirpath, f)
                    rel = os.path.relpath(path, root).replace(os.sep, "/")
                    with open(path, encoding="utf-8") as fh:
                        findings += check_file(rel, fh.read())
    for f in findings:
        print(f)
    print("ownership: %d finding(s)" % len(findings))
    return 1 if findings else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv))
