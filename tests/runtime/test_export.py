"""Exports: RenderMan RIB (golden text, and a RIB reader here that checks structure) and glTF 2.0 (a structural
check against the specification: buffers, views, accessors, one translation and one rotation channel per body),
for a scene of every shape and for the chain; `isaac export` finds, reuses or makes the run it exports.

Regenerate the golden RIB after an intended change: ISAAC_REGEN_GOLDEN=1 pytest tests/runtime/test_export.py
"""
from __future__ import annotations

import base64
import json
import math
import os
import re
import struct
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main
from isaac_lang.load import load_scene, load_text
from isaac_runtime.export import geometry
from isaac_runtime.export.gltf import gltf_document, write_gltf
from isaac_runtime.export.rib import RibOptions, write_rib
from isaac_runtime.outputs import write_npz
from isaac_runtime.run import RunOptions, simulate

SCENES = Path(__file__).resolve().parents[2] / "scenes"
GOLDEN = Path(__file__).resolve().parent / "golden"

SHAPES = """
scene shapes {
  time 0 s .. 1 s
  frames 10 Hz
  camera main { at (0, 1.2, 3)  look (0, 0.3, 0)  fov 45 deg }
  camera side { at (3, 1, 0)  look (0, 0.3, 0) }
  light key distant { from (-1, 2, 3)  to (0, 0, 0)  intensity 0.8 }
  light bulb point { at (2, 2, 2)  intensity 0.3  color (1, 0.9, 0.7) }
  light beam spot { at (0, 3, 0)  to (0, 0, 0) }
  light sky ambient { intensity 0.2 }
  body floor plane { collide off }
  body crate box { size (0.3, 0.2, 0.2) m  mass 1 kg  at (-0.8, 0.6, 0)  collide off }
  body ball sphere { radius 10 cm  mass 1 kg  at (-0.3, 0.6, 0)  collide off }
  body drum cylinder { radius 10 cm  length 30 cm  mass 1 kg  at (0.2, 0.6, 0)  collide off }
  body pill capsule { radius 8 cm  length 20 cm  mass 1 kg  at (0.7, 0.6, 0)  orient (90, 0, 0)  collide off }
  body tet mesh { file "tet.obj"  mass 1 kg  inertia (0.01, 0.01, 0.01) kg*m2  at (1.2, 0.6, 0)  collide off }
}
"""
TETRAHEDRON = "v 0 0 0\nv 0.2 0 0\nv 0 0.2 0\nv 0 0 0.2\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3/7 4//1\n"


@pytest.fixture
def shapes(tmp_path):
    """The every-shape scene and a made-up trajectory: three frames, every moving body falling and turning."""
    (tmp_path / "tet.obj").write_text(TETRAHEDRON)
    scene = load_text(SHAPES, "shapes.isaac", folder=tmp_path).scene
    names = [b.name for b in scene.bodies]
    start = np.array([[0, 0, 0], [-0.8, 0.6, 0], [-0.3, 0.6, 0], [0.2, 0.6, 0], [0.7, 0.6, 0], [1.2, 0.6, 0]], float)
    time = np.array([0.0, 0.1, 0.2])
    fall = np.zeros((len(time), len(names), 3))
    fall[:, 1:, 1] = -4.905 * time[:, None] ** 2  # all but the floor
    position = start[None] + fall
    angle = 2.0 * time[:, None] * np.arange(len(names))[None, :]  # body b turns about x at 2b rad/s
    orientation = np.stack([np.cos(angle / 2), np.sin(angle / 2), 0 * angle, 0 * angle], axis=2)
    pill = np.array([math.cos(math.pi / 4), math.sin(math.pi / 4), 0, 0])  # the capsule's 90 degrees about x
    orientation[:, 4] = pill
    return scene, {"time": time, "bodies": np.array(names), "position": position, "orientation": orientation}, tmp_path


# ---- a RIB reader ----------------------------------------------------------------------------------------

