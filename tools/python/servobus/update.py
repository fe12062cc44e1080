"""Firmware update over the bus (PROTOCOL.md §10): the frames, their answers and
retries, and the servo's restart into the new image."""

import sys
import time
from collections import namedtuple

from . import image as I
from . import protocol as P
from . import values as V
from .errors import (BusTimeout, Interrupted, RangeError, ServoBusError, UpdateError,
                     UpdateRefused, UpdateTimeout)
from .discovery import IN_UPDATE_MODE
from .link import check_id

UpdateStats = namedtuple("UpdateStats",
                         "frames resent bytes_out bytes_in transfer_s restart_s")

_CAN_REASONS = {
    "enter": "it cannot start an update now",
    "header block": "the image length does not fit its application slot (%d..%d bytes)" % (
        I.MIN_BYTES, I.MAX_BYTES),
    "data block 1": "the image's info block is not for this servo (another model, or a "
                    "length that differs from the header block), or a flash error",
    "data block": "a flash error, or more blocks than the header block announced",
    "end of file": "fewer blocks arrived than the header block announced (truncated image)",
    "end of batch": "the image it received failed its check (CRC-32, model or length: a "
                    "corrupt or truncated image)",
}
# Time the servo may spend on an update frame before answering: erase, program and read
# back a 1 KiB flash page; the CRC-32 of the whole image at the end of the batch.
UPDATE_WORK_S = 0.2
# After the end of batch: seconds to wait for the restarted servo (the bootloader copies
# the image, up to 26 pages, before starting it).
RESTART_TIMEOUT_S = 10.0


