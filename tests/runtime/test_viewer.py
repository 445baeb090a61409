"""The offline viewer: its data round-trips, the page is self-contained, and in headless Chromium (no network)
it draws the bodies where the trajectory puts them, plays the sound and, served live, takes in a new result.

The screenshots are checked against an independent projection written here (gluLookAt + perspective), not
against the viewer's own code. Chromium tests skip when no Chromium is installed (`apt-get install -y chromium`).
"""
from __future__ import annotations

import base64
import json
import math
import os
import re
import shutil
import struct
import subprocess
import tempfile
import time
import wave
import zlib
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main
from isaac_lang.load import load_scene, load_text
from isaac_runtime.run import RunOptions, simulate
from isaac_runtime.viewer import render_html, viewer_data, write_viewer
from isaac_runtime.viewer.serve import LiveServer

SCENES = Path(__file__).resolve().parents[2] / "scenes"
BACKGROUND = np.array([0x26, 0x2A, 0x31])
CHROMIUM_FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
                  "--disable-background-networking", "--disable-component-update", "--disable-sync",
                  "--hide-scrollbars", "--mute-audio"]
WIDTH, HEIGHT = 800, 600


def chromium() -> str | None:
    for name in (os.environ.get("ISAAC_CHROMIUM"), "chromium", "chromium-browser", "google-chrome", "chrome"):
        if name and shutil.which(name):
            return shutil.which(name)
    return None


needs_chromium = pytest.mark.skipif(chromium() is None, reason="Chromium is not installed (apt-get install -y "
                                    "chromium; .ci/run installs it); the viewer's browser tests need it")


def run_chromium(url: str, *args: str, timeout: float = 60) -> subprocess.CompletedProcess:
    with tempfile.TemporaryDirectory(prefix="isaac-chromium-") as profile:
        return subprocess.run([chromium(), *CHROMIUM_FLAGS, f"--user-data-dir={profile}", *args, url],
                              capture_output=True, text=True, timeout=timeout)


def screenshot(page: Path, hash_: str, out: Path) -> np.ndarray:
    result = run_chromium(page.resolve().as_uri() + "#" + hash_, f"--window-size={WIDTH},{HEIGHT}",
                          f"--screenshot={out}")
    assert out.is_file(), result.stderr[-2000:]
    return read_png(out)


def dump_dom(url: str, budget_ms: int = 3000) -> str:
    result = run_chromium(url, f"--virtual-time-budget={budget_ms}", "--dump-dom")
    return result.stdout


# ---- helpers: a PNG reader and a projection, independent of the code under test ---------------------------

def read_png(path: Path) -> np.ndarray:
    """(H, W, 3) uint8 of an 8-bit RGB or RGBA, non-interlaced PNG (what Chromium writes)."""
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n"
    pos, chunks, header = 8, [], None
    while pos < len(data):
        length, kind = struct.unpack(">I4s", data[pos:pos + 8])
        body = data[pos + 8:pos + 8 + length]
        if kind == b"IHDR":
            header = struct.unpack(">IIBBBBB", body)
        elif kind == b"IDAT":
            chunks.append(body)
        pos += 12 + length
    width, height, depth, color, _, _, interlace = header
    assert depth == 8 and color in (2, 6) and interlace == 0
    channels = 3 if color == 2 else 4
    raw = zlib.decompress(b"".join(chunks))
    stride = width * channels
    image = np.zeros((height, stride), np.uint8)
    previous = np.zeros(stride, np.int64)
    for y in range(height):
        kind = raw[y * (stride + 1)]
        line = np.frombuffer(raw, np.uint8, stride, y * (stride + 1) + 1).astype(np.int64)
        if kind == 0:
            out = line
        elif kind == 1:  # sub: a running sum along the row, per channel
            out = np.cumsum(line.reshape(width, channels), axis=0).ravel() & 0xFF
        elif kind == 2:  # up
            out = (line + previous) & 0xFF
        else:  # average or Paeth: each byte needs the one decoded just before it
            out = _unfilter_sequential(kind, line.tolist(), previous.tolist(), channels)
        image[y] = out
        previous = np.asarray(out, np.int64)
    return image.reshape(height, width, channels)[:, :, :3]


def _unfilter_sequential(kind: int, line: list, previous: list, channels: int) -> list:
    out = [0] * len(line)
    for x, value in enumerate(line):
        a = out[x - channels] if x >= channels else 0
        b = previous[x]
        if kind == 3:
            predictor = (a + b) // 2
        else:
            c = previous[x - channels] if x >= channels else 0
            p = a + b - c
            pa, pb, pc = abs(p - a), abs(p - b), abs(p - c)
            predictor = a if pa <= pb and pa <= pc else (b if pb <= pc else c)
        out[x] = (value + predictor) & 0xFF
    return out


