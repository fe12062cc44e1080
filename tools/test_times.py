#!/usr/bin/python3
"""CPU time per CTest (issue 28's faster loop): the figure that does not depend on how
busy a shared machine is, where ctest's own times do.

    tools/test_times.py [BUILD_DIR] [ctest selection...]   e.g.  tools/test_times.py -L fast

Runs each selected test of BUILD_DIR (default build/host) alone, one after the other, as
ctest would (its command, working directory and environment), and prints its wall time
and the CPU time (user + system) of it and its children, longest first, then the totals.
Exit status 1 if a test failed."""

import json
import os
import subprocess
import sys
import time

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def tests_of(build, selection):
    out = subprocess.check_output(["ctest", "--test-dir", build, "--show-only=json-v1",
                                   *selection])
    for t in json.loads(out)["tests"]:
        props = {p["name"]: p["value"] for p in t.get("properties", [])}
        env = dict(os.environ)
        for kv in props.get("ENVIRONMENT", []):
            k, v = kv.split("=", 1)
            env[k] = v
        yield t["name"], t["command"], props.get("WORKING_DIRECTORY", build), env


def run(command, cwd, env):
    """(wall s, CPU s, exit status) of command and every child it waited for."""
    t0 = time.monotonic()
    p = subprocess.Popen(command, cwd=cwd, env=env, stdout=subprocess.DEVNULL,
                         stderr=subprocess.DEVNULL)
    _, status, usage = os.wait4(p.pid, 0)
    p.returncode = os.waitstatus_to_exitcode(status)
    return time.monotonic() - t0, usage.ru_utime + usage.ru_stime, p.returncode


def main(argv):
    build = os.path.join(REPO, "build", "host")
    if argv and not argv[0].startswith("-"):
        build = os.path.abspath(argv.pop(0))
    rows = []
    for name, command, cwd, env in tests_of(build, argv):
        wall, cpu, rc = run(command, cwd, env)
        rows.append((cpu, wall, name, rc))
        print("%-32s wall %7.2f s  cpu %7.2f s%s" % (name, wall, cpu,
                                                     "" if rc == 0 else "  FAILED"),
              flush=True)
    print("--- longest first (CPU)")
    for cpu, wall, name, rc in sorted(rows, reverse=True)[:15]:
        print("%-32s cpu %7.2f s  wall %7.2f s" % (name, cpu, wall))
    print("%d tests: cpu %.1f s, wall %.1f s one after the other" % (
        len(rows), sum(r[0] for r in rows), sum(r[1] for r in rows)))
    return 1 if any(r[3] for r in rows) else 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
