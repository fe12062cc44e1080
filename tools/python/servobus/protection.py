"""Settings that lock a host out, and clearing a latched protection unload (§7.2).

One rule set for servoctl (`--force`) and Servo Studio (a confirmation): lockout()
says, before anything is sent, which settings would leave the servo unreachable or
unloaded as it is being talked to now. clear_unload() writes register 25 and tries
again for as long as the firmware can take to see the cause gone."""

import time

from . import protocol as P
from . import values as V
from .errors import InstructionError, Interrupted, ServoBusError
from .link import check_id
from .registers import baud_of_code, register

# src/safety.c: a latched unload may be cleared only once its condition is gone, and a
# condition counts as present until its leaky accumulator has drained, one count per
# 1 kHz control tick. Temperature trips at TEMP_TRIP = 2000 counts, so a servo may see
# the cause for up to 2.0 s after it has gone (voltage: 200 counts, 0.2 s; current and
# stall: at once). docs/safety.md, "Protection".
SAFETY_DRAIN_S = 2000 / 1000.0
# How long a refused clear is tried again: twice the drain, plus 0.5 s for a host or a
# servo-sim that runs late (servo-sim's clock jumps after a 200 ms stall, losing ticks).
CLEAR_WINDOW_S = 2 * SAFETY_DRAIN_S + 0.5
CLEAR_RETRY_S = 0.1


class Protection:
    """Lock-out rules and the unload clear (a mixin of Bus: it uses Control)."""

    clear_took = None  # seconds the last clear_unload() took (retries included)

    def lockout(self, servo_id, values):
        """The settings of {register name: value} after which this host could no longer
        reach servo_id as it is talking to it now, or the servo would unload at once:
        a list of sentences, one per setting, each with the way back. Empty: none.
        Reads the servo where a rule needs it (its temperature, its variant)."""
        check_id(servo_id)
        values = {register(k).name: v for k, v in V.mapping(values, "settings").items()}
        reasons = []
        if values.get("status_return_level") == 0:
            reasons.append(
                "status_return_level 0: ID %d would answer nothing but PING, so reads time "
                "out and writes go unconfirmed (writing status_return_level 2 brings it "
                "back)" % servo_id)
        if "temperature_limit" in values:
            now = self.read(servo_id, "present_temperature")
            if values["temperature_limit"] <= now:
                reasons.append(
                    "temperature_limit %d C: ID %d is at %d C now, so it would unload at "
                    "once (over-temperature: torque off, motion refused) until the limit "
                    "is raised and the unload cleared (clear_unload 1)" % (
                        values["temperature_limit"], servo_id, now))
        if "baud_rate" in values:
            try:
                variant = self.variant(servo_id)
            except Interrupted:  # a STOP goes through every check
                raise
            except ServoBusError:
                variant = None
            baud = baud_of_code(values["baud_rate"], variant)
            if baud != self.baud:
                reasons.append(
                    "baud_rate %d: ID %d would then answer at %d baud only, and this host "
                    "talks at %d" % (values["baud_rate"], servo_id, baud, self.baud))
        return reasons

    def clear_unload(self, servo_id, window=CLEAR_WINDOW_S):
        """Write 1 to register 25 (clear_unload). The servo refuses it while it still
        sees the cause, which it may do for up to SAFETY_DRAIN_S after the cause has
        gone: a refusal with a fault bit is tried again every CLEAR_RETRY_S for `window`
        seconds. Returns the seconds it took; InstructionError saying the cause is still
        there after the window. A Bus's stop_event cuts the waiting short."""
        check_id(servo_id)
        V.seconds(window, "window", 0.0, 3600.0)
        start = time.monotonic()
        self.clear_took = None
        while True:
            try:
                self.write(servo_id, "clear_unload", 1)
                if self.confirmed or not self.ping(servo_id) & P.ERR_FAULTS:
                    self.clear_took = time.monotonic() - start
                    return self.clear_took
                err = P.ERR_INSTRUCTION | self.last_err  # silent servo, fault still live
            except InstructionError as e:
                if not e.err & P.ERR_FAULTS:
                    raise  # refused for another reason (an update session): said in e
                err = e.err
            if time.monotonic() - start >= window:
                raise InstructionError(
                    servo_id, err, "WRITE clear_unload=1",
                    "the cause (%s) is still there %.1f s later (a servo sees a cause "
                    "gone within %.1f s): remove it — e.g. raise temperature_limit above "
                    "the present temperature — then clear again" % (
                        ", ".join(P.describe_err(err & P.ERR_FAULTS)),
                        time.monotonic() - start, SAFETY_DRAIN_S))
            self.pause(CLEAR_RETRY_S)
