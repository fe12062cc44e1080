"""Reading picked registers of several servos in as few READs as the table allows, and
what the wire allows (issue 29: Servo Studio's plot of any register and its
dashboard; `make bench` prints the same figures).

plan_reads() gives each servo the READs that cover its picked registers: one READ per
servo unless a gap between two picked registers costs more wire time than a second
READ (its request, its answer's framing and the servo's return delay). wire_time() is
what one READ takes on the wire; wire_limit_hz() is the most cycles a second the wire
carries, when every servo is read once per cycle (the poller's fair share: every servo
gets the same rate, and when the bus is slow every one of them drops together)."""

from . import protocol as P
from .errors import RangeError
from .registers import register

READ_REQUEST_BYTES = 8     # D5 5D ID 04 02 ADDR COUNT CHK
ANSWER_FRAME_BYTES = 6     # D5 5D ID LEN ERR ... CHK
DEFAULT_RETURN_DELAY_S = 0.008  # register 5 = 16 (500 us units): foot, arm, wrist, finger


def plan_reads(picks, return_delay_s=DEFAULT_RETURN_DELAY_S, baud=9600):
    """picks: {servo ID: [register name or address, ...]} (readable registers). The
    READs: [(ID, first address, byte count, [register names])], in ID order. Two picked
    registers share a READ when the bytes between them take less time on the wire than
    a READ of its own would add. RangeError for a register that cannot be read."""
    out = []
    for sid in sorted(picks):
        regs = []
        for name in picks[sid]:
            r = register(name)
            if not r.readable:
                raise RangeError("%s (register %d) cannot be read: it is write-only" % (
                    r.name, r.address))
            if r not in regs:
                regs.append(r)
        regs.sort(key=lambda r: r.address)
        # a gap of this many bytes costs as much as a READ of its own
        worth = READ_REQUEST_BYTES + ANSWER_FRAME_BYTES + return_delay_s / P.byte_time(baud)
        runs = []
        for r in regs:
            if runs and r.address - runs[-1][1] <= worth:
                runs[-1][1] = max(runs[-1][1], r.address + r.size)
                runs[-1][2].append(r.name)
            else:
                runs.append([r.address, r.address + r.size, [r.name]])
        out += [(sid, first, end - first, names) for first, end, names in runs]
    return out


def wire_time(count, baud, return_delay_s=DEFAULT_RETURN_DELAY_S):
    """Seconds one READ of count bytes takes on the wire: the request, the servo's
    return delay, the answer (8N1: ten bits a byte)."""
    return (READ_REQUEST_BYTES + ANSWER_FRAME_BYTES + count) * P.byte_time(baud) + \
        return_delay_s


def wire_limit_hz(reads, baud, return_delays=None):
    """The most polling cycles a second the wire carries, each cycle every READ of
    reads ([(ID, first, count, ...)]) once; return_delays: {ID: seconds} (default 8 ms).
    The host's own time is not counted: this is the wire's limit."""
    delays = return_delays or {}
    total = sum(wire_time(r[2], baud, delays.get(r[0], DEFAULT_RETURN_DELAY_S))
                for r in reads)
    return 1.0 / total if total else 0.0


def decode_reads(reads, answers, variants=None):
    """{ID: {register name: value}} from the data each READ of reads brought back
    (answers: the bytes of each READ, in order; None for one that failed). Registers
    that do not exist on the servo's variant ({ID: Variant}) are left out."""
    variants = variants or {}
    out = {}
    for (sid, first, _count, names), data in zip(reads, answers):
        if data is None:
            continue
        values = out.setdefault(sid, {})
        for name in names:
            r = register(name)
            if not r.applies_to(variants.get(sid)):
                continue
            off = r.address - first
            values[name] = r.decode(int.from_bytes(data[off:off + r.size], "little"))
    return out