def project(camera: dict, point, width: int = WIDTH, height: int = HEIGHT) -> tuple:
    """Pixel (column, row) of a world point seen by camera (position, look_at, up, vertical fov)."""
    eye, target, up = (np.asarray(camera[k], float) for k in ("position", "look_at", "up"))
    forward = (target - eye) / np.linalg.norm(target - eye)
    side = np.cross(forward, up)
    side /= np.linalg.norm(side)
    true_up = np.cross(side, forward)
    d = np.asarray(point, float) - eye
    x, y, depth = d @ side, d @ true_up, d @ forward
    f = 1.0 / math.tan(camera["fov"] / 2.0)
    return ((f * height / width * x / depth + 1) * width / 2, (1 - f * y / depth) * height / 2)


def page_data(page: Path) -> dict:
    text = page.read_text()
    payload = re.search(r'<script id="isaac-data" type="application/json">(.*?)</script>', text, re.S).group(1)
    return json.loads(payload.replace("<\\/", "</"))


def is_background(image: np.ndarray, pixel) -> bool:
    col, row = int(round(pixel[0])), int(round(pixel[1]))
    patch = image[row - 1:row + 2, col - 1:col + 2].reshape(-1, 3).astype(int)
    return bool((np.abs(patch - BACKGROUND).max(axis=1) < 12).all())


def is_body(image: np.ndarray, pixel, color) -> bool:
    """The pixel shows a lit surface of this colour: far from the background, channels ordered as the colour's."""
    col, row = int(round(pixel[0])), int(round(pixel[1]))
    rgb = image[row, col].astype(float)
    if np.abs(rgb - BACKGROUND).max() < 40:
        return False
    order = np.argsort(color)
    return bool(rgb[order[2]] >= rgb[order[0]])


# ---- scenes and trajectories ------------------------------------------------------------------------------

def swinging_pendulum(period: float = 2.0, frames: int = 101) -> dict:
    """The pendulum scene's bob swinging between +-60 degrees (an analytic stand-in for a run)."""
    t = np.linspace(0.0, period, frames)
    theta0 = math.radians(60.0)
    theta = theta0 * np.cos(2 * math.pi * t / period)
    position = np.stack([np.sin(theta), 1 - np.cos(theta), 0 * t], axis=1)[:, None, :]
    alpha = theta - theta0  # the body turns with the rod
    orientation = np.stack([np.cos(alpha / 2), 0 * t, 0 * t, np.sin(alpha / 2)], axis=1)[:, None, :]
    return {"time": t, "bodies": np.array(["bob"]), "position": position, "orientation": orientation}


def tilted_chain(scene, frames: int = 11) -> dict:
    """The chain's ten links along a straight line from the nail, tilting from 0 to 60 degrees below +x."""
    t = np.linspace(0.0, 0.1 * (frames - 1), frames)
    phi = np.linspace(0.0, math.radians(60.0), frames)
    names = [b.name for b in scene.bodies]
    centres = 0.2 * (np.arange(len(names)) + 0.5)
    position = np.stack([np.cos(phi)[:, None] * centres, -np.sin(phi)[:, None] * centres,
                         np.zeros((frames, len(names)))], axis=2)
    orientation = np.zeros((frames, len(names), 4))
    orientation[..., 0] = np.cos(-phi / 2)[:, None]
    orientation[..., 3] = np.sin(-phi / 2)[:, None]
    return {"time": t, "bodies": np.array(names), "position": position, "orientation": orientation}


# ---- without a browser ------------------------------------------------------------------------------------

