"""A second adversarial round on Servo Studio (issues 26 and 29): what a careless or an
unlucky user does, through a raw client (and Chromium where the page's words matter).
Each test failed before the fix it names."""

import time

from raw import not_sampling, ready


def test_bus_gone_is_said_once_in_each_refusal(sim_factory, studio_factory):
    # before: "The bus is gone (The bus is gone: cannot connect ... — reconnecting):
    # nothing was sent." in every refusal and in the log
    from raw import Api
    sim = sim_factory("2:foot")
    api = Api(studio_factory(sim.url))  # no tap: with servo-sim gone, nothing listens
    api.wait(lambda st: st["selected"] == 2, what="the foot selected")
    sim.stop()
    api.wait(lambda st: not st["link_ok"], what="the studio seeing the bus gone")
    time.sleep(1.2)  # a reconnect attempt failed meanwhile: its words are the link's
    answers = [api.post(path, body) for path, body in (
        ("/api/move", {"goal": 10, "speed": 90, "acc": 36, "dec": 36}),
        ("/api/stop", {}), ("/api/console", {"text": "ping"}))]
    for status, answer in answers:
        assert status == 409, answer
        assert answer["error"].lower().count("the bus is gone") == 1, answer["error"]
        assert answer["error"].count("reconnecting") == 0, answer["error"]
    st = api.state()
    assert st["link"].lower().count("the bus is gone") == 1, st["link"]
    assert "reconnecting" in st["link"]  # the page's cue that it comes back
    for entry in st["log"][-3:]:
        assert entry["text"].lower().count("the bus is gone") == 1, entry


# servoctl commands the console does not run: each refused in words that name where the
# studio does it (before: "'update x.bin' is not hex bytes", or "Not a command")
ELSEWHERE = [("studio", "this is the studio"), ("update fw.bin", "Firmware panel"),
             ("servoctl update fw.bin", "Firmware panel"),
             ("set-id 5", "ID & reset panel"), ("--id 2 set-id 5", "ID & reset panel"),
             ("reset", "asks first"), ("config save f.json", "Configuration files"),
             ("scan", "Scan panel"), ("monitor", "Live plot")]


def test_console_names_where_a_command_it_does_not_take_is_done(tapped):
    t = tapped("2:foot")
    ready(t, 1)
    mark = t.tap.mark()
    for text, words in ELSEWHERE:
        status, answer = t.api.post("/api/console", {"text": text})
        assert status == 400, (text, answer)
        assert "is not taken in the console" in answer["error"], (text, answer)
        assert words in answer["error"] and "not hex" not in answer["error"], answer
    status, answer = t.api.post("/api/console", {"text": "gte present_position"})
    assert status == 400 and "'gte' is neither a command" in answer["error"], answer
    # --wait would hold the worker (the live values, every other tab's action) for up to
    # 60 s: refused, nothing sent (before: `home --wait` held another tab's Set 8.7 s)
    for text in ("--id 2 move 10deg --speed 30deg/s --wait",
                 "--id 2 traj 10:30 --wait-timeout 5"):
        status, answer = t.api.post("/api/console", {"text": text})
        assert status == 400 and "does not hold the bus" in answer["error"], answer
    time.sleep(0.3)
    assert not_sampling(t.tap, mark) == []


def test_console_help_is_answered_not_printed_on_the_studios_terminal(tapped):
    # before: argparse printed the help on the studio process's stdout (a pipe nobody
    # reads under a service manager or the tests: enough of them blocks the server) and
    # the page got "Not a command"
    t = tapped("2:foot")
    ready(t, 1)
    for text, first in (("-h", "usage: servoctl [-h]"), ("--help", "usage: servoctl"),
                        ("--id 2 get --help", "usage: servoctl get")):
        status, answer = t.api.post("/api/console", {"text": text})
        assert status == 200 and answer["output"].startswith(first), (text, answer)
        assert answer["frames"] == []
    assert t.studio.stop() == 0
    assert "usage:" not in t.studio.stdout, "the help went to the studio's terminal"


