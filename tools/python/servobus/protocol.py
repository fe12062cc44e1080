"""Wire format of the servo bus (PROTOCOL.md §2-§4): packet builder, status packet
parser, instruction codes and ERR bits. Pure functions, no I/O."""

import json
import os

# The instruction table, the ERR bits and the header, as the firmware defines them:
# protocol.json is written by `regdoc --protocol-json` from src/dispatch.c and
# include/proto.h (`make docs`), and CTest's docs.protocol_json fails when it drifts. A
# name looked up below that the firmware no longer has fails at import.
_JSON = os.path.join(os.path.dirname(os.path.abspath(__file__)), "protocol.json")
with open(_JSON, encoding="ascii") as _f:
    TABLE = json.load(_f)
_INS = {i["name"]: i for i in TABLE["instructions"]}
_ERR = {e["name"]: e["bit"] for e in TABLE["err_bits"]}

HEADER = bytes(TABLE["header"])
BROADCAST = TABLE["broadcast_id"]
ID_MAX = 253

PING = _INS["ping"]["code"]
READ = _INS["read"]["code"]
WRITE = _INS["write"]["code"]
REG_WRITE = _INS["reg_write"]["code"]
ACTION = _INS["action"]["code"]
RESET = _INS["reset"]["code"]
START_END = _INS["start_end"]["code"]
TRAJ_WRITE = _INS["trajectory_write"]["code"]
TRAJ_ACTION = _INS["trajectory_action"]["code"]
SYNC_WRITE = _INS["sync_write"]["code"]
CUSTOM = _INS["custom"]["code"]

# Instructions after which the servo commits what changed in its EEPROM registers to
# flash, spending one token of its commit budget (budget.py). Homing's measured limits
# are committed too, when it completes; REG WRITE commits at its ACTION.
COMMITS = frozenset(i["code"] for i in TABLE["instructions"] if "commits" in i["flags"])
# CUSTOM's sub-commands by name (the move subs, issue 27's identity sub), with their rules.
CUSTOM_SUBS = {s["name"]: s for s in TABLE["custom_subs"]}

# Every instruction of the table by its name in words (the spec's spelling: "sync_write"
# is SYNC WRITE), from the table itself, so an instruction added there is named in
# servoctl's errors and Studio's console without a second list.
_WORDS = {"start_end": "START/END"}
INSTRUCTION_NAMES = {i["code"]: _WORDS.get(i["name"], i["name"].upper().replace("_", " "))
                     for i in TABLE["instructions"]}

ERR_OVER_TEMPERATURE = _ERR["over_temperature"]
ERR_OVER_CURRENT = _ERR["over_current"]
ERR_OVER_VOLTAGE = _ERR["over_voltage"]
ERR_UNDER_VOLTAGE = _ERR["under_voltage"]
ERR_CHECKSUM = _ERR["checksum"]
ERR_INSTRUCTION = _ERR["instruction"]
ERR_STALL = _ERR["stall"]
ERR_FAULTS = (ERR_OVER_TEMPERATURE | ERR_OVER_CURRENT | ERR_OVER_VOLTAGE |
              ERR_UNDER_VOLTAGE | ERR_STALL)

ERR_BITS = [
    (ERR_STALL, "stall (commanded motion, no movement, high current)"),
    (ERR_INSTRUCTION, "instruction error"),
    (ERR_CHECKSUM, "checksum error"),
    (ERR_UNDER_VOLTAGE, "under-voltage"),
    (ERR_OVER_VOLTAGE, "over-voltage"),
    (ERR_OVER_CURRENT, "over-current (above register 12)"),
    (ERR_OVER_TEMPERATURE, "over-temperature (above register 11)"),
]

# Time of one 7-byte answer plus two byte-times, in bytes (§4.1 broadcast PING slots).
SLOT_BYTES = 9
# Longest return delay: register 5 = 255 x 500 us.
MAX_RETURN_DELAY_S = 0.1275


