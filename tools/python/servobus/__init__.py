"""servobus: host SDK for the D5 5D smart bus servos (PROTOCOL.md), on a serial port or
on servo-sim over TCP.

    from servobus import Bus
    with Bus("tcp://127.0.0.1:4242") as bus:
        print(bus.scan())
        bus.write(1, "goal_position", 90)
        bus.update(1, open("app.bin", "rb").read())   # firmware update, §10
"""

from .bus import Bus, Found, HomingStatus, UpdateStats
from .errors import (BusTimeout, ChecksumError, DuplicateId, DuplicateUid, IdTaken,
                     InstructionError, Interrupted, MotionRefused, NotApplied, ProtocolError,
                     RangeError, ServoBusError, ServoFault, StatusError, UnknownRegister, UpdateError,
                     UpdateRefused, UpdateTimeout)
from .image import ImageError
from .protocol import BROADCAST
from .registers import REGISTERS, VARIANTS, register

__all__ = [
    "Bus", "Found", "HomingStatus", "UpdateStats", "BROADCAST", "REGISTERS", "VARIANTS",
    "register",
    "ServoBusError", "BusTimeout", "ProtocolError", "RangeError", "UnknownRegister",
    "IdTaken", "DuplicateId", "DuplicateUid", "NotApplied", "Interrupted", "StatusError",
    "InstructionError", "MotionRefused", "ChecksumError",
    "ServoFault", "UpdateError", "UpdateRefused", "UpdateTimeout", "ImageError",
]
__version__ = "0.1.0"