class Update:
    """Firmware update (a mixin of Bus: it uses Link's transport and transactions)."""

    def update_timeout(self, frame_bytes):
        """Seconds to wait for the answer to an update frame of frame_bytes: the frame and
        its answer on the wire, the longest return delay, the servo's flash work, slack.
        Bus(timeout=...) overrides it."""
        V.strict_integer(frame_bytes, "frame bytes", 0, 0x10000)
        if self.timeout is not None:
            return self.timeout
        return (P.MAX_RETURN_DELAY_S + (frame_bytes + P.UPDATE_ANSWER_BYTES) *
                P.byte_time(self.baud) + UPDATE_WORK_S + self.slack())

    def update(self, servo_id, image, progress=None, retries=5, check=True,
               restart_timeout=RESTART_TIMEOUT_S, notify=None):
        """Send a firmware image to servo_id over the bus (PROTOCOL.md §10) and return the
        firmware version (register 2) the servo reports after restarting into it.

        image: the bytes of a stamped image (tools/fwstamp.py). With check (default) it is
        validated first (magic, length, CRC-32, size: ImageError, nothing sent), and if
        the servo answers PING its model number must match the image's (ImageError). A
        servo that does not answer PING may be in its bootloader, which answers only the
        update frames: the update goes ahead (notify says so). check=False sends the
        bytes as they are (the servo then makes its own checks).

        progress(blocks_done, blocks_total, bytes_done, bytes_total) is called before the
        first data block and after each one. A frame that is not answered in time
        (update_timeout) or answered NAK is sent again, `retries` times at most
        (UpdateTimeout, UpdateError). A CAN answer raises UpdateRefused: the servo
        abandoned the update and runs its old firmware. notify(text) receives notes
        (default: printed on stderr). Afterwards `update_stats` holds an UpdateStats:
        frames sent (resent: how many were repeats), bytes_out (frames, repeats
        included), bytes_in (the answers taken), transfer_s (enter to the end-of-batch
        answer) and restart_s (from there to the version read)."""
        check_id(servo_id)
        image = _image_bytes(image)
        if isinstance(retries, bool) or not isinstance(retries, int) or \
                not 0 <= retries <= 100:
            raise RangeError("retries %r: give 0..100" % (retries,))
        for name, fn in (("progress", progress), ("notify", notify)):
            if fn is not None and not callable(fn):
                raise RangeError("%s: %r is not a function (or None)" % (name, fn))
        V.seconds(restart_timeout, "restart time-out", 0.0, 3600.0)
        if notify is None:
            def notify(text):
                print("servobus: note: " + text, file=sys.stderr)
        self.update_step = None
        self.update_mode = False
        info = I.validate(image) if check else None
        self._before_update(servo_id, image, check, notify)
        expect_version = info.version if info is not None else _version_of(image)
        t0 = time.monotonic()
        self._send_image(servo_id, image, retries, progress)
        t1 = time.monotonic()
        self.update_step = "restart"
        self._variants.pop(servo_id, None)
        self._levels.pop(servo_id, None)
        version = self._await_restart(servo_id, restart_timeout, expect_version)
        self.update_step = None
        self.commit_budget.restarted(self.budget_key(servo_id))  # full after a restart
        self.update_stats = UpdateStats(*self._ustats, transfer_s=t1 - t0,
                                        restart_s=time.monotonic() - t1)
        return version

    def _before_update(self, servo_id, image, check, notify):
        """Is the servo there, and is the image for its model (with check)? A servo
        that does not answer PING may wait in update mode: notify says so, and the
        update goes ahead either way."""
        # Two PINGs with the full time-out: one lost answer does not skip the model check
        # (a late answer is drained before the next request, never taken for it).
        if any(self.present(servo_id, timeout=self.full_answer_time()) for _ in range(2)):
            if check:
                try:
                    saved, self.timeout = self.timeout, None
                    model = self.read(servo_id, "model_number")
                except BusTimeout:
                    notify("ID %d answers PING but not READ (status return level 0): its "
                           "model is not compared with the image's; the servo checks it "
                           "itself" % servo_id)
                else:
                    I.validate(image, model)
                finally:
                    self.timeout = saved
        elif self.in_update_mode(servo_id):
            self.update_mode = True
            notify("ID %d does not answer PING but answers the update handshake: %s; a "
                   "good image brings it back" % (servo_id, IN_UPDATE_MODE))
        else:
            notify("ID %d answers neither PING nor the update handshake at %d baud: "
                   "trying the update all the same" % (servo_id, self.baud))

    def _send_image(self, servo_id, image, retries, progress):
        """Every §10 frame of the image, each until it is answered, with progress."""
        frames = P.update_frames(servo_id, image)
        blocks = sum(1 for step, _, _ in frames if step.startswith("data block"))
        done = sent = 0
        self._ustats = [0, 0, 0, 0]  # frames, resent, bytes out, bytes in
        self.update_stats = None
        if progress:
            progress(0, blocks, 0, len(image))
        for step, frame, nbytes in frames:
            self.update_step = step  # what Ctrl-C interrupts (servoctl says so)
            self._update_step(servo_id, step, frame, retries)
            if nbytes:
                done += 1
                sent += nbytes
                if progress:
                    progress(done, blocks, sent, len(image))

    def _update_step(self, servo_id, step, frame, retries):
        """Send one update frame until it is answered with the expected code: the
        StatusPacket. NAK or silence: send again, retries times at most."""
        expect = P.READY if step == "enter" else P.ACK
        naks = silent = 0
        last = ""
        for attempt in range(retries + 1):
            self._drain()
            self.check_stop()
            self._put(frame)
            self._ustats[0] += 1
            self._ustats[1] += attempt > 0
            self._ustats[2] += len(frame)
            pkt, why = self._update_answer(servo_id, frame)
            if pkt is None:
                silent += 1
                last = why
                continue
            code = pkt.params[0] if pkt.params else None
            if pkt.err & P.ERR_INSTRUCTION:
                raise UpdateError(
                    "ID %d answered the %s with an instruction error (%s): its firmware "
                    "does not take updates over the bus (§10)" % (
                        servo_id, "request to enter update mode" if step == "enter" else step,
                        pkt.raw.hex(" ")), servo_id, step)
            if code == expect:
                self._ustats[3] += len(pkt.raw)
                return pkt
            if code == P.CAN:
                reason = _CAN_REASONS.get(step) or _CAN_REASONS["data block"]
                raise UpdateRefused(
                    "ID %d refused the update at the %s (CAN): %s; it keeps its running "
                    "firmware" % (servo_id, step, reason), servo_id, step)
            naks += 1
            last = ("NAK" if code == P.NAK else
                    "a checksum error" if pkt.err & P.ERR_CHECKSUM else
                    "an unexpected answer (%s)" % pkt.raw.hex(" "))
        tries = retries + 1
        if not naks:
            hint = ("wrong ID or baud, or the servo is not on the bus" if step == "enter"
                    else "the servo stopped answering (power, wiring?); it abandons a "
                         "silent update after 10 s and keeps its running firmware — start "
                         "the update again")
            raise UpdateTimeout("no answer from ID %d %s to the %s after %d tries (%s) — %s"
                                % (servo_id, self._where(), step, tries, last, hint),
                                servo_id, step)
        raise UpdateError(
            "ID %d %s: the %s failed %d times (%d NAK or damaged answers, %d silent; last: "
            "%s) — noise on the wire: check wiring, termination (register 20) and the baud "
            "rate" % (servo_id, self._where(), step, tries, naks, silent, last),
            servo_id, step)

    def _update_answer(self, servo_id, sent):
        """(StatusPacket, None) for the first intact answer from servo_id to the update
        frame `sent`, or (None, why) at the time-out. An adapter's echo of `sent` is
        dropped (the echo of a data block would not parse as a status packet)."""
        parser = P.StatusParser()
        deadline = time.monotonic() + self.update_timeout(len(sent))
        echo = bytearray()  # what arrived while it could still be the echo of `sent`
        in_echo = True
        corrupt = None
        while True:
            try:
                data = self._read(deadline, parser)
            except Interrupted:
                self._late_until(sent, P.UPDATE_ANSWER_BYTES)
                raise
            if not data:
                if time.monotonic() >= deadline:
                    break
                continue
            if in_echo:
                echo += data
                if sent.startswith(bytes(echo)):
                    if len(echo) == len(sent):
                        in_echo = False
                    continue
                in_echo = False
                data = bytes(echo[len(sent):] if echo.startswith(sent) else echo)
            for pkt in parser.feed(data):
                if pkt.raw == sent:
                    continue
                if not pkt.ok:
                    corrupt = pkt
                elif pkt.id == servo_id and _update_answer_shape(pkt):
                    return pkt, None
        self._late_until(sent, P.UPDATE_ANSWER_BYTES)
        if corrupt is not None:
            return None, "a corrupt answer: %s" % corrupt.raw.hex(" ")
        if parser.pending():
            return None, "an incomplete answer: %s" % bytes(parser.buf).hex(" ")
        return None, "no answer within %.0f ms" % (self.update_timeout(len(sent)) * 1e3)

    def _await_restart(self, servo_id, timeout, expect_version):
        """After the end of batch: poll PING until the restarted servo answers, then its
        firmware version (register 2); until it is expect_version if that is known.
        None if it answers PING but not READ (status return level 0)."""
        deadline = time.monotonic() + timeout
        self.pause(0.02)  # the servo restarts once its last answer is out
        version = None
        while True:
            try:
                if self.present(servo_id):
                    version = self.read(servo_id, "firmware_version")
                    if expect_version is None or version == expect_version:
                        return version
            except BusTimeout:
                if self._levels.get(servo_id) == 0:  # PING answered, READ not
                    return None
            except Interrupted:  # a STOP goes through every check
                raise
            except ServoBusError:
                pass
            if time.monotonic() > deadline:
                break
            self.pause(0.05)
        if version is None:
            if self.in_update_mode(servo_id):
                self.update_mode = True
                raise UpdateError(
                    "ID %d took the image but does not start it: %s — send a good image "
                    "(`servoctl --id %d update FILE`)" % (servo_id, IN_UPDATE_MODE,
                                                          servo_id), servo_id, "restart")
            raise UpdateError(
                "ID %d took the image but does not answer PING %.0f s later: it may still "
                "be installing it — PING it again later, or repeat the update" % (
                    servo_id, timeout), servo_id, "restart")
        raise UpdateError(
            "ID %d took the image but restarted with firmware version %d, not the image's "
            "%d: its bootloader did not install it" % (servo_id, version, expect_version),
            servo_id, "restart")


def _update_answer_shape(pkt):
    """An answer to an update frame: 'C', ACK, NAK or CAN (ACK 'C' after the header block
    and the end of file), or an error answer without parameters."""
    if pkt.err & (P.ERR_INSTRUCTION | P.ERR_CHECKSUM) and not pkt.params:
        return True
    return pkt.err == 0 and 1 <= len(pkt.params) <= 2 and \
        pkt.params[0] in (P.READY, P.ACK, P.NAK, P.CAN)


def _image_bytes(image):
    """The image as bytes; RangeError for what is not bytes, ImageError if empty."""
    try:
        image = bytes(image)
    except (TypeError, ValueError):
        raise RangeError("the image is bytes, not %s" % type(image).__name__) from None
    if not image:
        raise I.ImageError("an empty image (0 bytes): nothing to send (its header "
                           "block would read as the end of batch)")
    return image


def _version_of(image):
    """The version the image's info block declares, or None (check=False on a file
    without one)."""
    try:
        return I.parse(image).version
    except I.ImageError:
        return None