TOKEN = re.compile(r'\s*(?:(#[^\n]*)|("[^"]*")|(\[)|(\])|([-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?)|([A-Za-z]\w*))')
# request: (positional arguments, whether a parameter list may follow)
REQUESTS = {"version": (1, False), "FrameBegin": (1, False), "FrameEnd": (0, False), "WorldBegin": (0, False),
            "WorldEnd": (0, False), "AttributeBegin": (0, False), "AttributeEnd": (0, False),
            "TransformBegin": (0, False), "TransformEnd": (0, False), "MotionBegin": (1, False),
            "MotionEnd": (0, False), "Display": (3, True), "Format": (3, False), "PixelSamples": (2, False),
            "Projection": (1, True), "Clipping": (2, False), "Shutter": (2, False), "Scale": (3, False),
            "Translate": (3, False), "ConcatTransform": (1, False), "LightSource": (2, True),
            "Attribute": (1, True), "Color": (1, False), "Surface": (1, True), "Sphere": (4, True),
            "Cylinder": (4, True), "Disk": (3, True), "ReverseOrientation": (0, False), "Polygon": (0, True),
            "PointsPolygons": (2, True)}
BLOCKS = {"FrameEnd": "FrameBegin", "WorldEnd": "WorldBegin", "AttributeEnd": "AttributeBegin",
          "TransformEnd": "TransformBegin", "MotionEnd": "MotionBegin"}
PRIMITIVES = {"Sphere", "Cylinder", "Disk", "Polygon", "PointsPolygons"}


def read_rib(text: str) -> list:
    """The requests of a RIB file as (name, positional arguments, parameters), checking what RISpec asks of the
    requests written here: argument counts and types, balanced blocks, motion blocks with one transform per
    time, primitives only inside a world, polygons with whole points and indices that exist."""
    assert text.startswith("##RenderMan RIB\n")
    tokens, pos = [], 0
    while pos < len(text.rstrip()):
        match = TOKEN.match(text, pos)
        assert match and match.end() > pos, f"unreadable RIB at {text[pos:pos + 40]!r}"
        pos = match.end()
        comment, string, open_, close, number, word = match.groups()
        if comment is None:
            tokens.append(("s", string[1:-1]) if string else ("[", None) if open_ else ("]", None) if close
                          else ("n", float(number)) if number else ("w", word))
    requests, i = [], 0
    while i < len(tokens):
        kind, name = tokens[i]
        assert kind == "w" and name in REQUESTS, f"not a request: {tokens[i]}"
        values, i = [], i + 1
        while i < len(tokens) and tokens[i][0] != "w":
            if tokens[i][0] == "[":
                end = tokens.index(("]", None), i)
                values.append([v for _, v in tokens[i + 1:end]])
                i = end + 1
            else:
                values.append(tokens[i][1])
                i += 1
        count, has_params = REQUESTS[name]
        positional, rest = values[:count], values[count:]
        assert len(positional) == count, f"{name} wants {count} arguments: {values}"
        assert has_params or not rest, f"{name}: unexpected {rest}"
        assert len(rest) % 2 == 0 and all(isinstance(k, str) for k in rest[::2]), f"{name}: bad parameters {rest}"
        requests.append((name, positional, dict(zip(rest[::2], rest[1::2]))))
    _check_structure(requests)
    return requests


def _check_structure(requests: list) -> None:
    stack, motion = [], None
    for name, args, params in requests:
        if name.endswith("Begin"):
            stack.append(name)
            if name == "MotionBegin":
                motion = (len(args[0]), [])
        elif name in BLOCKS:
            assert stack and stack.pop() == BLOCKS[name], f"{name} closes nothing open"
            if name == "MotionEnd":
                assert len(motion[1]) == motion[0] and len(set(motion[1])) == 1, motion
                motion = None
        elif motion is not None:
            motion[1].append(name)
        if name == "ConcatTransform":
            assert len(args[0]) == 16 and args[0][3::4] == [0, 0, 0, 1], args[0]
        if name == "Color":
            assert len(args[0]) == 3
        if name in PRIMITIVES:
            assert "WorldBegin" in stack and "FrameBegin" in stack, f"{name} outside a world"
        if name in ("Polygon", "PointsPolygons"):
            points = params["P"]
            assert len(points) % 3 == 0 and all(math.isfinite(v) for v in points)
        if name == "PointsPolygons":
            counts, indices = args
            assert sum(counts) == len(indices) and max(indices) < len(params["P"]) // 3
    assert not stack, f"unclosed: {stack}"


