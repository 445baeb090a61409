"""The parts of `isaac live`, each against what it must do: the pacer on a clock of our own (a slow simulation is
said once, with its factor, and goes on slowed down), the stream's count of dropped frames, the server's loopback
rules, the sliders a scene offers, the drag's spring."""
from __future__ import annotations

import http.client
import math
import json
from pathlib import Path

import pytest

from isaac.live_command import sliders
from isaac_runtime.live.clock import CATCH_UP, SLOW_WINDOW, Pacer
from isaac_runtime.live.server import BUFFER, Hub, LiveServer

SCENES = Path(__file__).resolve().parents[2] / "scenes"
FRAME = 0.02


class Clock:
    """A wall clock that moves only when slept on or worked on."""

    def __init__(self):
        self.now = 100.0

    def __call__(self) -> float:
        return self.now

    def sleep(self, seconds: float) -> None:
        self.now += seconds


def paced(work: float, frames: int):
    """A run of `frames` frames of FRAME, each taking `work` seconds to compute: (pacer, what it said, wall);
    pacer.told_at: the frame after which it said it, if it did."""
    clock, said = Clock(), []
    pacer = Pacer(0.0, FRAME, clock, clock.sleep, said.append)
    pacer.told_at = None
    began = pacer.begin()
    for k in range(1, frames + 1):
        pacer.wait_until((k - 1) * FRAME)
        clock.now += work
        pacer.done(k * FRAME, work)
        if said and pacer.told_at is None:
            pacer.told_at = k
    return pacer, said, clock.now - began


def test_a_simulation_that_keeps_up_waits_for_the_wall_clock():
    pacer, said, wall = paced(work=0.005, frames=150)
    # each frame's steps start when its start is due and end 5 ms later, 15 ms before its end is due
    assert said == [] and pacer.max_lag == 0.0 and pacer.late == 0
    assert wall == pytest.approx(149 * FRAME + 0.005)
    assert pacer.report(wall)["real_time_factor"] == pytest.approx(150 * FRAME / wall)


def test_a_slow_simulation_says_so_once_with_its_factor_and_goes_on_slowed_down():
    pacer, said, wall = paced(work=2 * FRAME, frames=4 * SLOW_WINDOW)
    # said once, when a second of work has shown it (25 frames): half real time, 40 ms of work for a 20 ms frame
    assert len(said) == 1 and pacer.told_at == 25
    assert "runs at 0.50x real time (each 20 ms frame takes 40 ms); going on slowed down" in said[0]
    report = pacer.report(wall)
    assert report["slowed"] is True and report["keep_up_factor"] == pytest.approx(0.5)
    # not raced after: the lag grows by a frame's overrun (20 ms) until it passes CATCH_UP, then the clock slips
    assert CATCH_UP < pacer.max_lag <= CATCH_UP + FRAME + 1e-12 and pacer.slips > 0
    # and the run went on, slowed down to the factor it said
    assert wall == pytest.approx(4 * SLOW_WINDOW * 2 * FRAME, rel=0.01)
    assert report["real_time_factor"] == pytest.approx(0.5, rel=0.01)


def test_a_stall_that_is_not_the_simulations_is_forgiven():
    clock, said = Clock(), []
    pacer = Pacer(0.0, FRAME, clock, clock.sleep, said.append)
    pacer.begin()
    pacer.wait_until(0.0)
    since = clock.now
    clock.now += 0.4  # a parameter re-planned
    pacer.forgive(since)
    clock.now += 0.001
    pacer.done(FRAME, 0.001)
    assert pacer.max_lag == 0.0 and pacer.forgiven == pytest.approx(0.4) and said == []


def test_a_page_that_falls_behind_the_buffer_counts_the_frames_it_missed():
    hub = Hub()
    hub.publish("notice", {"text": "hello"})
    for k in range(BUFFER + 50):
        hub.publish("frame", {"k": k})
    # a page that saw nothing yet: the oldest messages are gone, the notice and the first 50 frames with them
    fresh, missed = hub.wait(0, 0, timeout=0.0)
    assert len(fresh) == BUFFER and missed == 50 and hub.dropped == 50
    # one that is up to date misses nothing
    seq, frames = hub.newest()
    hub.publish("frame", {"k": -1})
    assert hub.wait(seq, frames, timeout=0.0)[1] == 0 and hub.dropped == 50


# ---- the server: loopback only ----------------------------------------------------------------------------------

@pytest.fixture()
def server():
    live = LiveServer(b"<!DOCTYPE html><title>page</title>", 0)
    yield live
    live.close()


def request(server, method: str, route: str, body: bytes | None = None, **headers) -> tuple:
    connection = http.client.HTTPConnection("127.0.0.1", server.port, timeout=5)
    try:
        connection.putrequest(method, route, skip_host=True)
        headers.setdefault("Host", f"127.0.0.1:{server.port}")
        if body is not None:
            headers.setdefault("Content-Length", str(len(body)))
        for name, value in headers.items():
            connection.putheader(name.replace("_", "-"), value)
        connection.endheaders(body)
        reply = connection.getresponse()
        return reply.status, reply.read()
    finally:
        connection.close()