def test_viewer_data_round_trips_the_trajectory():
    scene = load_scene(SCENES / "pendulum.isaac").scene
    arrays = swinging_pendulum()
    data = viewer_data(scene, arrays)
    decode = lambda text, dtype: np.frombuffer(base64.b64decode(text), dtype)  # noqa: E731
    assert np.array_equal(decode(data["time"], "<f8"), arrays["time"])
    assert np.allclose(decode(data["position"], "<f4").reshape(-1, 1, 3), arrays["position"], atol=1e-6)
    assert np.allclose(decode(data["orientation"], "<f4").reshape(-1, 1, 4), arrays["orientation"], atol=1e-6)
    (bob,) = data["bodies"]
    vertices = decode(bob["positions"], "<f4").reshape(-1, 3)
    triangles = decode(bob["triangles"], "<u4")
    assert triangles.max() < len(vertices) and np.allclose(np.linalg.norm(vertices, axis=1), 0.05, rtol=1e-5)
    assert data["cameras"][0]["name"] == "main" and data["lights"][0]["type"] == "distant"
    # the nail: its wire starts on the bob's surface, toward the nailed point
    assert data["links"] == [{"body": 0, "point": pytest.approx([-0.866025, 0.5, 0], abs=1e-6),
                              "attach": pytest.approx([-0.0433013, 0.025, 0], abs=1e-6),
                              "target": [0.0, 1.0, 0.0], "start": 0.0, "end": 1e300}]


def test_the_page_is_self_contained():
    scene = load_scene(SCENES / "pendulum.isaac").scene
    data = viewer_data(scene, swinging_pendulum())
    data["note"] = "</script><script>alert(1)</script>"  # data cannot end the data element
    html = render_html(data)
    assert "http://" not in html and "https://" not in html and "//cdn" not in html
    assert not re.search(r"<(script|link|img|audio)[^>]+(src|href)=", html)
    assert "Content-Security-Policy" in html and "default-src 'none'" in html
    assert html.count("</script>") == 2  # the data element's and the script's own, nothing from the data
    assert page_data_from_text(html)["note"] == data["note"]


def page_data_from_text(html: str) -> dict:
    payload = re.search(r'<script id="isaac-data" type="application/json">(.*?)</script>', html, re.S).group(1)
    return json.loads(payload)


def test_isaac_run_writes_the_viewer_cheaply(tmp_path):
    out = tmp_path / "out"
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(out), "--until", "0.3", "--quiet"]) == 0
    assert (out / "viewer.html").is_file()
    data = page_data(out / "viewer.html")
    assert [b["name"] for b in data["bodies"]] == ["bob"] and data["frames"] == 31
    # the cost of the default: a 10 s, 100 Hz run of ten bodies (the chain) in well under a tenth of a second
    scene = load_scene(SCENES / "chain.isaac").scene
    arrays = tilted_chain(scene, frames=1001)
    started = time.perf_counter()
    write_viewer(tmp_path / "chain.html", scene, arrays)
    assert time.perf_counter() - started < 0.1
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(tmp_path / "none"), "--until", "0.1",
                 "--quiet", "--no-viewer"]) == 0
    assert not (tmp_path / "none" / "viewer.html").exists()


def test_a_mesh_that_cannot_be_read_is_drawn_as_a_box_with_a_note(tmp_path):
    # `isaac check` refuses a missing mesh (isaac_lang/assets.py); the viewer still copes with one it cannot read
    scene = load_text('scene m { body rock mesh { file "rock.obj" mass 1 kg inertia (1, 1, 1) kg*m2 '
                      "collide off } }", folder=tmp_path, assets=False).scene
    arrays = {"time": np.zeros(1), "bodies": np.array(["rock"]), "position": np.zeros((1, 1, 3)),
              "orientation": np.array([[[1.0, 0, 0, 0]]])}
    data = viewer_data(scene, arrays, tmp_path)
    assert "rock.obj" in data["note"] and len(data["bodies"]) == 1


# ---- in headless Chromium ---------------------------------------------------------------------------------

@needs_chromium
def test_the_viewer_draws_the_pendulum_where_the_trajectory_puts_it(tmp_path):
    scene = load_scene(SCENES / "pendulum.isaac").scene
    arrays = swinging_pendulum()
    page = write_viewer(tmp_path / "viewer.html", scene, arrays)
    camera = page_data(page)["cameras"][0]
    color = page_data(page)["bodies"][0]["color"]
    # t = 0.5 s: the bottom of the swing; t = 1.0 s: the far side; t = 0.27 s: between two frames
    for t, elsewhere in ((0.5, 1.0), (1.0, 0.0), (0.27, 1.0)):
        image = screenshot(page, f"t={t}&ui=0", tmp_path / f"t{t}.png")
        here = [np.interp(t, arrays["time"], arrays["position"][:, 0, i]) for i in range(3)]
        there = [np.interp(elsewhere, arrays["time"], arrays["position"][:, 0, i]) for i in range(3)]
        assert is_body(image, project(camera, here), color), f"no bob at t = {t} where the trajectory has it"
        assert is_background(image, project(camera, there)), f"the bob of t = {elsewhere} shows at t = {t}"