# ---- a glTF checker --------------------------------------------------------------------------------------

COMPONENTS = {5126: ("<f4", 4), 5125: ("<u4", 4), 5123: ("<u2", 2)}
WIDTHS = {"SCALAR": 1, "VEC2": 2, "VEC3": 3, "VEC4": 4, "MAT4": 16}


def check_gltf(doc: dict, binary: bytes) -> dict:
    """Check a glTF document against the specification's structural rules; returns every accessor's data."""
    assert doc["asset"]["version"] == "2.0"
    assert len(doc["buffers"]) == 1 and doc["buffers"][0]["byteLength"] <= len(binary)
    for view in doc["bufferViews"]:
        assert view["byteOffset"] % 4 == 0 and view["byteOffset"] + view["byteLength"] <= len(binary)
    data = {}
    for k, accessor in enumerate(doc["accessors"]):
        view = doc["bufferViews"][accessor["bufferView"]]
        dtype, size = COMPONENTS[accessor["componentType"]]
        width = WIDTHS[accessor["type"]]
        assert accessor["count"] * width * size <= view["byteLength"]
        values = np.frombuffer(binary, dtype, accessor["count"] * width, view["byteOffset"])
        values = values.reshape(accessor["count"], width)
        if "min" in accessor:
            assert np.allclose(values.min(axis=0), accessor["min"]) and np.allclose(values.max(axis=0), accessor["max"])
        data[k] = values
    nodes = doc["nodes"]
    for scene in doc["scenes"]:
        assert all(0 <= n < len(nodes) for n in scene["nodes"])
    for mesh in doc["meshes"]:
        for primitive in mesh["primitives"]:
            position = doc["accessors"][primitive["attributes"]["POSITION"]]
            assert "min" in position and "max" in position and position["type"] == "VEC3"
            assert doc["accessors"][primitive["attributes"]["NORMAL"]]["count"] == position["count"]
            indices = data[primitive["indices"]]
            assert indices.max() < position["count"] and len(indices) % 3 == 0
            assert 0 <= primitive["material"] < len(doc["materials"])
            normals = data[primitive["attributes"]["NORMAL"]]
            assert np.allclose(np.linalg.norm(normals, axis=1), 1.0, atol=1e-5)
    for animation in doc["animations"]:
        for sampler in animation["samplers"]:
            times = data[sampler["input"]].ravel()
            assert times[0] >= 0 and np.all(np.diff(times) > 0), "animation times must increase from >= 0"
            assert "min" in doc["accessors"][sampler["input"]]
            assert len(data[sampler["output"]]) == len(times) and sampler["interpolation"] == "LINEAR"
        for channel in animation["channels"]:
            sampler = animation["samplers"][channel["sampler"]]
            values = data[sampler["output"]]
            assert 0 <= channel["target"]["node"] < len(nodes)
            if channel["target"]["path"] == "rotation":
                assert values.shape[1] == 4 and np.allclose(np.linalg.norm(values, axis=1), 1.0, atol=1e-6)
            else:
                assert channel["target"]["path"] == "translation" and values.shape[1] == 3
    return data


def read_glb(blob: bytes) -> tuple:
    magic, version, length = struct.unpack_from("<III", blob, 0)
    assert (magic, version, length) == (0x46546C67, 2, len(blob))
    json_length, json_kind = struct.unpack_from("<II", blob, 12)
    assert json_kind == 0x4E4F534A and json_length % 4 == 0
    doc = json.loads(blob[20:20 + json_length])
    bin_length, bin_kind = struct.unpack_from("<II", blob, 20 + json_length)
    assert bin_kind == 0x004E4942 and bin_length % 4 == 0 and 28 + json_length + bin_length == len(blob)
    return doc, blob[28 + json_length:]


