#!/usr/bin/python3
"""qemu_bus_test.py - issue 27 on real images: three arm images under QEMU (the `qemu`
build, tools/qemu_servo.py), each with its own UID loaded at 0x0801FFF0, and two host
nodes, all at ID 1, share servo-sim's modelled RS485 wire (`servo-sim --uart`): their
answers collide and every node hears the others. `servoctl ids --fix` alone gives them
IDs 1-5; then each answers PING at its own ID alone, and after servo-sim restarts (its
host nodes' flash in --state-dir; the QEMU images keep running, and QEMU keeps their
store in RAM) the IDs are still there. Two of the images share their UID's first nibble,
so their ENUMERATE answers collide too."""
import os
import subprocess
import sys
import tempfile

REPO = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
sys.path.insert(0, os.path.join(REPO, "tools"))
sys.path.insert(0, os.path.join(REPO, "tools", "python"))

from qemu_servo import QemuServo, free_port  # noqa: E402
from servobus import Bus  # noqa: E402

NAME = "qemu_bus_test"
SIM = os.environ.get("SERVO_SIM") or os.path.join(REPO, "build", "host", "servo-sim")
UIDS = ("a1000000000000000000000e", "b1000000000000000000000e", "c2000000000000000000000e")


def fail(msg):
    print(f"{NAME}: FAIL: {msg}", file=sys.stderr, flush=True)
    sys.exit(1)


def say(msg):
    print(f"{NAME}: {msg}", flush=True)


def start_sim(port, qemus, state):
    args = [SIM, "--listen", f"127.0.0.1:{port}", "--servo", "1:foot", "--servo", "1:wrist",
            "--state-dir", state]
    for q in qemus:
        args += ["--uart", f"127.0.0.1:{q.port}"]
    p = subprocess.Popen(args, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    line = p.stdout.readline()
    if "listening on" not in line:
        p.kill()
        fail("servo-sim did not start: " + p.stderr.read())
    return p


def servoctl(url, *args):
    env = dict(os.environ, PYTHONPATH=os.path.join(REPO, "tools", "python"),
               SERVOBUS_STATE=os.path.join(STATE, "budget.json"))
    p = subprocess.run([sys.executable, "-m", "servobus", "--port", url, *args],
                       capture_output=True, text=True, env=env, timeout=120)
    return p.returncode, p.stdout, p.stderr


def table(out):
    """UID -> ID from the last table servoctl ids printed."""
    rows = {}
    for line in out.splitlines():
        parts = line.split()
        if len(parts) >= 6 and len(parts[0]) == 24 and parts[1].isdigit():
            rows[parts[0]] = int(parts[1])
    return rows


def alone(url, ids):
    with Bus(url) as bus:
        for i in ids:
            bus.ping(i)
            if bus.duplicate(i, tries=1, probes=("ping",)):
                fail(f"ID {i} still answers twice")


def main():
    qemus = [QemuServo(uid=bytes.fromhex(u)) for u in UIDS]
    sim = None
    try:
        for q in qemus:
            if not q.wait_ready():
                fail("a QEMU image did not answer PING: " + q.stop())
        port = free_port()
        url = f"tcp://127.0.0.1:{port}"
        sim = start_sim(port, qemus, STATE)
        rc, out, err = servoctl(url, "ids")
        if rc != 1 or out.count("DUPLICATE ID") != 5:
            fail(f"ids before: rc {rc}, {out} {err}")
        before = table(out)
        if not set(UIDS) <= set(before) or len(before) != 5:
            fail(f"not every node enumerated: {before}")
        say("5 nodes at ID 1 enumerated, the 3 QEMU images by their loaded UIDs")
        rc, out, err = servoctl(url, "ids", "--fix")
        if rc != 0:
            fail(f"ids --fix: rc {rc}, {out} {err}")
        after = table(out.split("now:")[1])
        if sorted(after.values()) != [1, 2, 3, 4, 5]:
            fail(f"IDs after --fix: {after}")
        alone(url, range(1, 6))
        say("ids --fix gave IDs 1-5: " + ", ".join(f"{u} -> {i}" for u, i in sorted(after.items())))
        sim.terminate()
        sim.wait()
        sim = start_sim(port, qemus, STATE)
        rc, out, err = servoctl(url, "ids")
        if rc != 0 or table(out) != after:
            fail(f"after a restart: rc {rc}, {table(out)} (was {after}) {err}")
        alone(url, range(1, 6))
        say("PASS: every node keeps its ID across a restart of servo-sim")
    finally:
        if sim is not None:
            sim.terminate()
            sim.wait()
        for q in qemus:
            q.stop()


if __name__ == "__main__":
    with tempfile.TemporaryDirectory() as STATE:
        main()
