#!/usr/bin/env python3
"""CTest lint.ownership: tools/lint/ownership.py finds nothing in the tree, and finds
each kind of violation planted in a scratch tree (so the check can fail)."""
import io
import os
import sys
import tempfile
from contextlib import redirect_stdout

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, os.path.join(HERE, "..", "tools", "lint"))
import ownership  # noqa: E402

PLANTED = {
    "src/command.c": "void f(struct servo *s, struct regs *r)\n{\n"
                     "    s->link.state = 0;\n"          # line 3: reaches into link
                     "    r->mem[3] = 1;\n"              # line 4: writes the table
                     "    s->regs.mem[REG_ID]++;\n"      # line 5
                     "    memcpy(r->mem, x, 3);\n"       # line 6
                     "    if (r->mem[2] == 1) {}\n"      # a read: fine
                     "    /* s->rx.pos = 1; */\n}\n",    # a comment: fine
    "src/link.c": "void g(struct servo *s) { s->link.state = 0; }\n",  # the owner: fine
    "tools/sim/bus.c": "x = v->node.servo.rx.overruns;\n"            # line 1
                       "const struct link *l = &n->servo.link;\n"   # a pointer to it: fine
                       "if (l->state == 2) {}\n",                    # line 3: through it
    # What a name-bound check misses: another name, a macro, a pointer to the part, a
    # pointer to the table's bytes (issue 28's review; a pointer to const bytes reads).
    "src/sequence.c": "#define MODE(x) ((x)->motion.mode)\n"          # line 1
                      "void h(struct servo *sv)\n{\n"
                      "    sv->safety.quiet_ticks = 0;\n"            # line 4
                      "    struct motion *m = &sv->motion;\n"        # a pointer: fine
                      "    m->mode = 0;\n"                           # line 6
                      "    uint8_t *t = sv->regs.mem;\n"             # a pointer: fine
                      "    t[3] = 1;\n"                              # line 8
                      "    const uint8_t *u = sv->regs.mem;\n"       # const: fine
                      "    if (u[1] == 0) {}\n}\n",                 # a read: fine
}


def run(root):
    out = io.StringIO()
    with redirect_stdout(out):
        rc = ownership.main(["ownership.py", root])
    return rc, out.getvalue()


def main():
    rc, out = run(os.path.join(HERE, ".."))
    if rc != 0:
        print(out)
        return 1
    with tempfile.TemporaryDirectory() as d:
        for rel, text in PLANTED.items():
            os.makedirs(os.path.dirname(os.path.join(d, rel)), exist_ok=True)
            with open(os.path.join(d, rel), "w", encoding="utf-8") as f:
                f.write(text)
        rc, out = run(d)
    found = sorted(line.split(": ")[0] for line in out.splitlines() if ": " in line
                   and not line.startswith("ownership:"))
    want = ["src/command.c:3", "src/command.c:4", "src/command.c:5", "src/command.c:6",
            "src/sequence.c:1", "src/sequence.c:4", "src/sequence.c:6", "src/sequence.c:8",
            "tools/sim/bus.c:1", "tools/sim/bus.c:3"]
    if rc != 1 or found != want:
        print("planted violations: expected %s, found %s\n%s" % (want, found, out))
        return 1
    print("ownership: the tree is clean, and all %d planted violations were found" % len(want))
    return 0


if __name__ == "__main__":
    sys.exit(main())