def channels_per_body(doc: dict) -> dict:
    """{body name: sorted paths animated} over the document's one animation."""
    (animation,) = doc["animations"]
    paths = {}
    for channel in animation["channels"]:
        paths.setdefault(doc["nodes"][channel["target"]["node"]]["name"], []).append(channel["target"]["path"])
    return {name: sorted(p) for name, p in paths.items()}


# ---- RIB --------------------------------------------------------------------------------------------------

def test_rib_of_every_shape_matches_the_golden_text(shapes, tmp_path):
    scene, arrays, folder = shapes
    (path,) = write_rib(tmp_path / "rib", scene, arrays, RibOptions(width=640, height=360, sequence=True,
                                                                      motion_blur=True), folder)
    text = path.read_text()
    golden = GOLDEN / "shapes.rib"
    if os.environ.get("ISAAC_REGEN_GOLDEN"):
        golden.parent.mkdir(parents=True, exist_ok=True)
        golden.write_text(text)
    assert text == golden.read_text(), f"RIB changed; if intended, regenerate: ISAAC_REGEN_GOLDEN=1 ({path})"
    requests = read_rib(text)
    names = [r[0] for r in requests]
    assert names.count("FrameBegin") == 3 and names.count("MotionBegin") == 3 * 5  # the floor does not move
    kinds = {n for n in names if n in PRIMITIVES}
    assert kinds == PRIMITIVES  # quadrics for the round shapes, polygons for the rest


def test_rib_frame_files_camera_and_lights(shapes, tmp_path):
    scene, arrays, folder = shapes
    paths = write_rib(tmp_path / "rib", scene, arrays, RibOptions(frames=slice(1, 3), camera="side"), folder)
    assert [p.name for p in paths] == ["shapes.0001.rib", "shapes.0002.rib"]
    requests = read_rib(paths[0].read_text())
    by_name = {}
    for name, args, params in requests:
        by_name.setdefault(name, []).append((args, params))
    assert "Shutter" not in by_name and "MotionBegin" not in by_name
    assert [a[0] for a, _ in by_name["LightSource"]] == ["ambientlight", "distantlight", "pointlight", "spotlight"]
    assert by_name["LightSource"][0][1]["intensity"] == [pytest.approx(0.3)]  # 0.1 + the scene's ambient 0.2
    assert by_name["Display"][0][0][0] == "shapes.0001.tif"
    # the camera: the look-at point lands in the middle of the picture, in front (RenderMan's camera looks down +z)
    scale = np.diag([1.0, 1.0, -1.0, 1.0])
    (view,) = [np.array(a[0]).reshape(4, 4).T for a, _ in by_name["ConcatTransform"][:1]]
    camera_point = scale @ view @ np.array([0, 0.3, 0, 1.0])
    assert np.allclose(camera_point[:2], 0, atol=1e-6) and camera_point[2] == pytest.approx(math.hypot(3, 0.7), 1e-5)
    # a body's transform puts its centre where the trajectory has it at that frame
    ball = next(i for i, (n, a, p) in enumerate(requests) if n == "Attribute" and p.get("name") == ["ball"])
    matrix = np.array(requests[ball + 3][1][0]).reshape(4, 4).T
    assert np.allclose(matrix[:3, 3], arrays["position"][1, 2], atol=1e-6)


