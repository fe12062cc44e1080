"""Only the studio's own page can drive it (docs/studio.md, "Security").

Every page the user's browser shows can send requests to the loopback, so the address
alone protects nothing. Every request must pass, in this order:
1. Host: one of this studio's names (the listen address, 127.0.0.1, localhost, [::1];
   for a wildcard listen address, an IP literal). A name that resolves here by DNS
   rebinding is refused.
2. Origin, when the browser sends one (it does on every cross-origin request, and on
   every POST and WebSocket): exactly this studio's origin.
3. The token: a secret drawn for this process and printed in the URL to open (as
   Jupyter does). GET /?token=... sets it in a SameSite=Strict, HttpOnly cookie and
   redirects to /; after that the browser sends the cookie, a script client sends the
   X-Studio-Token header (or ?token=).
4. Content-Type: application/json for the JSON actions, application/octet-stream for
   a firmware image: types a browser may not send cross-origin without a CORS
   preflight, which this server never grants.
A refusal is HTTP 403 with a sentence, before the request reaches a handler: nothing
is queued and nothing goes on the wire."""

import hmac
import ipaddress
import secrets

from aiohttp import web

LOOPBACK_NAMES = ("127.0.0.1", "localhost", "[::1]")
WILDCARDS = ("0.0.0.0", "::", "")
HEADER = "X-Studio-Token"
# What each POST must carry; any other POST is JSON.
UPLOADS = {"/api/update": "application/octet-stream"}
JSON = "application/json"


def is_loopback(host):
    return host in ("127.0.0.1", "localhost", "::1", "[::1]")


class Guard:
    """The checks above for a studio listening on host:port, with this process's
    token."""

    def __init__(self, host, port):
        self.host = host
        self.port = port
        self.token = secrets.token_urlsafe(24)
        self.cookie = "servo_studio_%d" % port  # cookies ignore ports: one per studio
        shown = "[%s]" % host if ":" in host else host
        self.shown_host = "127.0.0.1" if host in WILDCARDS else shown

    def url(self):
        """The address to open, with the token."""
        return "http://%s:%d/?token=%s" % (self.shown_host, self.port, self.token)

    # ---- the checks -----------------------------------------------------------------

    def host_ok(self, value):
        """Host header: name:port of this studio (no port: port 80)."""
        name, port = _split_host(value or "")
        if name is None or (port or "80") != str(self.port):
            return False
        if name in LOOPBACK_NAMES or name == self.shown_host:
            return True
        if self.host in WILDCARDS:  # any address of this machine: an IP literal, no name
            try:
                ipaddress.ip_address(name.strip("[]"))
                return True
            except ValueError:
                return False
        return False

    def token_ok(self, request, only_query=False):
        """Does the request carry this process's token? Any of its places counts: a
        cookie left by an earlier studio on this port does not hide a good one."""
        given = [request.query.get("token")]
        if not only_query:
            given += [request.cookies.get(self.cookie), request.headers.get(HEADER)]
        return any(hmac.compare_digest(g.encode(), self.token.encode())
                   for g in given if g)

    def refusal(self, request):
        """None if the request may go on, else the sentence that refuses it."""
        if not self.host_ok(request.headers.get("Host")):
            return ("Host '%s' is not this studio's address: requests must name it as "
                    "127.0.0.1:%d or localhost:%d (a page that reaches the studio under "
                    "another name is refused)." % (request.headers.get("Host", ""),
                                                   self.port, self.port))
        origin = request.headers.get("Origin")
        if origin is not None and origin != "http://" + request.headers["Host"]:
            return ("Origin '%s' is not this studio: only the studio's own page may "
                    "drive it." % origin)
        if not self.token_ok(request):
            return ("No valid token: open the address the studio printed when it "
                    "started (http://%s:%d/?token=...)." % (self.shown_host, self.port))
        if request.method == "POST":
            want = UPLOADS.get(request.path, JSON)
            # the header as sent: aiohttp's content_type would read a missing one (which
            # a browser may send cross-origin without a preflight) as octet-stream
            given = request.headers.get("Content-Type", "").split(";")[0].strip().lower()
            if given != want:
                return ("Content-Type '%s' is refused: this request must be %s." % (
                    request.headers.get("Content-Type", ""), want))
        return None

    @web.middleware
    async def middleware(self, request, handler):
        """Every request passes the checks before its handler runs."""
        if request.path == "/favicon.ico":
            return web.Response(status=204)
        if request.method == "GET" and request.path == "/" and \
                self.host_ok(request.headers.get("Host")) and \
                request.headers.get("Origin") is None and \
                self.token_ok(request, only_query=True):
            return self._enter(request)
        why = self.refusal(request)
        if why is None:
            return await handler(request)
        if request.path.startswith("/api/") or request.path == "/ws":
            return web.json_response({"ok": False, "error": why, "sent": False},
                                     status=403)
        return web.Response(status=403, content_type="text/html",
                            text=_PAGE % why.replace("&", "&amp;").replace("<", "&lt;"))

    def _enter(self, request):
        """The printed URL: the token goes into the cookie, and the page opens at /
        (the token does not stay in the address bar or the history)."""
        response = web.HTTPFound("/")
        response.set_cookie(self.cookie, self.token, httponly=True, samesite="Strict",
                            path="/")
        return response


def _split_host(value):
    """(name, port) of a Host header ('' when there is no port; an IPv6 literal keeps
    its brackets), or (None, None) if it is not one."""
    if value.startswith("["):
        end = value.find("]")
        rest = value[end + 1:] if end > 0 else None
        if rest is None or (rest and not rest.startswith(":")):
            return None, None
        return value[:end + 1], rest[1:]
    name, _, port = value.partition(":")
    if ":" in port or not name:
        return None, None
    return name, port


_PAGE = """<!DOCTYPE html><html lang="en"><head><meta charset="utf-8">
<title>Servo Studio: not allowed</title></head><body style="font-family: sans-serif">
<h1>Servo Studio</h1><p>%s</p></body></html>"""
