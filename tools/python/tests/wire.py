"""A tap on the wire: a TCP relay in front of servo-sim that records, with the time each
arrived, every byte a client sends to the servos. What a test sees here is what reached
servo-sim, not what the client believes it sent. It speaks both of servo-sim's client
kinds: raw tcp:// bytes, and rfc2217:// (Telnet), whose commands are taken out so that
only the bytes that go on the bus are kept."""

import selectors
import socket
import threading
import time

from servobus import protocol as P

IAC, SB, SE = 0xFF, 0xFA, 0xF0


class TelnetData:
    """Takes the Telnet commands out of a byte stream (RFC 854/2217): IAC IAC is a data
    0xFF, IAC SB ... IAC SE and IAC WILL/WONT/DO/DONT x are commands."""

    def __init__(self):
        self.state = "data"

    def feed(self, chunk):
        out = bytearray()
        for b in chunk:
            if self.state == "data":
                if b == IAC:
                    self.state = "iac"
                else:
                    out.append(b)
            elif self.state == "iac":
                if b == IAC:
                    out.append(IAC)
                    self.state = "data"
                elif b == SB:
                    self.state = "sb"
                elif 0xFB <= b <= 0xFE:
                    self.state = "option"
                else:
                    self.state = "data"
            elif self.state == "option":
                self.state = "data"
            elif self.state == "sb":
                self.state = "sb-iac" if b == IAC else "sb"
            elif self.state == "sb-iac":
                self.state = "data" if b == SE else "sb"
        return bytes(out)


class WireTap:
    """Listens on 127.0.0.1:port and relays one client at a time to servo-sim at
    sim_port. .url / .rfc2217_url are the addresses to give the client."""

    def __init__(self, sim_port):
        self.sim_port = sim_port
        self.lock = threading.Lock()
        self.chunks = []  # (monotonic time, bytes on the bus) from the client
        self.replies = []  # (monotonic time, bytes) from servo-sim to the client
        self.server = socket.socket()
        self.server.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.server.bind(("127.0.0.1", 0))
        self.server.listen(4)
        self.port = self.server.getsockname()[1]
        self.closing = False
        self.thread = threading.Thread(target=self._serve, daemon=True)
        self.thread.start()

    url = property(lambda self: "tcp://127.0.0.1:%d" % self.port)
    rfc2217_url = property(lambda self: "rfc2217://127.0.0.1:%d" % self.port)

    def _serve(self):
        while not self.closing:
            try:
                client, _ = self.server.accept()
            except OSError:
                return
            sim = socket.create_connection(("127.0.0.1", self.sim_port))
            for s in (client, sim):
                s.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)
            self._relay(client, sim)

    def _relay(self, client, sim):
        telnet = None  # decided by the first bytes, as servo-sim does
        sel = selectors.DefaultSelector()
        sel.register(client, selectors.EVENT_READ, sim)
        sel.register(sim, selectors.EVENT_READ, client)
        try:
            while not self.closing:
                for key, _ in sel.select(timeout=0.2):
                    data = key.fileobj.recv(65536)
                    if not data:
                        return
                    key.data.sendall(data)
                    if key.fileobj is sim:
                        with self.lock:
                            self.replies.append((time.monotonic(), data))
                    if key.fileobj is client:
                        if telnet is None:
                            telnet = TelnetData() if data[0] == IAC else False
                        bus = telnet.feed(data) if telnet else data
                        if bus:
                            with self.lock:
                                self.chunks.append((time.monotonic(), bus))
        except OSError:
            return
        finally:
            sel.close()
            client.close()
            sim.close()

    def mark(self):
        """A position in the record: what arrives later is after(mark)."""
        with self.lock:
            return len(self.chunks)

    def after(self, mark=0):
        """The bytes that reached servo-sim since mark."""
        with self.lock:
            return b"".join(c for _, c in self.chunks[mark:])

    def packets(self, mark=0):
        """(time of its last byte, packet bytes) of each instruction packet sent since
        mark."""
        with self.lock:
            chunks = list(self.chunks[mark:])
        parser = P.StatusParser()  # instruction packets share the status format
        out = []
        for t, data in chunks:
            out += [(t, pkt.raw) for pkt in parser.feed(data)]
        return out

    def answers(self):
        """Every status packet servo-sim sent the client (bytes), in order (raw
        tcp:// clients: no Telnet on this side)."""
        with self.lock:
            data = b"".join(c for _, c in self.replies)
        return [pkt.raw for pkt in P.StatusParser().feed(data)]

    def close(self):
        self.closing = True
        self.server.close()
        self.thread.join(timeout=2)