def test_rib_and_gltf_of_the_chain_are_well_formed(tmp_path):
    scene = load_scene(SCENES / "chain.isaac").scene
    arrays = simulate(scene, RunOptions(until=0.05)).recorder.arrays()
    write_npz(tmp_path / "chain.npz", arrays)
    out = tmp_path / "out"
    for fmt in ("rib", "gltf", "glb"):
        args = ["export", str(SCENES / "chain.isaac"), "--format", fmt, "--out", str(out),
                "--trajectory", str(tmp_path / "chain.npz")]
        assert main(args + (["--sequence", "--motion-blur"] if fmt == "rib" else [])) == 0
    requests = read_rib((out / "rib" / "chain.rib").read_text())
    assert sum(1 for r in requests if r[0] == "FrameBegin") == len(arrays["time"])
    assert sum(1 for r in requests if r[0] == "PointsPolygons") == 10 * len(arrays["time"])
    doc = json.loads((out / "chain.gltf").read_text())
    uri = doc["buffers"][0]["uri"]
    assert uri.startswith("data:application/octet-stream;base64,")
    binary = base64.b64decode(uri.split(",", 1)[1])
    data = check_gltf(doc, binary)
    names = [f"link{i}" for i in range(10)]
    assert channels_per_body(doc) == {name: ["rotation", "translation"] for name in names}
    glb_doc, glb_binary = read_glb((out / "chain.glb").read_bytes())
    check_gltf(glb_doc, glb_binary)
    assert channels_per_body(glb_doc) == channels_per_body(doc)
    # the animation is the trajectory: link3's translation at every frame, its rotation reordered to x,y,z,w
    (animation,) = doc["animations"]
    node = next(i for i, n in enumerate(doc["nodes"]) if n["name"] == "link3")
    for channel in animation["channels"]:
        if channel["target"]["node"] == node:
            values = data[animation["samplers"][channel["sampler"]]["output"]]
            if channel["target"]["path"] == "translation":
                assert np.allclose(values, arrays["position"][:, 3], atol=1e-6)
            else:
                q = arrays["orientation"][:, 3][:, [1, 2, 3, 0]]
                assert np.allclose(np.abs(np.einsum("ti,ti->t", values, q)), 1.0, atol=1e-6)


# ---- glTF -------------------------------------------------------------------------------------------------

