"""Exceptions of the servo bus SDK. Every one derives from ServoBusError and carries a
message that says what happened and what to check."""

from .protocol import ERR_CHECKSUM, ERR_INSTRUCTION, describe_err


class ServoBusError(Exception):
    """Base class of everything the SDK raises about the bus or a servo."""


class BusTimeout(ServoBusError):
    """No (complete) status packet arrived in time. update_mode: True when the servo
    was found waiting in its bootloader's update mode (the message says so)."""

    update_mode = False

    def __init__(self, message, servo_id=None):
        super().__init__(message)
        self.servo_id = servo_id


class Interrupted(ServoBusError):
    """A job cut short because the Bus's stop_event was set (Servo Studio's STOP): at
    the next packet boundary, before anything more was sent. written: the registers a
    write of several (Bus.write_many) had written before it was cut short, and
    unwritten: the ones it had not ({name: value}; empty for other jobs)."""

    written = {}
    unwritten = {}


class ProtocolError(ServoBusError):
    """A status packet arrived but is malformed or corrupt."""


class RangeError(ServoBusError, ValueError):
    """A value refused before anything was sent: out of its range, not a number, not a
    whole number, the wrong type, missing (servobus/values.py words it)."""


class UnknownRegister(ServoBusError, KeyError):
    """No register of that name or address."""

    def __str__(self):  # KeyError would quote the message
        return str(self.args[0])


class IdTaken(ServoBusError):
    """set_id() refused: another servo already answers at the new ID."""


class DuplicateId(ServoBusError):
    """Two (or more) servos answer at one ID: anything sent to it reaches both."""


class DuplicateUid(ServoBusError):
    """Two (or more) servos report one unique ID (a cloned or copied part): ENUMERATE
    cannot tell them apart. found: every servo that enumerate() could tell apart; uids:
    the shared UIDs as text (24 hex digits; "?" for a digit garbled answers hid)."""

    def __init__(self, message, found=(), uids=()):
        super().__init__(message)
        self.found = list(found)
        self.uids = list(uids)


class NotApplied(ServoBusError):
    """A servo that does not answer writes (status return level 0 or 1) did not take
    one: reading back showed the old value."""


class StatusError(ServoBusError):
    """A status packet whose ERR byte reports a problem.

    Attributes: servo_id, err (the ERR byte), bits (list of bit names), what (the
    request), params (the answer's parameters, if any)."""

    def __init__(self, servo_id, err, what, hint="", params=b""):
        self.servo_id = servo_id
        self.err = err
        self.what = what
        self.params = params
        self.bits = describe_err(err)
        self.hint = hint
        message = "ID %d %s %s (ERR 0x%02X: %s)" % (
            servo_id, self.verb, what, err, ", ".join(self.bits))
        if hint:
            message += ": " + hint
        super().__init__(message)

    verb = "reports a problem with"


class InstructionError(StatusError):
    """ERR bit 5: the servo refused the instruction; nothing of it was applied."""

    verb = "refused"


class MotionRefused(InstructionError):
    """ERR bit 5 on a motion instruction (trajectory action, custom move, start/end,
    homing): the servo cannot run that motion now."""


class ChecksumError(StatusError):
    """ERR bit 4: the servo received the packet with a wrong checksum."""

    verb = "received a corrupted"


class ServoFault(StatusError):
    """ERR bits 0-3 or 6: a live condition (over-temperature, over-current, voltage,
    stall). The request itself was carried out; params holds the answer's data."""

    verb = "reports a fault while answering"


def status_error(servo_id, err, what, hint="", params=b"", motion=False):
    """The exception for an ERR byte, most serious first (instruction, checksum, fault)."""
    if err & ERR_INSTRUCTION:
        return (MotionRefused if motion else InstructionError)(servo_id, err, what, hint)
    if err & ERR_CHECKSUM:
        return ChecksumError(servo_id, err, what,
                             "noise on the wire: check wiring, termination (register 20) "
                             "and that the host and the servo use the same baud rate")
    # A fault bit is a live condition, not a refusal of this request: the request's
    # refusal hint does not apply to it.
    return ServoFault(servo_id, err, what, "the request was carried out; a protection "
                      "that unloaded stays latched (torque off, motion refused) until the "
                      "cause is gone and clear_unload 1 is written", params)


class UpdateError(ServoBusError):
    """A firmware update (§10) that did not complete. Attributes: servo_id, step (the
    frame concerned: "enter", "header block", "data block 3", "end of file", "end of
    batch", "restart")."""

    def __init__(self, message, servo_id=None, step=None):
        super().__init__(message)
        self.servo_id = servo_id
        self.step = step


class UpdateRefused(UpdateError):
    """The servo answered CAN (0x18): it abandoned the update (image too large, for
    another model, failed its CRC check, flash error) and keeps its running image."""


class UpdateTimeout(UpdateError, BusTimeout):
    """No answer to an update frame after every retry."""
