"""Servo Studio: the browser configurator served by the SDK (docs/studio.md).

    servoctl studio [--port PORT] [--baud B] [--listen 127.0.0.1:8080]

The studio owns the bus while it runs: one process, one Bus, one worker thread that
talks to it; every browser tab sees the same state. cli/args.py hooks it in with
add_command(); everything else lives in this package."""

DEFAULT_LISTEN = "127.0.0.1:8080"


def add_command(add):
    """Register `studio` with cli/args.py's add(name, func, help); the bus options
    (--port, --baud) come with it."""
    sp = add("studio", run, "the browser app: scan, control table, motion, live plot, "
             "safety, firmware update (docs/studio.md)")
    sp.add_argument("--listen", default=DEFAULT_LISTEN, metavar="HOST:PORT",
                    help="where the web app listens (default %s)" % DEFAULT_LISTEN)
    return sp


def run(bus, args):
    """servoctl studio: serve the app on args.listen with the Bus servoctl opened."""
    import sys
    try:
        from .server import serve
    except ImportError as e:
        print("servoctl studio: %s — the studio needs python3-aiohttp (Debian: apt-get "
              "install python3-aiohttp libjs-chart.js, or tools/install-deps.sh)" % e,
              file=sys.stderr)
        return 2
    try:
        return serve(bus, args.listen)
    finally:
        # The page showed the fault bits live; the bus may be closed by now, so nothing
        # is left for the command line to ask about them after the studio ends.
        getattr(bus, "faults", {}).clear()