def test_hand_edited_config_and_group_moves_are_refused_in_words(tapped):
    from servobus import config as C
    from servobus import RangeError
    t = tapped("1:arm", "2:foot", "7:foot")
    ready(t, 3)
    mark = t.tap.mark()
    status, answer = t.api.post("/api/config/save", {"id": 2})
    assert status == 200, answer
    doc = answer["config"]
    for variant in (["foot"], {"foot": 1}):  # before: HTTP 500 (unhashable)
        bad = dict(doc, variant=variant)
        for path, body in (("/api/config/diff", {"a": bad, "b": 2}),
                           ("/api/config/restore", {"config": bad, "id": 7})):
            status, answer = t.api.post(path, body)
            assert status == 400 and "variant" in answer["error"], (path, answer)
        try:  # servoctl config restore FILE: the same check, a ServoBusError
            C.check(bad)
            raise AssertionError("a list for the variant passed the check")
        except RangeError as e:
            assert "variant" in str(e)
    # a register's name starts the sentence as it is (before: "Id: 254 is out of range")
    status, answer = t.api.post("/api/config/restore", {"config": dict(doc, settings=dict(
        doc["settings"], id=254)), "id": 7, "with_id": True})
    assert status == 400 and answer["error"].startswith("id: 254 is out of range"), answer
    # two keys for one servo: before, one servo moved, to the last goal, though the
    # form asks for at least two
    status, answer = t.api.post("/api/group", {"goals": {"2": 10, "2.0": 20},
                                               "speed": 30})
    assert status == 400 and "ID 2 is given twice" in answer["error"], answer
    time.sleep(0.3)
    assert [raw for _, raw in not_sampling(t.tap, mark) if raw[4] != 0x02] == []


def test_a_restore_that_changes_the_id_is_followed_by_the_studio(tapped):
    # before: the foot answered at ID 7, the studio kept ID 2 in its list and selected,
    # sampled it ("No answer from ID 2") and refused Set ID back to 2 ("taken")
    t = tapped("1:arm", "2:foot")
    ready(t, 2)
    assert t.api.post("/api/select", {"id": 2})[0] == 200
    status, answer = t.api.post("/api/config/save", {"id": 2})
    doc = answer["config"]
    doc["settings"]["id"] = 7
    status, answer = t.api.post("/api/config/restore", {"config": doc, "id": 2,
                                                        "with_id": True})
    assert status == 200 and answer["changes"] == {"id": 7}, answer
    st = t.api.state()
    assert [s["id"] for s in st["servos"]] == [1, 7] and st["selected"] == 7, st
    mark = t.tap.mark()
    time.sleep(1.0)
    st = t.api.state()
    assert not st["sample_error"], st["sample_error"]
    sampled = [raw[2] for _, raw in t.tap.packets(mark) if raw[4] == 0x02]
    assert sampled.count(7) > 5 and 2 not in sampled, sampled  # it samples ID 7
    assert any("restore 1 setting (id)" in e["text"] for e in st["log"]), st["log"]
    status, answer = t.api.post("/api/setid", {"new_id": 2})  # and back, from the panel
    assert status == 200, answer


def test_a_restore_that_changes_the_baud_is_followed_on_a_serial_bus(tapped):
    # through servo-sim's baud model (rfc2217://, 9600 baud): before, the studio stayed
    # at 9600 and lost the foot it had just restored
    t = tapped("2:foot", rfc2217=True)
    ready(t, 1)
    status, answer = t.api.post("/api/config/save", {"id": 2})
    doc = answer["config"]
    doc["settings"]["baud_rate"] = 4  # 115200 baud
    body = {"config": doc, "id": 2, "with_baud": True}
    status, answer = t.api.post("/api/config/restore", body)
    assert status == 409 and "115200" in answer["confirm"], answer  # it asks first
    status, answer = t.api.post("/api/config/restore", dict(body, confirm=True))
    assert status == 200 and answer["changes"] == {"baud_rate": 4}, answer
    st = t.api.state()
    assert st["baud"] == 115200 and st["servos"][0]["baud"] == 115200, st
    time.sleep(1.0)
    st = t.api.state()
    assert not st["sample_error"], st["sample_error"]


