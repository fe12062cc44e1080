"""A second adversarial round on Servo Studio (issues 26 and 29): what a careless or an
unlucky user does, through a raw client (and Chromium where the page's words matter).
Each test failed before the fix it names."""

import time

from raw import not_sampling, writes_to
from servobus.registers import REGISTERS

GOAL = REGISTERS["goal_position"].address


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
