"""A raw HTTP client for the studio (http.client: every header as the test says, none
added), and what the wire tap in front of servo-sim saw."""

import http.client
import json
import time

from servobus import protocol as P

# The studio's live sampling of the selected servo: the READs (first, count) it sends
# whatever the user does (studio/sampler.py).
SAMPLER_READS = {(24, 26), (30, 17), (0, 50)}


class Api:
    """Requests to a studio at host:port with its token (unless told otherwise)."""

    def __init__(self, studio):
        self.studio = studio
        self.host, port = studio.listen.rsplit(":", 1)
        self.port = int(port)
        self.token = studio.token

    def request(self, method, path, body=None, headers=None, token=True, timeout=30):
        """(status, the JSON answer or the text) of one request. body: a dict or list
        (sent as JSON), bytes or str (sent as they are)."""
        h = {"Host": "%s:%d" % (self.host, self.port)}
        if token:
            h["X-Studio-Token"] = self.token
        if isinstance(body, (dict, list)):
            body = json.dumps(body)
            h["Content-Type"] = "application/json"
        h.update(headers or {})
        conn = http.client.HTTPConnection(self.host, self.port, timeout=timeout)
        try:
            conn.putrequest(method, path, skip_host=True, skip_accept_encoding=True)
            for k, v in h.items():
                if v is not None:
                    conn.putheader(k, v)
            data = body.encode() if isinstance(body, str) else body
            if data is not None:
                conn.putheader("Content-Length", str(len(data)))
            conn.endheaders(data)
            r = conn.getresponse()
            text = r.read().decode("utf-8", "replace")
        finally:
            conn.close()
        try:
            return r.status, json.loads(text)
        except ValueError:
            return r.status, text

    def post(self, path, body=None, headers=None, **kw):
        """POST body (JSON unless headers say another Content-Type, or None for none)."""
        h = {"Content-Type": "application/json"}
        h.update(headers or {})
        return self.request("POST", path, {} if body is None else body, headers=h, **kw)

    def state(self):
        status, st = self.request("GET", "/api/state")
        assert status == 200, st
        return st

    def wait(self, predicate, timeout=20.0, what="the condition"):
        """Poll the state until predicate(state) is true; that state."""
        deadline = time.monotonic() + timeout
        st = None
        while time.monotonic() < deadline:
            st = self.state()
            if predicate(st):
                return st
            time.sleep(0.05)
        raise AssertionError("timed out waiting for %s (state: %r)" % (what, st))


def not_sampling(tap, mark=0):
    """The packets that reached servo-sim since mark other than the studio's live
    sampling READs: what the user's actions (or a forged request) put on the wire."""
    out = []
    for t, raw in tap.packets(mark):
        if raw[4] == P.READ and len(raw) == 8 and (raw[5], raw[6]) in SAMPLER_READS:
            continue
        out.append((t, raw))
    return out


def writes_to(tap, address, mark=0, servo_id=None):
    """(time, data) of each WRITE to address since mark (to servo_id, or any)."""
    return [(t, raw[6:-1]) for t, raw in tap.packets(mark)
            if raw[4] == P.WRITE and raw[5] == address and
            (servo_id is None or raw[2] == servo_id)]


# A studio whose start-up scan found n servos and is free again.
def ready(t, n):
    return t.api.wait(lambda st: len(st["servos"]) == n and not st["busy"] and
                      st["selected"] is not None, what="the start-up scan")
