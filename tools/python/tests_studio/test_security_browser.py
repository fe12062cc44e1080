"""Issue 26, security in a real browser: a page from another origin, opened in the same
headless Chromium that holds the studio's cookie, can neither read the WebSocket nor
move a servo. The hostile page is served from 127.0.0.1 on another port: the same site
as the studio (SameSite ignores ports, so the cookie goes along), another origin."""

import http.server
import threading

from raw import not_sampling

SERVOS = ("1:arm", "2:foot")

EVIL = """<!DOCTYPE html><html><body>
<iframe name="sink" style="display:none"></iframe>
<form id="f" method="POST" action="STUDIO/api/move" enctype="text/plain" target="sink">
<input name='{"goal": 200, "speed": 90, "acc": 36, "dec": 36, "id": 2, "x": "' value='"}'>
</form>
<script>
window.result = {messages: 0, wsError: false, wsClosed: false, read: null, done: false};
const move = JSON.stringify({goal: 200, speed: 90, acc: 36, dec: 36, id: 2});
const ws = new WebSocket("ws://HOST/ws");
ws.onmessage = () => { window.result.messages++; };
ws.onerror = () => { window.result.wsError = true; };
ws.onclose = () => { window.result.wsClosed = true; };
async function attack() {
  const tries = [
    fetch("STUDIO/api/move", {method: "POST", mode: "no-cors", body: move}),
    fetch("STUDIO/api/move", {method: "POST", mode: "no-cors", credentials: "include",
                              headers: {"Content-Type": "text/plain"}, body: move}),
    fetch("STUDIO/api/move", {method: "POST", credentials: "include",
                              headers: {"Content-Type": "application/json"}, body: move}),
    fetch("STUDIO/api/update?id=2", {method: "POST", mode: "no-cors",
                                     body: new Blob([new Uint8Array(3000)])}),
    fetch("STUDIO/api/state", {credentials: "include"}).then(
      (r) => r.text()).then((t) => { window.result.read = t; }),
  ];
  for (const t of tries) { try { await t; } catch (e) { /* refused: what we want */ } }
  document.getElementById("f").submit();
  setTimeout(() => { window.result.done = true; }, 1500);
}
attack();
</script></body></html>"""


class _Evil(http.server.BaseHTTPRequestHandler):
    page = b""

    def do_GET(self):  # noqa: N802 (http.server's name)
        self.send_response(200)
        self.send_header("Content-Type", "text/html")
        self.end_headers()
        self.wfile.write(self.page)

    def log_message(self, *args):
        pass


def test_a_page_from_another_origin_can_neither_read_the_websocket_nor_move_a_servo(
        tapped, page):
    t = tapped(*SERVOS)
    p = page(t.studio.url)  # the user opened the studio: the browser holds its cookie
    p.wait_scanned(2)
    p.wait(lambda: p.d.get_cookies(), what="the studio's cookie")
    _Evil.page = EVIL.replace("STUDIO", t.studio.base).replace(
        "HOST", t.studio.listen).encode()
    server = http.server.ThreadingHTTPServer(("127.0.0.1", 0), _Evil)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    try:
        mark = t.tap.mark()
        p.d.get("http://127.0.0.1:%d/" % server.server_address[1])
        result = p.wait(lambda: p.d.execute_script(
            "return window.result.done && window.result"), what="the hostile page's tries")
        assert result["messages"] == 0, result  # before: the servo list and live samples
        assert result["wsError"] or result["wsClosed"], result
        assert result["read"] is None, result  # the state could not be read either
        # before: the foot moved twice (no-cors fetch, text/plain form)
        assert not_sampling(t.tap, mark) == [], "the hostile page reached servo-sim"
    finally:
        server.shutdown()
        server.server_close()
        p.d.get_log("browser")  # the hostile page's own errors (its refused tries)
    # the user's own page still works: the control
    p.d.get(t.studio.base + "/")
    p.wait_scanned(2)
