"""servoctl update: the image checked before the bus is opened, a progress bar, the
version after."""

import os
import stat
import sys
import time

from .. import image as I
from ..errors import ServoBusError
from .common import PROG, UsageError


class Progress:
    """A progress bar on stderr: blocks sent / total and bytes."""

    WIDTH = 30

    def __init__(self, stream=sys.stderr):
        self.stream = stream
        self.tty = stream.isatty()
        self.start = time.monotonic()
        self.open = False  # a line without its newline on the terminal

    def close(self):
        if self.open:
            self.stream.write("\n")
            self.open = False

    def __call__(self, done, total, nbytes, total_bytes):
        filled = self.WIDTH * done // total if total else self.WIDTH
        line = "[%s%s] %2d/%d blocks, %6d/%d bytes, %4.1f s" % (
            "#" * filled, "." * (self.WIDTH - filled), done, total, nbytes, total_bytes,
            time.monotonic() - self.start)
        if self.tty:
            self.stream.write("\r" + line)
            self.open = True
            if done == total:
                self.close()
        elif done == 0 or done == total or done % 4 == 0:
            self.stream.write(line + "\n")  # a log: not every block
        self.stream.flush()


def prepare_update(args):
    """Before the bus is opened: read the image (a regular file, at most one byte more
    than the largest image) and (unless --no-check) validate it."""
    try:
        st = os.stat(args.file)
        if not stat.S_ISREG(st.st_mode):
            raise UsageError("%s is not a regular file (a device, FIFO or directory): "
                              "give the image file" % args.file)
        if st.st_size > I.MAX_BYTES + 1:
            raise UsageError("%s has %d bytes: larger than any image (%d bytes at most)"
                              % (args.file, st.st_size, I.MAX_BYTES))
        with open(args.file, "rb") as f:
            args.data = f.read(I.MAX_BYTES + 1)
    except OSError as e:
        raise UsageError("cannot read %s: %s" % (args.file, e.strerror or e)) from None
    if not args.data:
        raise UsageError("%s is empty (0 bytes): not an image" % args.file)
    args.info = None if args.no_check else I.validate(args.data)


def cmd_update(bus, args):
    if args.info is not None:
        print("%s: %s" % (args.file, args.info.describe()), file=sys.stderr)
        try:
            if bus.present(args.id):
                print("ID %d runs firmware version %d" % (
                    args.id, bus.read(args.id, "firmware_version")), file=sys.stderr)
        except ServoBusError:
            pass
    t0 = time.monotonic()
    bar = Progress()
    try:
        version = bus.update(args.id, args.data, progress=bar, retries=args.retries,
                             check=not args.no_check,
                             notify=lambda text: print("%s: note: %s" % (PROG, text),
                                                       file=sys.stderr))
    finally:
        bar.close()
    if version is None:
        print("ID %d: updated in %.1f s; it answers PING (its firmware version cannot be "
              "read: status return level 0)" % (args.id, time.monotonic() - t0))
    else:
        print("ID %d: updated in %.1f s, now runs firmware version %d" % (
            args.id, time.monotonic() - t0, version))
    return 0
