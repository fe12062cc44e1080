"""The Bus: one host on one servo bus (a serial port or servo-sim over TCP).

Bus is composed by concern: Link (transport and transactions: link.py), Discovery (scan,
two servos on one ID, update mode: discovery.py), Control (the control table:
control.py), Identity (IDs, the ID checks, factory reset: identity.py), Protection
(settings that lock a host out, clearing an unload: protection.py), Motion (motion.py)
Ids (every servo by its unique identity: enumerate, set an ID by UID, separate
duplicates, adopt a replacement: ids.py) and Update (firmware update, §10: update.py).
Everything is reached as a method of Bus."""

from .control import Control
from .discovery import Discovery
from .identity import Identity
from .ids import Ids
from .link import Found, Link
from .motion import HOMING_STATES, HomingStatus, Motion
from .protection import Protection
from .update import RESTART_TIMEOUT_S, UPDATE_WORK_S, Update, UpdateStats

__all__ = ["Bus", "Found", "HomingStatus", "UpdateStats", "HOMING_STATES",
           "RESTART_TIMEOUT_S", "UPDATE_WORK_S"]


class Bus(Update, Motion, Protection, Ids, Identity, Control, Discovery, Link):
    """A servo bus.

    Bus('tcp://127.0.0.1:4242') talks to servo-sim; Bus('/dev/ttyUSB0', baud=115200) to
    a USB-RS485 adapter (pyserial). `timeout` (seconds) overrides the answer time-out
    computed from the baud rate. With raise_faults=False, live fault bits (temperature,
    current, voltage, stall) in an answer do not raise; they are kept in `faults`."""
