"""Frames on the wire in words (issue 29: Servo Studio's console). decode() turns an
instruction or a status packet into the instruction, the ID, the registers by name with
their values in units, and the ERR bits in words; a status packet is decoded against
the request it answers. parse_hex() makes a frame from what a person typed in hex,
the checksum filled in. servoctl() is the servoctl command that sends the same thing.
Pure functions, no I/O."""

import re
import shlex

from . import protocol as P
from .errors import RangeError
from .registers import REGISTERS

_BY_ADDRESS = {r.address: r for r in REGISTERS.values()}
# CUSTOM's sub-commands in words, from the table (protocol.json), and the §10 update subs.
_CUSTOM_SUBS = {s["sub"]: s["name"].replace("_", " ") for s in P.CUSTOM_SUBS.values()}
_CUSTOM_SUBS.update({P.UPDATE_ENTER: "update: enter", P.UPDATE_BLOCK: "update: block"})
_START_END = {1: "start (here is 0 and the CW limit)", 2: "end (here is the CCW limit)"}


def registers_in(address, data, resolution=10):
    """[(register name, value in its unit, physical text)] of the bytes data read from
    or written at address; a byte that does not start a register is ('byte N', raw).
    ValueError-free: any bytes give a list."""
    out = []
    i = 0
    while i < len(data):
        r = _BY_ADDRESS.get(address + i)
        if r is None or i + r.size > len(data):
            out.append(("byte %d" % (address + i), data[i], ""))
            i += 1
            continue
        value = r.decode(int.from_bytes(data[i:i + r.size], "little"))
        text = r.format(value, resolution)
        out.append((r.name, value, text[text.find("(") + 1:-1] if "(" in text else ""))
        i += r.size
    return out


def _span(address, count):
    """'present_position..moving (36-42)' for a READ of count bytes at address."""
    names = [n for n, _, _ in registers_in(address, bytes(count)) if not n.startswith("byte")]
    if not names:
        return "%d bytes at %d" % (count, address)
    head = names[0] if len(names) == 1 else "%s..%s" % (names[0], names[-1])
    return "%s (%d-%d)" % (head, address, address + count - 1)


def _fields_text(fields):
    return ", ".join("%s = %s%s" % (n, v, " (%s)" % t if t else "") for n, v, t in fields)


def decode_instruction(raw, resolution=10):
    """An instruction packet (bytes) in words: a dict with id, ins, name, summary,
    fields [(register, value, physical)], ok (checksum)."""
    raw = bytes(raw)
    pkt = P.StatusPacket(raw)
    ins, params = raw[4], raw[5:-1]
    name = P.INSTRUCTION_NAMES.get(ins, "instruction 0x%02X" % ins)
    out = {"kind": "instruction", "id": raw[2], "ins": ins, "name": name, "fields": [],
           "ok": pkt.ok, "err": None, "err_words": []}
    summary = ""
    if ins == P.READ and len(params) == 2:
        summary = _span(params[0], params[1])
        out["read"] = [params[0], params[1]]
    elif ins in (P.WRITE, P.REG_WRITE) and params:
        out["fields"] = registers_in(params[0], params[1:], resolution)
        summary = _fields_text(out["fields"])
    elif ins == P.SYNC_WRITE and len(params) >= 2 and params[1]:
        addr, size, rest = params[0], params[1], params[2:]
        parts = []
        for k in range(0, len(rest) - size, size + 1):
            fields = registers_in(addr, rest[k + 1:k + 1 + size], resolution)
            out["fields"] += [("ID %d: %s" % (rest[k], n), v, t) for n, v, t in fields]
            parts.append("ID %d: %s" % (rest[k], _fields_text(fields)))
        summary = "; ".join(parts)
    elif ins == P.TRAJ_WRITE and params:
        summary = _trajectory(params, resolution, out)
    elif ins == P.START_END and len(params) == 1:
        summary = _START_END.get(params[0], "code %d" % params[0])
    elif ins == P.CUSTOM and params:
        summary = _custom(params, resolution)
    elif params:
        summary = params.hex(" ")
    if raw[2] == P.BROADCAST:
        summary = ("broadcast" + (": " + summary if summary else "")) if ins != P.PING \
            else "broadcast (every servo answers in its ID's slot)"
    out["summary"] = summary
    return out


def _trajectory(params, resolution, out):
    count, body = params[0], params[1:]
    if not count or len(body) % count or len(body) // count not in (3, 4):
        return "%d points (malformed)" % count if count else "clear the stored trajectory"
    size = len(body) // count
    deg = resolution * 0.1
    pts = []
    for k in range(0, len(body), size):
        angle = int.from_bytes(body[k:k + 2], "little")
        speed = int.from_bytes(body[k + 2:k + size], "little")
        pts.append((angle, speed))
    out["points"] = pts
    return "%d points: %s" % (count, ", ".join("%g deg at %g deg/s" % (
        round(a * deg, 2), round(s * deg, 2)) for a, s in pts))


def _custom(params, resolution):
    sub = params[0]
    words = _CUSTOM_SUBS.get(sub, "sub-command 0x%02X" % sub)
    if sub in (1, 2) and len(params) >= 5:
        deg = resolution * 0.1
        target = int.from_bytes(params[1:3], "little")
        speed = int.from_bytes(params[3:5], "little")
        sign = -1 if speed & 0x8000 and sub == 1 else 1
        words += " %g deg at %g deg/s" % (round(target * deg * sign, 2),
                                         round((speed & 0x7FFF) * deg, 2))
        if len(params) >= 7:
            words += ", acc %d, dec %d (x10 deg/s^2)" % (params[5], params[6])
    return words


