"""The live page of `isaac live` in headless Chromium (tests/cdp.py), with real mouse events: it connects and draws
the poses as they are computed, a drag with the mouse pulls the body it picked toward the pointer, a slider
re-plans the scene with a parameter, the chimes' sound arrives and is played. Skipped, saying why, when Chromium
is not installed (.ci/run installs it).

The pixel of a body is found with test_viewer's projection (written independently of the page's); where the
drag must take the body is worked out here from the camera, the pixels moved and the body's depth.
"""
from __future__ import annotations

import base64
import json
import math
import time

import numpy as np
import pytest

from tests.cdp import Browser, chromium
from tests.runtime.test_live import COMPILE, LiveRun, breath_wav, report
from tests.runtime.test_viewer import project

pytestmark = pytest.mark.skipif(chromium() is None, reason="Chromium is not installed (apt-get install -y "
                                "chromium; .ci/run installs it); the live page's browser tests need it")

WIDTH, HEIGHT = 800, 600
DRAGGED = "top.left.plate"  # the largest disc (8 cm), facing the camera
PIXELS = 80  # how far the mouse moves it, to the right
BREATH_AT = 3.5  # s: the breath of the slider's check starts here, after the slider and the drag
FRAME = 0.02  # s: the mobile's frames


# every frame's (t, winds, breath level) as the page shows them, kept by the test in the page
RECORD_WINDS = """(() => {
    window.windsSeen = [];
    new MutationObserver(() => {
        const ds = document.body.dataset;
        if (ds.wind) window.windsSeen.push([Number(ds.t), ds.wind, Number(ds.breath),
                                            document.getElementById("level").style.width]);
    }).observe(document.body, { attributes: true, attributeFilter: ["data-wind"] });
})()"""


def page_data(page) -> dict:
    return page.evaluate("JSON.parse(document.getElementById('isaac-data').textContent)")


def body_position(data: dict, name: str) -> np.ndarray:
    """The body's centre in the page's data (the state when the page was made: the mobile at rest)."""
    names = [b["name"] for b in data["bodies"]]
    position = np.frombuffer(base64.b64decode(data["position"]), "<f4").reshape(-1, len(names), 3)
    return position[0, names.index(name)].astype(float)


def camera_axes(camera: dict):
    """(right, depth direction) of the camera, as test_viewer.project sees it."""
    eye, target, up = (np.asarray(camera[k], float) for k in ("position", "look_at", "up"))
    forward = (target - eye) / np.linalg.norm(target - eye)
    side = np.cross(forward, up)
    return side / np.linalg.norm(side), forward


def world_per_pixel(camera: dict, point) -> float:
    """m per pixel on the plane through `point` facing the camera (perspective: depth * 2 tan(fov/2) / height)."""
    _, forward = camera_axes(camera)
    depth = float((np.asarray(point) - np.asarray(camera["position"], float)) @ forward)
    return depth * 2.0 * math.tan(camera["fov"] / 2.0) / HEIGHT


@pytest.fixture(scope="module")
def live_page(tmp_path_factory):
    """The mobile live for 5 s, a breath only from 3.5 s on; the page opened in Chromium; a slider moved, then a
    drag (both before the breath)."""
    folder = tmp_path_factory.mktemp("live_page")
    wav = breath_wav(folder / "breath.wav", [(BREATH_AT, 4.9)], 5.1)
    seen = {}
    with Browser() as browser, LiveRun(["scenes/mobile.isaac", "--mic", str(wav), "--until", "5", "--out",
                                        str(folder / "out")]) as live:
        page = browser.open(live.address(), size=(WIDTH, HEIGHT))
        page.wait_for("Number(document.body.dataset.frames) >= 5", timeout=COMPILE)
        page.evaluate(RECORD_WINDS)
        seen["first"] = page.evaluate("[Number(document.body.dataset.frames), Number(document.body.dataset.t)]")
        data = page_data(page)
        seen["data"] = data
        seen.update(slide(page))
        seen.update(drag(page, data))
        page.wait_for("document.body.dataset.ended === '1'", timeout=30)
        seen["winds"] = page.evaluate("window.windsSeen")
        seen["frames"] = int(page.evaluate("document.body.dataset.frames"))
        code = live.wait()
        seen["stderr"] = live.stderr
    seen.update(code=code, trajectory=np.load(folder / "out" / "trajectory.npz"), report=report(folder / "out"))
    return seen


def drag(page, data: dict) -> dict:
    """Press on the disc, move the mouse PIXELS to the right over 0.4 s, hold it there 0.8 s, let go."""
    camera = data["cameras"][0]
    x, y = project(camera, body_position(data, DRAGGED), WIDTH, HEIGHT)
    page.mouse("mousePressed", x, y)
    picked = page.evaluate("[document.body.dataset.dragging, document.body.dataset.dragBody]")
    began = float(page.evaluate("document.body.dataset.t"))
    for step in range(1, 11):
        page.mouse("mouseMoved", x + PIXELS * step / 10, y)
        time.sleep(0.04)
    time.sleep(0.8)
    held = float(page.evaluate("document.body.dataset.t"))
    page.mouse("mouseReleased", x + PIXELS, y, buttons=0)
    return {"picked": picked, "drag_began": began, "drag_held": held}