def test_gltf_of_every_shape_has_meshes_cameras_lights_and_an_animation(shapes, tmp_path):
    scene, arrays, folder = shapes
    doc, binary = gltf_document(scene, arrays, folder)
    data = check_gltf(doc, binary)
    assert len(doc["meshes"]) == 6 and doc["materials"][0]["doubleSided"]  # the floor: seen from both sides
    assert channels_per_body(doc) == {b.name: ["rotation", "translation"] for b in scene.bodies}
    lights = doc["extensions"]["KHR_lights_punctual"]["lights"]
    assert [light["type"] for light in lights] == ["directional", "point", "spot"]  # glTF has no ambient light
    # each camera node looks (down its -z) at the camera's look-at point
    for camera in scene.cameras:
        node = next(n for n in doc["nodes"] if n.get("name") == camera.name and "camera" in n)
        x, y, z, w = node["rotation"]
        R = np.array([[1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
                      [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
                      [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)]])
        looking = R @ [0, 0, -1.0]
        wanted = np.subtract(camera.look_at, camera.position)
        assert np.allclose(looking, wanted / np.linalg.norm(wanted), atol=1e-6)
    (animation,) = doc["animations"]
    times = data[animation["samplers"][0]["input"]].ravel()
    assert np.allclose(times, arrays["time"])
    glb = write_gltf(tmp_path / "shapes.glb", scene, arrays, folder)
    check_gltf(*read_glb(glb.read_bytes()))


def test_quaternions_keep_one_hemisphere_for_linear_interpolation(shapes):
    scene, arrays, folder = shapes
    arrays = dict(arrays)
    arrays["orientation"] = arrays["orientation"].copy()
    arrays["orientation"][1] *= -1.0  # the same rotations, written with the other sign
    doc, binary = gltf_document(scene, arrays, folder)
    data = check_gltf(doc, binary)
    for channel in doc["animations"][0]["channels"]:
        if channel["target"]["path"] == "rotation":
            q = data[doc["animations"][0]["samplers"][channel["sampler"]]["output"]]
            assert np.all(np.einsum("ti,ti->t", q[1:], q[:-1]) > 0)


# ---- isaac export -----------------------------------------------------------------------------------------

TINY = """
scene tiny {
  time 0 s .. 0.1 s
  frames 50 Hz
  body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0)  collide off }
}
"""


def test_export_runs_the_scene_once_then_reuses_the_run(tmp_path, capsys):
    scene = tmp_path / "tiny.isaac"
    scene.write_text(TINY)
    out = tmp_path / "out"
    assert main(["export", str(scene), "--format", "gltf", "--out", str(out)]) == 0
    assert "a new run" in capsys.readouterr().out
    assert (out / "trajectory.npz").is_file() and (out / "tiny.gltf").is_file()
    assert main(["export", str(scene), "--format", "rib", "--out", str(out), "--frames", "2:6:2"]) == 0
    assert "this scene's last run" in capsys.readouterr().out
    assert sorted(p.name for p in (out / "rib").iterdir()) == ["tiny.0002.rib", "tiny.0004.rib"]
    scene.write_text(TINY.replace("(0, 1, 0)", "(0, 2, 0)"))  # a changed scene: its old run does not count
    assert main(["export", str(scene), "--format", "glb", "--out", str(out)]) == 0
    assert "a new run" in capsys.readouterr().out


@pytest.mark.parametrize("bad", [["--frames", "a:b"], ["--size", "big"], ["--camera", "nope"],
                                 ["--trajectory", "missing.npz"]])
def test_export_usage_mistakes_are_scene_errors_not_tracebacks(tmp_path, capsys, bad):
    scene = tmp_path / "tiny.isaac"
    scene.write_text(TINY)
    assert main(["export", str(scene), "--format", "rib", "--out", str(tmp_path / "o"), *bad]) == 2
    err = capsys.readouterr().err
    assert "error:" in err and "Traceback" not in err


# ---- shared geometry --------------------------------------------------------------------------------------

def test_obj_and_both_kinds_of_stl_read_the_same_triangles(tmp_path):
    (tmp_path / "t.obj").write_text(TETRAHEDRON)
    vertices, triangles = geometry.read_mesh(tmp_path / "t.obj")
    corners = vertices[triangles]
    ascii_stl = "solid t\n" + "".join(
        "facet normal 0 0 0\nouter loop\n" + "".join(f"vertex {x} {y} {z}\n" for x, y, z in tri) +
        "endloop\nendfacet\n" for tri in corners) + "endsolid t\n"
    (tmp_path / "a.stl").write_text(ascii_stl)
    binary = b"\0" * 80 + struct.pack("<I", len(corners)) + b"".join(
        struct.pack("<12fH", 0, 0, 0, *tri.ravel(), 0) for tri in corners)
    (tmp_path / "b.stl").write_bytes(binary)
    canonical = lambda v, t: sorted(tuple(map(tuple, np.round(v[tri], 6))) for tri in t)  # noqa: E731
    for name in ("a.stl", "b.stl"):
        assert canonical(*geometry.read_mesh(tmp_path / name)) == canonical(vertices, triangles)
    (tmp_path / "bad.obj").write_text("v 0 0 0\nf 1 2 x\n")
    with pytest.raises(geometry.MeshFileError, match="bad.obj:2"):
        geometry.read_mesh(tmp_path / "bad.obj")


@pytest.mark.parametrize("make", [lambda: geometry.sphere(0.5), lambda: geometry.box((1, 2, 3)),
                                  lambda: geometry.cylinder(0.5, 2), lambda: geometry.capsule(0.5, 1)])
def test_closed_shapes_face_outward_and_enclose_their_volume(make):
    mesh = make()
    corners = mesh.positions[mesh.triangles]
    normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    assert np.all(np.einsum("ij,ij->i", normals, corners.mean(axis=1)) > 0)  # counter-clockwise from outside
    # divergence theorem: the signed volume is positive and near the shape's (tessellation makes it smaller)
    volume = np.einsum("ij,ij->i", corners[:, 0], np.cross(corners[:, 1], corners[:, 2])).sum() / 6
    assert volume > 0
