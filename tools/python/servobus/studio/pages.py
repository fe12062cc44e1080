"""What the studio serves besides its JSON actions: the page, Chart.js, the control
table as the page needs it, and the WebSocket that pushes the shared state."""

import json
import os

from aiohttp import WSMsgType, web

from .. import VARIANTS
from ..registers import BAUD_RATES, UNIT_TEXT
from .words import register_info

STATIC = os.path.join(os.path.dirname(os.path.abspath(__file__)), "static")
# Debian's libjs-chart.js, served from where the package installs it.
CHART_JS = os.environ.get("STUDIO_CHART_JS",
                          "/usr/share/javascript/chart.js/chart.min.js")


class Pages:
    """The GET handlers, on the shared Studio state st."""

    def __init__(self, st):
        self.st = st

    def add_routes(self, app):
        app.router.add_get("/", self.index)
        app.router.add_get("/chart.js", self.chart)
        app.router.add_get("/api/registers", self.registers)
        app.router.add_get("/ws", self.ws_handler)
        app.router.add_static("/static/", STATIC)

    async def index(self, _):
        return web.FileResponse(os.path.join(STATIC, "index.html"))

    async def chart(self, _):
        if not os.path.exists(CHART_JS):
            return web.Response(
                status=404, content_type="application/javascript",
                text="window.CHART_MISSING = %s;" % json.dumps(
                    "%s is missing: install Debian's libjs-chart.js "
                    "(tools/install-deps.sh)" % CHART_JS))
        return web.FileResponse(CHART_JS)

    async def registers(self, _):
        return web.json_response({
            "registers": register_info(), "bauds": BAUD_RATES, "units": UNIT_TEXT,
            "variants": {v.name: {"photo_switches": v.photo_switches,
                                  "model": v.model_number,
                                  "max_angle_deg": v.max_angle_ddeg / 10}
                         for v in VARIANTS.values()}})

    async def ws_handler(self, request):
        """The live state for a tab. Opening one sends nothing on the bus: the studio
        scanned when it started, and scans again only when asked."""
        st = self.st
        tab = request.query.get("tab")  # the page's name for itself (its traces)
        ws = web.WebSocketResponse(heartbeat=20)
        await ws.prepare(request)
        st.clients.add(ws)
        await ws.send_str(json.dumps({"type": "state", "state": st.state}))
        try:
            async for msg in ws:
                if msg.type == WSMsgType.ERROR:
                    break
        finally:
            st.clients.discard(ws)
            if tab:  # a closed tab's traces and dashboard are read no more
                st.live.drop_tab(tab, st.state["baud"])
        return ws
