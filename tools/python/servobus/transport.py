"""Byte transports under a Bus: a serial port (pyserial, imported only when used) or a
TCP connection to servo-sim (or to anything else that carries the bus over TCP)."""

import socket
import time

from .errors import ServoBusError


class TcpTransport:
    """tcp://HOST:PORT. TCP has no baud rate: `baud` only sizes time-outs and windows."""

    is_tcp = True

    def __init__(self, url, baud, connect_timeout=3.0):
        self.url = url
        self.baud = baud
        host, sep, port = url[len("tcp://"):].rpartition(":")
        if not sep or not host or not port.isdigit():
            raise ServoBusError("bad bus address '%s': expected tcp://HOST:PORT" % url)
        try:
            self.sock = socket.create_connection((host, int(port)), timeout=connect_timeout)
        except OSError as e:
            raise ServoBusError(
                "cannot connect to %s: %s — is servo-sim running? start it with "
                "`build/host/servo-sim --listen %s:%s`" % (url, e.strerror or e, host, port)
            ) from None
        self.sock.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)

    def set_baud(self, baud):
        self.baud = baud

    def write(self, data):
        try:
            self.sock.sendall(data)
        except OSError as e:
            raise ServoBusError("lost the connection to %s: %s" % (self.url, e)) from None

    def read(self, deadline):
        """Bytes that arrive before deadline (time.monotonic()); b'' when none did."""
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return b""
        self.sock.settimeout(remaining)
        try:
            data = self.sock.recv(4096)
        except socket.timeout:
            return b""
        except ConnectionResetError:
            data = b""
        except OSError as e:
            raise ServoBusError("lost the connection to %s: %s" % (self.url, e)) from None
        if not data:
            raise ServoBusError(
                "%s closed the connection (servo-sim serves one client at a time: is "
                "another one connected?)" % self.url)
        return data

    def flush_input(self):
        """Drop whatever has arrived and not been read (late answers, noise)."""
        self.sock.setblocking(False)
        try:
            while self.sock.recv(4096):
                pass
        except (BlockingIOError, InterruptedError):
            pass
        except OSError:
            pass
        finally:
            self.sock.setblocking(True)

    def close(self):
        self.sock.close()


class SerialTransport:
    """A serial device (USB-RS485/TTL adapter), 8N1."""

    is_tcp = False

    def __init__(self, device, baud):
        try:
            import serial  # pyserial, only needed for real ports
        except ImportError:
            raise ServoBusError(
                "serial ports need pyserial: apt-get install python3-serial (or pip "
                "install pyserial); tcp:// addresses work without it") from None
        self.url = device
        self.baud = baud
        try:
            self.port = serial.Serial(device, baud, bytesize=8, parity="N", stopbits=1,
                                      timeout=0, write_timeout=2)
        except (serial.SerialException, ValueError) as e:
            raise ServoBusError("cannot open %s: %s" % (device, e)) from None

    def set_baud(self, baud):
        self.baud = baud
        self.port.baudrate = baud

    def write(self, data):
        self.port.write(data)
        self.port.flush()

    def read(self, deadline):
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return b""
        self.port.timeout = remaining
        data = self.port.read(1)
        if data and self.port.in_waiting:
            data += self.port.read(self.port.in_waiting)
        return data

    def flush_input(self):
        self.port.reset_input_buffer()

    def close(self):
        self.port.close()


def open_transport(port, baud):
    """tcp://HOST:PORT or a serial device path."""
    if port.startswith("tcp://"):
        return TcpTransport(port, baud)
    if "://" in port:
        raise ServoBusError("unknown bus address '%s': use tcp://HOST:PORT or a serial "
                            "device such as /dev/ttyUSB0" % port)
    return SerialTransport(port, baud)