def describe_err(err):
    """Names of the bits set in an ERR byte."""
    names = [name for bit, name in ERR_BITS if err & bit]
    if err & 0x80:
        names.append("bit 7 (unused, should be 0)")
    return names or ["no error"]


def checksum(body):
    """Plain 8-bit sum (not inverted) of ID, LEN, INS/ERR and the parameters."""
    return sum(body) & 0xFF


def instruction(servo_id, ins, params=b""):
    """`D5 5D ID LEN INS P1..Pn CHK`."""
    params = bytes(params)
    if not 0 <= servo_id <= 0xFE:
        raise ValueError("ID %r is not 0-253 or 254 (broadcast)" % (servo_id,))
    if len(params) > 253:
        raise ValueError("%d parameters do not fit in one packet (253 at most)" % len(params))
    body = bytes([servo_id, len(params) + 2, ins]) + params
    return HEADER + body + bytes([checksum(body)])


class StatusPacket:
    """One status packet: id, err (the byte after LEN), params, raw bytes, ok (checksum)."""

    __slots__ = ("id", "err", "params", "raw", "ok")

    def __init__(self, raw):
        self.raw = bytes(raw)
        self.id = raw[2]
        self.err = raw[4]
        self.params = self.raw[5:-1]
        self.ok = checksum(self.raw[2:-1]) == raw[-1]

    def ping_err(self):
        """For a PING answer `03 01 ERR`, the live ERR byte; otherwise the ERR byte."""
        if len(self.params) == 1 and self.err == 0x01:
            return self.params[0]
        return self.err

    def __repr__(self):
        return "StatusPacket(%s)" % self.raw.hex(" ")


class StatusParser:
    """Cuts a byte stream into packets, resynchronising on `D5 5D`. Status packets, and
    (for tests and tools) instruction packets too: they share the format; a §10 data
    block (LEN 0xFF, `FF FE 02`) is 1031 bytes after LEN. A status packet's ERR byte
    never has bit 7 set, so it never looks like one."""

    def __init__(self):
        self.buf = bytearray()
        self.skipped = 0  # bytes dropped while hunting for a header

    def feed(self, data):
        """Add bytes; return the complete packets now available."""
        self.buf += data
        out = []
        while True:
            i = self.buf.find(HEADER)
            if i < 0:
                keep = 1 if self.buf[-1:] == HEADER[:1] else 0
                self.skipped += len(self.buf) - keep
                del self.buf[:len(self.buf) - keep]
                return out
            if i:
                self.skipped += i
                del self.buf[:i]
            if len(self.buf) < 4:
                return out
            length = self.buf[3]
            if length < 2 or self.buf[2] == 0xFF:
                self.skipped += 2
                del self.buf[:2]
                continue
            total = 4 + length
            if length == 0xFF and len(self.buf) >= 7 and \
                    bytes(self.buf[4:7]) == bytes([CUSTOM, UPDATE_BLOCK, UPDATE_DATA]):
                total = 4 + UPDATE_DATA_FRAME + 1  # §10: its LEN cannot say 1031
            elif length == 0xFF and len(self.buf) < 7:
                return out
            if len(self.buf) < total:
                return out
            pkt = StatusPacket(self.buf[:total])
            if not pkt.ok:
                # A bad checksum may mean a lost byte: resynchronise just after the header
                # so a packet starting inside this one is still found.
                out.append(pkt)
                del self.buf[:2]
                continue
            out.append(pkt)
            del self.buf[:total]

    def pending(self):
        """Bytes of an incomplete packet held back."""
        return len(self.buf)


def byte_time(baud):
    """Seconds per byte on the wire (8N1: 10 bits)."""
    return 10.0 / baud


def u16(value):
    return bytes([value & 0xFF, (value >> 8) & 0xFF])


# ---- firmware update (§10): YMODEM blocks in CUSTOM frames, sub-commands 0xFC/0xFE ----