def decode_status(raw, request=None, resolution=10):
    """A status packet in words, against the instruction packet it answers (None: not
    known). ERR in words; a READ's data as registers; a PING's live ERR byte."""
    raw = bytes(raw)
    pkt = P.StatusPacket(raw)
    out = {"kind": "status", "id": pkt.id, "ins": None, "name": "status", "fields": [],
           "ok": pkt.ok, "err": pkt.err, "summary": ""}
    err = pkt.err
    req_ins = request[4] if request is not None and len(request) > 5 else None
    if req_ins == P.PING and len(pkt.params) == 1 and pkt.err == 0x01:
        err = pkt.params[0]  # `03 01 ERR`: the live ERR byte is the parameter
        out["summary"] = "PING answer"
    elif req_ins == P.READ and len(request) == 8 and len(pkt.params) == request[6]:
        out["fields"] = registers_in(request[5], pkt.params, resolution)
        out["summary"] = _fields_text(out["fields"])
    elif pkt.params:
        out["summary"] = pkt.params.hex(" ")
    out["err"] = err
    out["err_words"] = P.describe_err(err)
    if not pkt.ok:
        out["err_words"] = ["checksum wrong: a garbled answer"] + out["err_words"]
    return out


def looks_like_hex(text):
    """Is text meant as a frame in hex (only hex digits, spaces, commas, colons and 0x),
    rather than a command?"""
    digits = re.sub(r"(0x|[\s,:])", "", text.strip(), flags=re.I)
    return bool(digits) and re.fullmatch(r"[0-9a-fA-F]*", digits) is not None


def parse_hex(text):
    """The frame for hex a person typed: `D5 5D ID LEN INS P.. [CHK]`, the header
    optional, the checksum filled in when left out. RangeError with a sentence for
    what is not a frame (a wrong checksum given is refused: the studio sends no
    corrupt frame)."""
    if not isinstance(text, str):
        raise RangeError("the frame must be text: hex bytes such as 'D5 5D 01 02 01'")
    digits = re.sub(r"(0x|[\s,:])", "", text.strip(), flags=re.I)
    if not digits:
        raise RangeError("the frame is empty: give hex bytes such as 'D5 5D 01 02 01'")
    if not re.fullmatch(r"[0-9a-fA-F]*", digits) or len(digits) % 2:
        raise RangeError("'%s' is not hex bytes (two hex digits each, e.g. 'D5 5D 01 02 "
                         "01')" % text.strip()[:60])
    data = bytes.fromhex(digits)
    if data[:2] == P.HEADER:
        data = data[2:]
    if len(data) < 3:
        raise RangeError("a frame needs at least ID, LEN and the instruction after the "
                         "header D5 5D")
    sid, length, rest = data[0], data[1], data[2:]
    if length < 2:
        raise RangeError("LEN %d is too small: LEN is the parameters plus 2" % length)
    if len(rest) == length - 1:
        body = data
    elif len(rest) == length:
        body = data[:-1]
        want = P.checksum(body)
        if data[-1] != want:
            raise RangeError("checksum 0x%02X is wrong: this frame's is 0x%02X (leave it "
                             "out and it is filled in)" % (data[-1], want))
    else:
        raise RangeError("LEN 0x%02X says %d parameters, but %d bytes follow the "
                         "instruction" % (length, length - 2, len(rest) - 1))
    if sid == 0xFF:
        raise RangeError("ID 0xFF is not an ID (0-253, or 254 for broadcast)")
    return P.HEADER + body + bytes([P.checksum(body)])


def servoctl(raw, port="", baud=None, resolution=10):
    """The servoctl command that sends what the instruction packet raw does, or None
    when servoctl has no command for it (REG WRITE, ACTION, SYNC WRITE, update
    frames): a string a person can paste into a shell."""
    raw = bytes(raw)
    if len(raw) < 6 or raw[:2] != P.HEADER:
        return None
    sid, ins, params = raw[2], raw[4], raw[5:-1]
    head = ["servoctl"] + (["--port", port] if port else []) + (
        ["--baud", str(baud)] if baud else [])
    if sid == P.BROADCAST:
        return " ".join(map(shlex.quote, head + ["scan"])) if ins == P.PING else None
    head += ["--id", str(sid)]
    words = None
    if ins == P.PING:
        words = ["ping"]
    elif ins == P.READ and len(params) == 2:
        names = [n for n, _, _ in registers_in(params[0], bytes(params[1]))
                 if not n.startswith("byte") and REGISTERS[n].readable]
        words = ["get"] + names if names else None
        if params[0] == 0 and params[1] >= 50:
            words = ["dump"]
    elif ins == P.WRITE and len(params) >= 2:
        fields = registers_in(params[0], params[1:], resolution)
        if any(n.startswith("byte") for n, _, _ in fields):
            return None
        words = ["set"] + [str(x) for n, v, _ in fields for x in (n, v)]
    elif ins == P.TRAJ_WRITE and params:
        pts = decode_instruction(raw, resolution).get("points")
        words = ["traj", "--no-run"] + ["%d:%d" % p for p in pts] if pts else None
    elif ins == P.RESET:
        words = ["reset", "--yes"]
    return " ".join(map(shlex.quote, head + words)) if words else None
