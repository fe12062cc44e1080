"""Issue 26, security: only the studio's own page can drive it. Raw clients forge each
header the checks look at; what reached servo-sim is read from a tap in front of it
(not from the studio's own account). The browser's side is test_security_browser.py."""

import time

import pytest

from raw import not_sampling, writes_to
from servobus.registers import REGISTERS

SERVOS = ("1:arm", "2:foot")
GOAL = REGISTERS["goal_position"].address
# What a hostile page asks for: move the foot, and a firmware image.
MOVE = {"goal": 200, "speed": 90, "acc": 36, "dec": 36, "id": 2}
ENDPOINTS = ["/api/move", "/api/stop", "/api/write", "/api/select", "/api/scan",
             "/api/speed", "/api/home", "/api/traj", "/api/setid", "/api/reset",
             "/api/clear", "/api/update?id=2", "/api/console", "/api/dashboard",
             "/api/scope", "/api/group", "/api/plan", "/api/config/save",
             "/api/config/restore", "/api/config/diff", "/api/ids", "/api/separate",
             "/api/adopt"]


def scanned(t):
    """The studio's start-up scan done and the foot selected: only sampling READs
    from now on."""
    return t.api.wait(lambda st: len(st["servos"]) == 2 and not st["busy"] and
                      st["selected"] is not None, what="the start-up scan")


def forgeries(api):
    """(name, headers, token) of requests a hostile page or script could make."""
    host = "%s:%d" % (api.host, api.port)
    return [
        ("forged Origin", {"Origin": "http://evil.example"}, True),
        ("Origin of another local port", {"Origin": "http://127.0.0.1:1"}, True),
        ("null Origin", {"Origin": "null"}, True),
        ("forged Host (DNS rebinding)", {"Host": "evil.example:%d" % api.port}, True),
        ("forged Host, same port", {"Host": "attacker.test:%d" % api.port,
                                    "Origin": "http://attacker.test:%d" % api.port}, True),
        ("no token", {}, False),
        ("wrong token", {"X-Studio-Token": "x" * 32}, False),
        ("text/plain (a form, no preflight)", {"Content-Type": "text/plain"}, True),
        ("form-urlencoded", {"Content-Type": "application/x-www-form-urlencoded"}, True),
        ("multipart", {"Content-Type": "multipart/form-data; boundary=x"}, True),
        ("no Content-Type", {"Content-Type": None}, True),
        ("right Origin, wrong token", {"Origin": "http://" + host,
                                       "X-Studio-Token": "y" * 32}, False),
    ]


def test_every_forged_request_is_refused_and_nothing_reaches_the_wire(tapped):
    t = tapped(*SERVOS)
    scanned(t)
    start = t.tap.mark()
    for name, headers, token in forgeries(t.api):
        for path in ENDPOINTS:
            mark = t.tap.mark()
            status, answer = t.api.post(path, MOVE, headers=headers, token=token)
            assert status == 403, (name, path, status, answer)
            assert answer["ok"] is False and answer["error"].endswith("."), (name, answer)
            assert answer["sent"] is False
    time.sleep(0.3)  # a job queued by mistake would have gone out by now
    assert not_sampling(t.tap, start) == [], "forged requests reached servo-sim"
    # the control: the same request, as the studio's page sends it, reaches the wire
    mark = t.tap.mark()
    status, answer = t.api.post("/api/move", MOVE)
    assert status == 200, answer
    assert [d for _, d in writes_to(t.tap, GOAL, mark, servo_id=2)] == [bytes([200, 0, 90, 0,
                                                                               36, 36])]


def test_an_upload_needs_a_type_a_browser_cannot_send_cross_origin(tapped):
    t = tapped(*SERVOS)
    scanned(t)
    start = t.tap.mark()
    image = b"\x00" * 3000
    for ctype in ("text/plain", "application/json", None):
        status, answer = t.api.request("POST", "/api/update?id=2", image,
                                       headers={"Content-Type": ctype})
        assert status == 403 and "application/octet-stream" in answer["error"], answer
    time.sleep(0.3)
    assert not_sampling(t.tap, start) == []


def test_the_page_websocket_and_state_are_refused_to_other_origins_and_names(tapped):
    t = tapped(*SERVOS)
    scanned(t)
    api = t.api
    for headers, token in (({"Origin": "http://evil.example"}, True),
                           ({"Host": "evil.example:%d" % api.port}, True), ({}, False)):
        for path in ("/", "/api/state", "/api/registers", "/static/studio.js"):
            status, _ = api.request("GET", path, headers=headers, token=token)
            assert status == 403, (path, headers, status)
        ws = dict(headers, Connection="Upgrade", Upgrade="websocket",
                  **{"Sec-WebSocket-Version": "13",
                     "Sec-WebSocket-Key": "dGhlIHNhbXBsZSBub25jZQ=="})
        status, answer = api.request("GET", "/ws", headers=ws, token=token)
        assert status == 403 and "ok" in answer, (headers, status, answer)
    # the printed address: the token goes into a SameSite=Strict cookie, then /
    status, _ = api.request("GET", "/", token=False)
    assert status == 403
    import http.client
    conn = http.client.HTTPConnection(api.host, api.port, timeout=10)
    conn.request("GET", "/?token=" + api.token)
    r = conn.getresponse()
    cookie = r.getheader("Set-Cookie")
    assert r.status == 302 and r.getheader("Location") == "/"
    assert api.token in cookie and "SameSite=Strict" in cookie and "HttpOnly" in cookie
    conn.close()
    # a cookie left by an earlier studio on this port does not block the new address
    conn = http.client.HTTPConnection(api.host, api.port, timeout=10)
    conn.request("GET", "/?token=" + api.token,
                 headers={"Cookie": "servo_studio_%d=%s" % (api.port, "s" * 32)})
    r = conn.getresponse()
    assert r.status == 302 and api.token in r.getheader("Set-Cookie")
    conn.close()


@pytest.mark.parametrize("listen", ["0.0.0.0"])
def test_listening_beyond_the_loopback_needs_the_token_and_says_why(tapped, listen):
    from servobus.studio.process import free_port
    port = free_port()
    t = tapped(*SERVOS, studio_args=("--listen", "%s:%d" % (listen, port)))
    stderr_line = t.studio.proc.stderr.readline()
    assert "every request needs that token" in stderr_line, stderr_line
    t.api.port = port
    t.api.host = "127.0.0.1"
    assert t.api.request("GET", "/api/state")[0] == 200
    assert t.api.request("GET", "/api/state", token=False)[0] == 403
    # any address of this machine is fine as an IP literal, a name is not (rebinding)
    assert t.api.request("GET", "/api/state",
                         headers={"Host": "127.0.0.2:%d" % port})[0] == 200
    assert t.api.request("GET", "/api/state",
                         headers={"Host": "studio.example:%d" % port})[0] == 403