UPDATE_ENTER = TABLE["update_subs"]["enter"]
UPDATE_BLOCK = TABLE["update_subs"]["block"]
UPDATE_HEADER = 0x01
UPDATE_DATA = 0x02
UPDATE_EOF = 0x04
ACK = 0x06
NAK = 0x15
CAN = 0x18
READY = 0x43  # 'C'
UPDATE_HEADER_DATA = 128
UPDATE_BLOCK_DATA = 1024
UPDATE_DATA_FRAME = 1031  # bytes after LEN in a data block frame, before the checksum
# Answers: enter 'C' (LEN 3), header and end of file ACK 'C' (LEN 4), data block and end
# of batch ACK (LEN 3); NAK or CAN in place of the first byte (LEN 3).
UPDATE_ANSWER_BYTES = 8


def crc16_xmodem(data, crc=0):
    """CRC-16/XMODEM: polynomial 0x1021, initial 0, MSB first, no final xor
    (b"123456789" -> 0x31C3)."""
    for byte in bytes(data):
        crc ^= byte << 8
        for _ in range(8):
            crc = ((crc << 1) ^ 0x1021) if crc & 0x8000 else (crc << 1)
            crc &= 0xFFFF
    return crc


def _frame(body):
    return HEADER + body + bytes([checksum(body)])


def _check_id(servo_id):
    if not 0 <= servo_id <= ID_MAX:
        raise ValueError("the update addresses one servo: ID %r is not 0-253" % (servo_id,))


def update_enter(servo_id):
    """`D5 5D ID 03 FF FC CHK`: enter update mode (answer 'C')."""
    _check_id(servo_id)
    return _frame(bytes([servo_id, 3, CUSTOM, UPDATE_ENTER]))


def _block(servo_id, btype, number, data, size, len_byte):
    data = bytes(data)
    if len(data) > size:
        raise ValueError("a block carries %d bytes, not %d" % (size, len(data)))
    data += (b"\0" if size == UPDATE_HEADER_DATA else b"\xFF") * (size - len(data))
    crc = crc16_xmodem(data)
    number &= 0xFF
    return _frame(bytes([servo_id, len_byte, CUSTOM, UPDATE_BLOCK, btype, number,
                         ~number & 0xFF]) + data + bytes([crc >> 8, crc & 0xFF]))


def update_header(servo_id, length):
    """Header block (type 1, number 0; LEN 0x88): 128 bytes, the first four the image
    length big-endian, the rest 0. Length 0 gives the end-of-batch block (all zero)."""
    _check_id(servo_id)
    if not 0 <= length <= 0xFFFFFFFF:
        raise ValueError("image length %r does not fit in 32 bits" % (length,))
    return _block(servo_id, UPDATE_HEADER, 0, length.to_bytes(4, "big"),
                  UPDATE_HEADER_DATA, 0x88)


def update_data(servo_id, number, data):
    """Data block number (1, 2, ...; LEN 0xFF, the frame is fixed at 1031 bytes after
    LEN): 1024 bytes, a short last block padded with 0xFF."""
    _check_id(servo_id)
    return _block(servo_id, UPDATE_DATA, number, data, UPDATE_BLOCK_DATA, 0xFF)


def update_eof(servo_id):
    """`D5 5D ID 04 FF FE 04 CHK`: end of file."""
    _check_id(servo_id)
    return _frame(bytes([servo_id, 4, CUSTOM, UPDATE_BLOCK, UPDATE_EOF]))


def update_end(servo_id):
    """End of batch: a header block whose 128 bytes are all 0."""
    return update_header(servo_id, 0)


def update_frames(servo_id, image):
    """Every frame of one update, in order: (step name, frame, data bytes it carries)."""
    image = bytes(image)
    out = [("enter", update_enter(servo_id), 0),
           ("header block", update_header(servo_id, len(image)), 0)]
    for i in range(0, len(image), UPDATE_BLOCK_DATA):
        n = i // UPDATE_BLOCK_DATA + 1
        chunk = image[i:i + UPDATE_BLOCK_DATA]
        out.append(("data block %d" % n, update_data(servo_id, n, chunk), len(chunk)))
    out.append(("end of file", update_eof(servo_id), 0))
    out.append(("end of batch", update_end(servo_id), 0))
    return out
