"""The studio's server: aiohttp for the page (pages.py), a JSON API for actions
(actions.py) and a WebSocket that pushes the shared state, live samples and the control
table to every open tab. The worker thread that owns the Bus is worker.py; scans and
updates are flows.py.

serve() checks --listen, takes the port's lock (lock.py), proves the bus is ours with
one PING, scans once, and runs the app until Ctrl-C or SIGTERM. Only the studio's own
page can drive it: every request passes security.py's checks (Host, Origin, the
process's token, Content-Type) before it reaches a handler."""

import asyncio
import sys
import threading

from aiohttp import web

from .. import BusTimeout, ServoBusError
from .. import protocol as P
from .actions import Actions
from .idpanel import IdActions
from .flows import do_scan
from .lock import PortInUse, take_port
from .entry import Entry
from .moves import Moves
from .pages import Pages
from .panels import Panels
from .security import Guard, is_loopback
from .words import in_words, is_link_error
from .worker import Studio


def _parse_listen(text):
    host, sep, port = text.rpartition(":")
    if not sep or not port.isdigit():
        raise ValueError("--listen '%s': expected HOST:PORT, e.g. 127.0.0.1:8080" % text)
    return host.strip("[]") or "127.0.0.1", int(port)


def serve(bus, listen):
    """Run the studio on `listen` with `bus` until Ctrl-C or SIGTERM. Exit status: 0,
    1 port in use or a dead bus, 2 a bad --listen."""
    try:
        host, hport = _parse_listen(listen)
    except ValueError as e:
        print("servoctl studio: %s" % e, file=sys.stderr)
        return 2
    url = "http://%s:%d/" % (host, hport)
    try:
        lock = take_port(bus.port, url)
    except PortInUse as e:
        print("servoctl studio: %s" % e, file=sys.stderr)
        return 1
    st = Studio(bus, url)
    try:
        return asyncio.run(_main(st, host, hport, url))
    except KeyboardInterrupt:
        return 0
    finally:
        lock.close()


PROBE_ID = 253  # any ID: the probe only needs the bus to carry a request


def _probe(st):
    """Before the address is printed: a PING that proves the bus is ours (servo-sim
    closes a second client at once). None, or what is wrong in words."""
    bus = st.bus
    saved = bus.timeout
    bus.timeout = 0.2
    try:
        bus.transact(PROBE_ID, P.PING)  # no update-mode check: only the link matters
    except BusTimeout:
        pass  # nobody at that ID: the usual answer
    except (ServoBusError, OSError) as e:
        if "closed the connection" in str(e):
            return ("port %s is in use: another program is connected to it (servo-sim "
                    "serves one client at a time); stop it first" % bus.port)
        if is_link_error(e):
            return in_words(e)
    finally:
        bus.timeout = saved
    return None


def _app(st, guard):
    """The web app: every request through the guard, then the pages and actions."""
    app = web.Application(client_max_size=1 << 20, middlewares=[guard.middleware])
    Pages(st).add_routes(app)
    Actions(st).add_routes(app)
    IdActions(st).add_routes(app)
    Moves(st).add_routes(app)
    Entry(st).add_routes(app)
    Panels(st).add_routes(app)
    return app


def _announce(st, guard, host):
    print("Servo Studio on %s at %d baud: open %s" % (st.port, st.state["baud"],
                                                      guard.url()), flush=True)
    if not is_loopback(host):
        print("servoctl studio: listening on %s, not only on this computer: anyone who "
              "reaches this address with the token in the address above can move the "
              "servos, so every request needs that token (keep the address to yourself); "
              "pages from other sites are refused" % (host or "every address"),
              file=sys.stderr, flush=True)


async def _main(st, host, port, url):
    import signal
    st.loop = asyncio.get_running_loop()
    st.loop_thread = threading.get_ident()
    guard = Guard(host, port)
    runner = web.AppRunner(_app(st, guard), access_log=None)
    await runner.setup()
    try:
        await web.TCPSite(runner, host, port).start()
    except OSError as e:
        print("servoctl studio: cannot listen on %s:%d: %s (another studio? choose "
              "another with --listen)" % (host, port, e.strerror or e), file=sys.stderr)
        await runner.cleanup()
        return 1
    wrong = _probe(st)  # (a page opened meanwhile waits for it: nothing else runs yet)
    if wrong:
        print("servoctl studio: %s" % wrong, file=sys.stderr)
        await runner.cleanup()
        return 1
    st.thread.start()
    _announce(st, guard, host)
    asyncio.ensure_future(do_scan(st, False))  # once, at start: a tab opened later does not
    done = asyncio.Event()
    for sig in (signal.SIGINT, signal.SIGTERM):
        st.loop.add_signal_handler(sig, done.set)
    await done.wait()
    st.stopping = True
    for ws in list(st.clients):
        await ws.close()
    await runner.cleanup()
    st.thread.join(timeout=2)
    return 0