def test_the_server_listens_on_loopback_only(server):
    assert server._httpd.server_address[0] == "127.0.0.1"
    assert server.url == f"http://127.0.0.1:{server.port}/"
    assert request(server, "GET", "/") == (200, b"<!DOCTYPE html><title>page</title>")
    # a page of another site that a DNS name made point at 127.0.0.1 is refused
    assert request(server, "GET", "/", Host=f"evil.example:{server.port}")[0] == 403


def test_the_page_commands_come_from_the_page_only(server):
    drag = json.dumps({"body": "top.rod", "point": [0, 0, 0], "target": [0.1, 1.4, 0]}).encode()
    json_type = {"Content_Type": "application/json"}
    assert request(server, "POST", "/drag", drag, Origin="http://evil.example", **json_type)[0] == 403
    assert request(server, "POST", "/drag", drag, Content_Type="text/plain")[0] == 415
    assert request(server, "POST", "/drag", b"{", **json_type)[0] == 400
    assert server.commands.take() == (False, None, [])
    origin = f"http://127.0.0.1:{server.port}"
    assert request(server, "POST", "/drag", drag, Origin=origin, **json_type)[0] == 200
    assert request(server, "POST", "/parameter", b'{"name": "breath", "value": "6 m/s"}', **json_type)[0] == 200
    changed, command, parameters = server.commands.take()
    assert changed and command == {"body": "top.rod", "point": [0.0, 0.0, 0.0], "target": [0.1, 1.4, 0.0]}
    assert parameters == [("breath", "6 m/s")]


# ---- the sliders ------------------------------------------------------------------------------------------------

def test_the_sliders_are_the_declared_numbers_of_the_scene():
    offered = {s["name"]: s for s in sliders(SCENES / "mobile.isaac", {"d1": "45 g"})}
    breath = offered["breath"]
    assert (breath["value"], breath["unit"], breath["min"], breath["max"]) == (3.0, "m/s", 0.0, 9.0)
    assert breath["text"] == "3 m/s" and offered["d1"]["text"] == "45 g"
    # computed ones (balance points, hooks) and vectors are not offered: moving them alone would unbalance it
    assert "p_low" not in offered and "hook_top" not in offered and "m_below_mid" not in offered
    assert {"drop", "wire", "l_top", "r1", "d4"} <= set(offered)


def test_a_very_slow_simulation_is_told_within_a_second_of_the_wall_clock():
    pacer, said, wall = paced(work=10 * FRAME, frames=12)
    # 200 ms of work for each 20 ms frame: said after the 5 frames that make a second of work, not after 50
    assert len(said) == 1 and "runs at 0.10x real time" in said[0] and pacer.told_at == 5
    assert pacer.report(wall)["keep_up_factor"] == pytest.approx(0.1)


# ---- the drag ------------------------------------------------------------------------------------------------------

class PulledSimulation:
    """The mobile's plan, and what the drag asked of the simulation."""

    def __init__(self):
        from isaac_lang.load import load_scene
        from isaac_runtime.plan import PlanOptions, compile_plan

        self.plan = compile_plan(load_scene(SCENES / "mobile.isaac").scene, PlanOptions(folder=SCENES))
        self.calls = []

    def body(self, name: str) -> int:
        return list(self.plan.names).index(name)

    def pull(self, name, point, target, stiffness, damping):
        self.calls.append(("pull", name, stiffness, damping))

    def release_pull(self):
        self.calls.append(("release",))


def test_a_drag_pulls_with_a_spring_of_two_hertz_for_all_the_mass_it_moves():
    from isaac_runtime.live.drag import DRAG_FREQUENCY, Drag

    sim, drag = PulledSimulation(), Drag()
    # a disc of the mobile drags every rod and disc with it (all joined by ball joints): 45 g of rods, 75 g of discs
    moved = 0.120
    w = 2 * math.pi * DRAG_FREQUENCY
    drag.apply(sim, {"body": "last.plate", "point": [0, 0, 0], "target": [0.5, 1.0, 0.0]})
    drag.apply(sim, {"body": "last.plate", "point": [0, 0, 0], "target": [0.6, 1.0, 0.0]})  # the mouse moved
    # k = m w^2, c = 2 zeta m w (zeta = 1): the mass follows the pointer as a critically damped 2 Hz oscillator
    assert sim.calls == [("pull", "last.plate", pytest.approx(moved * w * w), pytest.approx(2 * moved * w))] * 2
    assert drag.count == 1 and drag.overlay()["target"] == [0.6, 1.0, 0.0]
    drag.apply(sim, None)  # the button is up
    assert sim.calls[-1] == ("release",) and drag.overlay() is None
    # the ceiling is static: nothing to pull, nothing drawn
    drag.apply(sim, {"body": "ceiling", "point": [0, 0, 0], "target": [0.0, 2.0, 0.0]})
    assert sim.calls[-1] == ("release",) and drag.overlay() is None and drag.count == 2
