"""The offline viewer: one self-contained HTML file (page, script, scene, trajectory and sound inside it).

    write_viewer(out / "viewer.html", scene, arrays, folder=scene_folder, audio=out / "audio.wav")

`viewer_data` is what the page draws: every body tessellated in its own frame (isaac_runtime.export.geometry),
its colour, the trajectory's poses (float32, base64), the cameras and lights, and the sound as a data URL.
`isaac watch` serves the same page live (serve.py) with `live: true`, and the page then fetches new data itself;
`isaac live` serves its own page (render_live_html: live.html and live.js) with the same drawing (draw.js).
"""
from __future__ import annotations

import base64
import json
import math
from importlib import resources
from pathlib import Path

import numpy as np

from ..export import geometry
from ..outputs import write_atomic
from .mechanism import gear_teeth, mechanism_data, with_teeth
from .simplify import triangle_share, within_share

# above this many pose numbers (frames x bodies x 7) the viewer keeps every k-th frame: the page stays small
MAX_POSE_VALUES = 4_000_000
# sound files up to this size are embedded; a larger one is referenced beside the page
MAX_EMBEDDED_AUDIO = 64 * 2 ** 20


def write_viewer(path: Path, scene, arrays: dict, folder: Path | None = None, audio: Path | None = None,
                 note: str = "") -> Path:
    """Write the self-contained viewer page for a run to path (atomically); returns path."""
    data = viewer_data(scene, arrays, folder, note=note)
    if audio is not None and Path(audio).is_file():
        data["audio"] = audio_url(Path(audio), Path(path).parent)
    write_atomic(Path(path), render_html(data).encode("utf-8"))
    return Path(path)


def viewer_data(scene, arrays: dict, folder: Path | None = None, note: str = "") -> dict:
    """Everything the page draws, as JSON-able data (see module docstring)."""
    time = np.asarray(arrays["time"], float)
    position = np.asarray(arrays["position"], float)
    orientation = np.asarray(arrays["orientation"], float)
    names = [str(n) for n in arrays["bodies"]]
    keep = _frame_stride(len(time), len(names))
    if keep > 1:
        time, position, orientation = time[::keep], position[::keep], orientation[::keep]
        note = (note + "; " if note else "") + f"every {keep}th frame shown"
    order = _body_order(scene, names)
    colors = geometry.scene_colors(scene)
    size = geometry.plane_size(position)
    bodies, problems = [], []
    gears = gear_teeth(scene)
    for name in names:
        index = order[name]
        body = scene.bodies[index]
        try:
            mesh = geometry.tessellate(body.shape, size, folder)
        except geometry.MeshFileError as error:
            problems.append(str(error))
            mesh = geometry.box((0.1, 0.1, 0.1))
        if name in gears:
            mesh = with_teeth(mesh, body.shape, gears[name])
        mesh, simplified = within_share(mesh, triangle_share(len(names)))
        if simplified:
            problems.append(f"`{name}` drawn simplified: {simplified}")
        bodies.append(_body_data(body, mesh, colors[index]))
    if problems:
        note = "; ".join(([note] if note else []) + [p if p.startswith("`") else f"drawn as a small box: {p}"
                                                     for p in problems])
    cameras = [geometry.camera_of(scene, position, c.name) for c in scene.cameras] or \
        [geometry.framing_camera(position)]
    return {
        "scene": scene.name, "start": scene.time.start, "end": scene.time.end, "frame_rate": scene.time.frame_rate,
        "cameras": cameras, "lights": [_light_data(light) for light in scene.lights], "bodies": bodies,
        **mechanism_data(scene, names, position),
        "time": _b64(time, np.float64), "position": _b64(position, np.float32),
        "orientation": _b64(orientation, np.float32), "frames": int(len(time)), "note": note,
        "audio": None, "live": False, "result": 0,
    }


def render_html(data: dict) -> str:
    """The page with its data: script and data inlined, so that it opens from disk with no network."""
    return _page("template.html", ("draw.js", "viewer.js"), data)


def render_live_html(data: dict) -> str:
    """The page of `isaac live`: the same drawing, fed by the server's stream of poses (live.js)."""
    return _page("live.html", ("draw.js", "live.js"), data)


def _page(template_name: str, scripts: tuple, data: dict) -> str:
    folder = resources.files(__package__)
    template = folder.joinpath(template_name).read_text(encoding="utf-8")
    script = "\n".join(folder.joinpath(name).read_text(encoding="utf-8") for name in scripts)
    # `</` must not appear inside a <script> element: JSON allows the equivalent `<\/`
    payload = json.dumps(data, separators=(",", ":"), allow_nan=False).replace("</", "<\\/")
    return (template.replace("/*ISAAC_TITLE*/", _html_escape(data["scene"]))
            .replace("/*ISAAC_DATA*/", payload)
            .replace("/*ISAAC_SCRIPT*/", script.replace("</script", "<\\/script")))


def audio_url(audio: Path, page_folder: Path) -> str:
    """A data URL of the sound (so the page stays self-contained), or a relative path for a huge file."""
    if audio.stat().st_size <= MAX_EMBEDDED_AUDIO:
        return "data:audio/wav;base64," + base64.b64encode(audio.read_bytes()).decode("ascii")
    try:
        return audio.resolve().relative_to(page_folder.resolve()).as_posix()
    except ValueError:
        return audio.resolve().as_uri()


# ---- helpers ----------------------------------------------------------------------------------------------

def _body_data(body, mesh: geometry.TriMesh, color) -> dict:
    triangles = mesh.triangles.astype(np.uint32)
    return {
        "name": body.name, "shape": body.shape.type, "motion": body.motion, "color": [float(c) for c in color],
        "two_sided": bool(mesh.two_sided), "positions": _b64(mesh.positions, np.float32),
        "triangles": _b64(triangles, np.uint32), "tone": _b64(mesh.tone, np.uint8) if mesh.tone is not None else None,
    }


def _light_data(light) -> dict:
    return {"name": light.name, "type": light.type, "position": list(light.position), "target": list(light.target),
            "intensity": light.intensity, "color": list(light.color), "cone": math.radians(30.0)}


def _body_order(scene, names: list) -> dict:
    index = scene.body_index()
    missing = [n for n in names if n not in index]
    if missing:
        raise ValueError(f"the trajectory names bodies the scene does not have: {', '.join(missing)}")
    return index


def _frame_stride(frames: int, bodies: int) -> int:
    values = frames * max(bodies, 1) * 7
    return max(1, math.ceil(values / MAX_POSE_VALUES))


def _b64(array: np.ndarray, dtype) -> str:
    # little-endian, as every browser's typed arrays on every machine Isaac runs on
    return base64.b64encode(np.ascontiguousarray(array, dtype=np.dtype(dtype).newbyteorder("<")).tobytes()).decode()


def _html_escape(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")
