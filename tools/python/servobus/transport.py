"""Byte transports under a Bus: a serial port (pyserial, imported only when used), a
serial port on a network server speaking RFC 2217 (rfc2217://HOST:PORT: ser2net, or
servo-sim, which then models the baud rate), or a raw TCP connection to servo-sim (or to
anything else that carries the bus over TCP, with no baud rate)."""

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
    """A serial device (USB-RS485/TTL adapter), 8N1, or a pyserial URL for one:
    rfc2217://HOST:PORT is a serial port on a Telnet COM-PORT-CONTROL server (ser2net,
    servo-sim). Both have a real baud rate, which set_baud changes on the port."""

    is_tcp = False

    def __init__(self, device, baud):
        try:
            import serial  # pyserial, only needed for real ports
        except ImportError:
            raise ServoBusError(
                "serial ports and rfc2217:// need pyserial: apt-get install python3-serial "
                "(or pip install pyserial); tcp:// addresses work without it") from None
        self._serial = serial
        self.url = device
        self.baud = baud
        self.remote = "://" in device
        try:
            if self.remote:  # no write time-out: pyserial's rfc2217 does not support one
                self.port = serial.serial_for_url(device, baudrate=baud, bytesize=8,
                                                  parity="N", stopbits=1, timeout=0)
            else:
                self.port = serial.Serial(device, baud, bytesize=8, parity="N", stopbits=1,
                                          timeout=0, write_timeout=2)
        except (serial.SerialException, ValueError) as e:
            hint = ""
            if self.remote:
                hint = (" — is servo-sim (or ser2net) running there? servo-sim serves one "
                        "client at a time: is another one connected?")
            raise ServoBusError("cannot open %s: %s%s" % (device, e, hint)) from None

    def _lost(self, e):
        return ServoBusError("lost the connection to %s: %s" % (self.url, e))

    def set_baud(self, baud):
        self.baud = baud
        try:
            self.port.baudrate = baud
        except (self._serial.SerialException, ValueError) as e:
            raise ServoBusError("%s did not take %d baud: %s" % (self.url, baud, e)) from None

    def write(self, data):
        try:
            self.port.write(data)
            self.port.flush()
        except self._serial.SerialException as e:
            raise self._lost(e) from None

    def read(self, deadline):
        remaining = deadline - time.monotonic()
        if remaining <= 0:
            return b""
        try:
            self.port.timeout = remaining
            data = self.port.read(1)
            if data and self.port.in_waiting:
                data += self.port.read(self.port.in_waiting)
        except self._serial.SerialException as e:
            raise self._lost(e) from None
        return data

    def flush_input(self):
        """Drop whatever has arrived and not been read (late answers, noise). Over
        rfc2217:// what has reached this side is dropped: a PURGE round trip to the
        server would cost 50 ms per transaction in pyserial."""
        try:
            if not self.remote:
                self.port.reset_input_buffer()
                return
            while self.port.in_waiting:
                self.port.read(self.port.in_waiting)
        except self._serial.SerialException as e:
            raise self._lost(e) from None

    def close(self):
        self.port.close()


def open_transport(port, baud):
    """tcp://HOST:PORT, rfc2217://HOST:PORT or a serial device path."""
    if port.startswith("tcp://"):
        return TcpTransport(port, baud)
    if port.startswith("rfc2217://"):
        return SerialTransport(port, baud)
    if "://" in port:
        raise ServoBusError("unknown bus address '%s': use tcp://HOST:PORT, "
                            "rfc2217://HOST:PORT or a serial device such as /dev/ttyUSB0"
                            % port)
    return SerialTransport(port, baud)