def slide(page) -> dict:
    """The `breath` slider to its top (9 m/s), let go as a user lets go of it."""
    page.evaluate("""(() => {
        const input = document.querySelector('#sliders input[data-name="breath"]');
        input.value = input.max;
        input.dispatchEvent(new Event('input'));
        input.dispatchEvent(new Event('change'));
    })()""")
    notice = page.wait_for("document.getElementById('notice').textContent.includes('re-planned') && "
                           "document.getElementById('notice').textContent", timeout=20)
    return {"notice": notice, "slid_at": float(page.evaluate("document.body.dataset.t"))}


def test_the_page_connects_and_draws_the_poses_as_they_come(live_page):
    assert live_page["code"] == 0, live_page["stderr"]
    frames = live_page["report"]["realtime"]["frames"]
    # it joined a run in progress and then missed none of the frames published after
    first_count, first_t = live_page["first"]
    assert live_page["frames"] - first_count == pytest.approx(frames - 1 - round(first_t / FRAME), abs=1)
    assert live_page["report"]["realtime"]["pages"] == 1 and live_page["report"]["realtime"]["frames_dropped"] == 0


def test_a_drag_pulls_the_picked_body_toward_the_pointer(live_page):
    assert live_page["picked"] == ["1", DRAGGED]
    data, trajectory = live_page["data"], live_page["trajectory"]
    camera = data["cameras"][0]
    rest = body_position(data, DRAGGED)
    right, _ = camera_axes(camera)
    wanted = PIXELS * world_per_pixel(camera, rest)  # m: where the pointer took the picked point
    t = trajectory["time"]
    body = list(trajectory["bodies"]).index(DRAGGED)
    moved = (trajectory["position"][:, body] - rest) @ right
    before = t < live_page["drag_began"] - 0.1
    held = (t > live_page["drag_held"] - 0.3) & (t <= live_page["drag_held"])
    assert np.abs(moved[before]).max() < 1e-5  # at rest until pressed
    # pulled to the right by a 2 Hz spring while its joints hold it back (the rod turns, the levels below follow):
    # it gets most of the way, never past the pointer
    assert 0.5 * wanted < moved[held].max() <= 1.05 * wanted
    assert live_page["report"]["realtime"]["drags"] == 1


def breath_starts(live_page) -> float:
    """The scene time at which the breath file's burst came: BREATH_AT, less the time the run's clock slipped
    behind the wall clock (a re-plan, a late frame: the file, like a microphone, keeps the wall clock's time)."""
    realtime = live_page["report"]["realtime"]
    return BREATH_AT - (realtime["slowed_ms"] + realtime["stalls_forgiven_ms"]) / 1e3 - FRAME


def test_a_slider_replans_the_scene_with_the_parameter(live_page):
    replans = live_page["report"]["realtime"]["replans"]
    assert [(r["name"], r["value"]) for r in replans] == [("breath", "9 m/s")]
    assert "breath = 9 m/s (re-planned in" in live_page["notice"]
    assert replans[0]["t"] < BREATH_AT
    # the breath that comes after blows at the new speed: the loudest the follower gets is the file's peak (1)
    speeds = [(t, json.loads(w)[0]["speed"]) for t, w, _, _ in live_page["winds"] if w]
    loudest = max(s for t, s in speeds if t > BREATH_AT)
    assert 0.8 * 9.0 < loudest <= 9.0 * 1.001  # (3 m/s before the slider: at most 3)
    assert max(s for t, s in speeds if t < breath_starts(live_page)) == 0.0


def test_the_page_shows_the_breath_level(live_page):
    """The meter: the normalized follower the wind reads, 0 in the silence and up to the file's peak (1) in the
    breath, the bar as wide as the level."""
    shown = [(t, level, width) for t, _, level, width in live_page["winds"]]
    assert max(level for t, level, _ in shown if t < breath_starts(live_page)) == 0.0
    loudest = max(shown, key=lambda s: s[1])
    assert loudest[0] > breath_starts(live_page) and 0.8 < loudest[1] <= 1.001
    assert float(loudest[2].rstrip("%")) == pytest.approx(100 * min(1.0, loudest[1]), abs=0.1)


def test_the_page_plays_the_sound_as_it_is_rendered(tmp_path):
    """The chimes live for 2 s: every block of sound rendered after the page connected arrives and is scheduled
    on the page's audio context (Chromium runs it without a gesture: tests/cdp.py's autoplay flag)."""
    with Browser() as browser, LiveRun(["scenes/chimes.isaac", "--until", "2", "--out", str(tmp_path / "out")]) \
            as live:
        page = browser.open(live.address(), size=(WIDTH, HEIGHT))
        page.wait_for("Number(document.body.dataset.frames) >= 2", timeout=COMPILE)
        page.wait_for("document.body.dataset.ended === '1'", timeout=30)
        played = page.evaluate("['audioBlocks', 'audioPlayed', 'audioSeconds', 'audioFrom']"
                               ".map((k) => Number(document.body.dataset[k]))")
        assert live.wait() == 0, live.stderr
    blocks, scheduled, seconds, first = played
    assert blocks > 0 and scheduled == blocks
    # every block from the first this page had to the end of the run's 2 s, none missing
    assert seconds == pytest.approx(2.0 - first, abs=1e-3)