@needs_chromium
def test_the_viewer_draws_every_link_of_the_chain_from_a_run(tmp_path):
    scene = load_scene(SCENES / "chain.isaac").scene
    arrays = tilted_chain(scene)
    page = write_viewer(tmp_path / "viewer.html", scene, arrays)
    data = page_data(page)
    camera = data["cameras"][0]  # the chain has no camera: the viewer frames the paths
    image = screenshot(page, "t=1.0&ui=0", tmp_path / "chain.png")
    for b, body in enumerate(data["bodies"]):
        assert is_body(image, project(camera, arrays["position"][-1, b]), body["color"]), body["name"]
        assert is_background(image, project(camera, arrays["position"][0, b] + [0, 0.15, 0])), body["name"]
    # and a real run of the pendulum, the first 0.4 s: the bob where the solver put it
    scene = load_scene(SCENES / "pendulum.isaac").scene
    result = simulate(scene, RunOptions(until=0.4))
    real = result.recorder.arrays()
    page = write_viewer(tmp_path / "pendulum.html", scene, real)
    image = screenshot(page, "t=0.4&ui=0", tmp_path / "pendulum.png")
    assert is_body(image, project(page_data(page)["cameras"][0], real["position"][-1, 0]),
                   page_data(page)["bodies"][0]["color"])


@needs_chromium
def test_the_viewer_plays_the_scenes_sound(tmp_path):
    scene = load_scene(SCENES / "pendulum.isaac").scene
    audio = tmp_path / "audio.wav"
    with wave.open(str(audio), "wb") as handle:
        handle.setnchannels(1)
        handle.setsampwidth(2)
        handle.setframerate(8000)
        tone = (8000 * np.sin(2 * np.pi * 440 * np.arange(12000) / 8000)).astype("<i2")
        handle.writeframes(tone.tobytes())
    page = write_viewer(tmp_path / "viewer.html", scene, swinging_pendulum(), audio=audio)
    dom = dump_dom(page.resolve().as_uri() + "#t=0.25")
    assert 'data-audio="yes"' in dom and 'data-audio-duration="1.500"' in dom, dom[-3000:]
    assert 'data-ready="1"' in dom and 'data-time="0.250000"' in dom


@needs_chromium
def test_the_live_page_takes_in_a_new_result_by_itself(tmp_path):
    scene = load_scene(SCENES / "pendulum.isaac").scene
    first = dict(viewer_data(scene, swinging_pendulum()), result=1)
    second = dict(viewer_data(scene, swinging_pendulum(period=1.0)), result=2)
    server = LiveServer("pendulum", port=0)
    server.publish(first, state="complete", message="result #1")
    original = server._get

    def newer_result_once_the_page_asks(route):
        # the page is up and polling: a new result arrives now, and the page must fetch it and show it
        if route == "/status.json" and server.status()["result"] == 1:
            server.publish(second, state="complete", message="result #2")
        return original(route)

    server._get = newer_result_once_the_page_asks
    try:
        dom = dump_dom(server.url, budget_ms=5000)
    finally:
        server.close()
    assert 'data-result="2"' in dom, dom[-3000:]
    assert "result #2" in dom


# ---- the mechanism: what the page draws besides the surfaces (runtime/viewer/mechanism.py) ---------------------

def at_rest(scene) -> dict:
    """One frame: every body where the scene puts it."""
    value = lambda e: np.asarray(getattr(e, "value", e), float)  # noqa: E731
    return {"time": np.zeros(1), "bodies": np.array([b.name for b in scene.bodies]),
            "position": np.array([[value(b.position) for b in scene.bodies]]),
            "orientation": np.array([[value(b.orientation) for b in scene.bodies]])}


def test_the_mobile_hangs_by_a_wire_from_each_surface_to_its_joint():
    scene = load_scene(SCENES / "mobile.isaac").scene
    arrays = at_rest(scene)
    data = viewer_data(scene, arrays)
    names, position = list(arrays["bodies"]), arrays["position"][0]
    joints = data["joints"]
    assert len(joints) == 7  # three rods and four discs, each on a ball joint
    wires = {}
    for joint in joints:
        (hung, holder) = joint["ends"]
        # both anchors are the same world point (the bodies start unturned)
        world = [position[end["body"]] + end["anchor"] for end in (hung, holder)]
        assert np.allclose(world[0], world[1], atol=1e-12)
        # the holder's anchor is on (or in) it: no wire; the hung body's wire starts on its surface
        assert holder["attach"] == pytest.approx(holder["anchor"])
        wires[names[hung["body"]]] = float(np.linalg.norm(np.subtract(hung["anchor"], hung["attach"])))
    # a disc's wire is `wire` (4 cm) long; a rod's is `drop` (12 cm) less the rod's half thickness (2.5 mm)
    assert wires == {"top.left.plate": pytest.approx(0.04), "mid.left.plate": pytest.approx(0.04),
                     "low.left.plate": pytest.approx(0.04), "last.plate": pytest.approx(0.04),
                     "top.rod": pytest.approx(0.1175), "mid.rod": pytest.approx(0.1175),
                     "low.rod": pytest.approx(0.1175)}
    # no plane: a floor under the lowest disc, facing up
    ground = data["ground"]
    assert ground["plane"] == -1 and ground["normal"] == [0.0, 1.0, 0.0]
    assert ground["point"][1] < position[:, 1].min() - 0.08


