"""The studio's long actions: a scan (at one baud or every baud, with progress) and a
firmware update. Each runs as jobs of the worker; the state they change is pushed to
every tab. STOP cuts either short at its next packet (Interrupted), and says so."""

import asyncio

from .. import ImageError, Interrupted, ServoBusError
from ..protocol import describe_err
from ..registers import BAUD_RATES, baud_of_code, variant_by_model
from .jobs import Refused
from .words import in_words, is_link_error


def _at_baud(bus, baud, fn):
    """fn() with the host at baud, and back to where it was afterwards."""
    start = bus.baud
    try:
        if baud != bus.baud:
            bus.set_baud(baud)
        return fn()
    finally:
        if bus.baud != start:
            bus.set_baud(start)


def _scan_job(baud):
    """The job of one broadcast PING scan at baud: (found, notes, duplicate IDs)."""
    def job(bus):
        found = _at_baud(bus, baud, bus.scan)
        return found, list(bus.scan_notes), list(bus.duplicates)
    return job


def _resolve_job(finds):
    """The job that tells one servo heard at two bauds from two servos with one ID."""
    def job(bus):
        before = set(bus.duplicates)
        servos = bus.resolve_bauds(finds)
        return servos, sorted(set(bus.duplicates) - before), list(bus.scan_notes)
    return job


def _details_job(f):
    """The job that reads what the scan table shows of the servo found as f."""
    def job(bus):
        v = _at_baud(bus, f.baud, lambda: bus.read_many(
            f.id, ["model_number", "firmware_version", "baud_rate"]))
        variant = variant_by_model(v["model_number"])
        return {
            "id": f.id, "heard_baud": f.baud, "model": v["model_number"],
            "model_hex": "0x%04X" % v["model_number"],
            "variant": variant.name if variant else "unknown model",
            "firmware": v["firmware_version"],
            "baud": baud_of_code(v["baud_rate"], variant), "err": f.err,
            "health": describe_err(f.err),
        }
    return job


def _bauds(st, all_bauds, baud):
    """The bauds a scan goes through, and its first notes."""
    if all_bauds and st.state["tcp"]:
        return [st.state["baud"]], ["over tcp:// every servo hears every baud: one scan "
                                    "covers all eleven baud codes"]
    if all_bauds:
        return list(BAUD_RATES), []
    return [baud or st.state["baud"]], []


async def _details(st, found):
    """The scan table's rows for the servos found."""
    servos = []
    for f in found:
        try:
            servos.append(await st.call(_details_job(f)))
        except Interrupted:
            raise
        except ServoBusError as e:
            if is_link_error(e):
                raise
            servos.append({"id": f.id, "heard_baud": f.baud, "model": None,
                           "model_hex": "", "variant": "?", "firmware": None,
                           "baud": f.baud, "err": f.err, "health":
                           describe_err(f.err) + ["does not answer READ: %s" % e]})
    return servos


async def _scan_bauds(st, bauds):
    """Scan at each baud with progress; (servos found, IDs two servos answer at)."""
    sc = st.state["scan"]
    finds, dups = [], set()
    for i, b in enumerate(bauds):
        sc.update(done=i, baud=b)
        st.changed()
        found, notes, two = await st.call(_scan_job(b))
        sc["notes"] += notes
        finds += found
        dups.update(two)
    found, two, notes = await st.call(_resolve_job(finds))
    sc["notes"] += [n for n in notes if n not in sc["notes"]]
    return found, dups | set(two)


async def do_scan(st, all_bauds, baud=None):
    """Scan at the bus baud, at one baud, or at every baud, with progress."""
    if st.busy:
        return
    sc = st.state["scan"]
    bauds, notes = _bauds(st, all_bauds, baud)
    st.busy = "scanning"
    sc.update(running=True, done=0, total=len(bauds), baud=bauds[0], notes=notes,
              warning="", message="")
    st.changed()
    where = "every baud" if all_bauds and not st.state["tcp"] else "%d baud" % bauds[0]
    try:
        found, dups = await _scan_bauds(st, bauds)
        servos = await _details(st, found)
        st.state["servos"] = servos
        if baud is None or all_bauds:  # the studio's whole bus
            # a servo gone from the bus lost its RAM, a held REG WRITE with it
            st.held.intersection_update(s["id"] for s in servos)
        sc["warning"] = _duplicate_warning(dups)
        sc["message"] = ("%d servo%s found at %s." % (len(servos), "" if len(servos) == 1
                                                        else "s", where) if servos else
                         "No servo answered at %s: check power and wiring%s." % (
                             where, "" if all_bauds else ", or scan all baud rates"))
        st.log("scan at %s: %s" % (where, ", ".join(
            "ID %d %s" % (s["id"], s["variant"]) for s in servos) or "nothing"))
        sc["done"] = len(bauds)
        if st.selected not in [s["id"] for s in servos]:
            st.selected = None
        if st.selected is None and servos:
            await st.call(st.select(servos[0]["id"]))
    except Interrupted:
        sc["message"] = "Scan at %s stopped by STOP: scan again when you are ready." % where
        st.log("scan at %s: stopped by STOP" % where, ok=False)
    except (ServoBusError, OSError, Refused) as e:
        sc["message"] = in_words(e)
        st.log("scan: %s" % e, ok=False)
    finally:
        st.busy = None
        sc["running"] = False
        st.changed()


def _duplicate_warning(dups):
    if not dups:
        return ""
    return ("Duplicate ID: two servos answer at ID %s. Anything sent to that ID reaches "
            "both: connect one of them alone and give it a free ID (ID & reset)." %
            ", ".join(map(str, sorted(dups))))


def start_update(st, sid, data, name):
    """Send a firmware image to servo sid, with progress and the version before and
    after (finish_update() shows how it ended). The job is queued before anything
    changes, so a bus that is gone refuses it at once (BusGone)."""
    up = st.state["update"]

    def progress(done, total, nbytes, total_bytes):
        up.update(done=done, total=total, bytes=nbytes, bytes_total=total_bytes)
        st.changed()

    def note(text):
        up["note"] = text
        st.changed()

    def job(bus):
        up["before"] = bus.read(sid, "firmware_version") if bus.present(sid) else \
            "none (update mode)"
        st.changed()
        try:
            return bus.update(sid, data, progress=progress, notify=note)
        except Interrupted:
            up["step"] = bus.update_step
            raise
    future = st.submit(job, "ID %d: firmware update from %s (%d bytes)" % (
        sid, name, len(data)))
    up.update(running=True, id=sid, done=0, total=0, bytes=0, bytes_total=len(data),
              before=None, after=None, error="", note="", file=name, step=None)
    st.busy = "updating the firmware of ID %d" % sid
    st.changed()
    return future


async def finish_update(st, sid, future):
    """Wait for the update's job and show how it ended."""
    up = st.state["update"]
    try:
        up["after"] = await asyncio.wrap_future(future)
        st.log("ID %d now runs firmware version %s" % (sid, up["after"]))
        for s in st.state["servos"]:
            if s["id"] == sid:
                s["firmware"] = up["after"]
    except Interrupted:
        up["error"] = ("Update of ID %d stopped by STOP at the %s: the servo keeps its "
                       "firmware, and refuses other commands until its update session "
                       "ends, 10 s after the last frame." % (sid, up["step"] or "start"))
    except (ServoBusError, ImageError, OSError, Refused) as e:
        up["error"] = in_words(e)
    finally:
        up["running"] = False
        st.busy = None
        st.table_due = 0.0
        st.changed()