def test_a_clamped_goal_is_said_by_the_api_and_the_page(tapped, page):
    # before: "Moving ID 2 to 350 deg." while the servo went to its limit, 300 deg
    t = tapped("2:foot", "7:foot")
    ready(t, 2)
    status, answer = t.api.post("/api/write", {"id": 2, "name": "ccw_angle_limit",
                                               "value": "300"})
    assert status == 200, answer
    move = {"goal": 350, "speed": 90, "acc": 36, "dec": 36, "id": 2}
    status, answer = t.api.post("/api/move", move)
    assert status == 200 and answer["clamped"] == {
        "asked": 350, "held": 300, "limits": [0, 300]}, answer
    assert "outside its angle limits (0..300 deg): it goes to 300 deg" in answer["note"]
    status, answer = t.api.post("/api/move", dict(move, goal=200))  # within: no note
    assert status == 200 and "note" not in answer, answer
    for how in ("action", "sync"):  # a group move says which servo clamped
        status, answer = t.api.post("/api/group", {"goals": {"2": 350, "7": 100},
                                                   "speed": 60, "how": how})
        assert status == 200 and list(answer["clamped"]) == ["2"], answer
        assert "ID 2: 350 deg is outside" in answer["note"], answer
    # an arm not homed takes a REG WRITE of its goal, and ignores the broadcast ACTION:
    # said as such, not as a clamp (before: "started together")
    t2 = tapped("1:arm", "2:foot")
    ready(t2, 2)
    status, answer = t2.api.post("/api/group", {"goals": {"1": 50, "2": 100},
                                                "speed": 60})
    assert status == 200 and "ID 1 did not take the goal of 50 deg" in answer["note"], \
        answer
    p = page(t.studio.url)
    p.wait_scanned(2)
    p.select(2)
    p.panel("motion")
    for box, text in (("mv-goal", "350"), ("mv-speed", "90"), ("mv-acc", "36"),
                      ("mv-dec", "36")):
        p.by("#" + box).clear()
        p.by("#" + box).send_keys(text)
    p.click("mv-go")
    p.wait(lambda: "it goes to 300 deg instead" in p.message(),
           what="the page saying the goal was clamped")


def test_each_tab_keeps_its_own_plot_traces_and_dashboard(tapped):
    # before: the register plot's picks and the dashboard's on/off were the studio's, not
    # the tab's: a second tab's Add trace replaced the first tab's traces (its lines
    # went blank under a header still counting them), and leaving the dashboard in one
    # tab froze it in the other
    import asyncio
    import aiohttp
    t = tapped("1:arm", "2:foot")
    ready(t, 2)
    temp, pos = "2.present_temperature", "1.turned_angle"

    async def scenario():
        h = {"X-Studio-Token": t.api.token}
        async with aiohttp.ClientSession() as s:
            a = await s.ws_connect(t.studio.base + "/ws?tab=A", headers=h)
            b = await s.ws_connect(t.studio.base + "/ws?tab=B", headers=h)

            async def post(path, body):
                async with s.post(t.studio.base + path, json=body, headers=h) as r:
                    assert r.status == 200, await r.text()

            async def keys_seen(ws, kind, n=5):
                """The value keys of the next n messages of kind on ws."""
                seen = []
                while len(seen) < n:
                    m = await ws.receive_json(timeout=5)
                    if m["type"] == kind:
                        seen.append(set(m.get("v", {})) if kind == "scope" else m)
                return seen
            await post("/api/scope", {"tab": "A", "picks": [
                {"id": 2, "register": "present_temperature"}]})
            await post("/api/scope", {"tab": "B", "picks": [
                {"id": 1, "register": "turned_angle"}]})
            await keys_seen(a, "scope", 2)  # what was pushed before B's traces
            # A's trace is kept, B's read too (once, for both)
            assert all({temp, pos} <= k for k in await keys_seen(a, "scope"))
            await b.close()  # B's traces go with its tab
            await asyncio.sleep(0.5)
            await keys_seen(a, "scope", 3)
            assert all(k == {temp} for k in await keys_seen(a, "scope")), "B's read on"
            await post("/api/dashboard", {"tab": "A", "on": True})
            c = await s.ws_connect(t.studio.base + "/ws?tab=C", headers=h)
            await post("/api/dashboard", {"tab": "C", "on": True})
            await post("/api/dashboard", {"tab": "C", "on": False})  # C leaves it
            await keys_seen(a, "dash", 2)
            t0 = time.monotonic()
            assert len(await keys_seen(a, "dash", 3)) == 3  # A's still live
            assert time.monotonic() - t0 < 3
            await c.close()
            await a.close()
    asyncio.run(scenario())
    time.sleep(0.5)  # every tab closed: nothing of the plot or dashboard is read
    mark = t.tap.mark()
    time.sleep(0.5)
    assert not [raw for _, raw in not_sampling(t.tap, mark)], "read for a closed tab"