def test_gears_have_teeth_of_one_pitch_that_mesh():
    from isaac_runtime.viewer.mechanism import SMALL_GEAR_TEETH, gear_teeth

    scene = load_scene(SCENES / "gears.isaac").scene
    teeth = gear_teeth(scene)
    (drive,), (wheel,) = teeth["drive"], teeth["wheel"]
    assert drive[1:] == (0.1, SMALL_GEAR_TEETH) and wheel[1:] == (0.3, 3 * SMALL_GEAR_TEETH)  # radii 1 : 3
    data = viewer_data(scene, at_rest(scene))
    decode = lambda text, dtype: np.frombuffer(base64.b64decode(text), dtype)  # noqa: E731
    module = 2 * math.pi * 0.1 / SMALL_GEAR_TEETH / math.pi  # the same on both: pitch / pi
    for body in data["bodies"]:
        if body["name"] in ("drive", "wheel"):
            vertices = decode(body["positions"], "<f4").reshape(-1, 3)
            radius = {"drive": 0.1, "wheel": 0.3}[body["name"]]
            # the tips reach an addendum (one module) past the pitch circle
            assert np.hypot(vertices[:, 0], vertices[:, 1]).max() == pytest.approx(radius + module, rel=1e-5)


def test_a_spring_is_drawn_between_its_two_points():
    scene = load_text("scene s { body a sphere { radius 5 cm  mass 1 kg  at (0, 0, 0) }  force pull "
                      "spring(a @ (0, 5 cm, 0), (0, 1, 0)) { stiffness 50 N/m } }").scene
    data = viewer_data(scene, at_rest(scene))
    assert data["springs"] == [{"bodies": [0, -1], "points": [[0.0, 0.05, 0.0], [0.0, 1.0, 0.0]],
                                "type": "spring"}]
    # a static plane facing up is the ground
    bounce = load_scene(SCENES / "bounce.isaac").scene
    names = [b.name for b in bounce.bodies]
    assert viewer_data(bounce, at_rest(bounce))["ground"]["plane"] == names.index("floor")


@needs_chromium
def test_the_viewer_draws_the_mobiles_wires_and_their_shadows_on_a_grid(tmp_path):
    scene = load_scene(SCENES / "mobile.isaac").scene
    arrays = at_rest(scene)
    page = write_viewer(tmp_path / "viewer.html", scene, arrays)
    data = page_data(page)
    camera, names, position = data["cameras"][0], list(arrays["bodies"]), arrays["position"][0]
    image = screenshot(page, "t=0&ui=0", tmp_path / "mobile.png").astype(int)
    for joint in data["joints"]:  # halfway along each rod's wire, the wire (light grey on the dark background)
        hung = joint["ends"][0]
        if names[hung["body"]].endswith(".rod"):
            middle = position[hung["body"]] + (np.add(hung["anchor"], hung["attach"]) / 2)
            col, row = (int(round(c)) for c in project(camera, middle))
            assert image[row - 1:row + 2, col - 1:col + 2].max() > 120, names[hung["body"]]
    # the scene has no light: the shadows fall from above and a little in front (draw.js keyLight), each disc's
    # centre cast along that direction onto the floor (y = 0) is darker than the floor beside it
    light = np.array([0.0, 1.0, 0.45]) / np.linalg.norm([0.0, 1.0, 0.45])
    for name in ("top.left.plate", "mid.left.plate", "low.left.plate", "last.plate"):
        centre = position[names.index(name)]
        col, row = (int(round(c)) for c in project(camera, centre - centre[1] / light[1] * light))
        shadow, floor = image[row, col].sum(), min(image[row, col + 60].sum(), image[row - 25, col].sum())
        assert shadow < floor - 15, name
