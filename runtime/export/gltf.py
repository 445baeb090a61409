"""glTF 2.0 export: every body a node with its mesh and material, the scene's cameras and lights, and one
animation that moves every body through the run (a translation and a rotation channel per body).

    write_gltf(out / "pendulum.gltf", scene, arrays)   # JSON, the buffer inside as a data URI
    write_gltf(out / "pendulum.glb", scene, arrays)    # binary container: one file, smaller

glTF is y-up, right-handed, in metres, as the IR, so positions go over unchanged; quaternions are reordered from
(w, x, y, z) to glTF's (x, y, z, w) and kept in one hemisphere from frame to frame (LINEAR rotation is a slerp).
Animation times are seconds from the scene's start (glTF wants them >= 0). Lights use KHR_lights_punctual
(directional, point, spot); glTF has no ambient light, so an ambient light is left out. Loads in Blender's
importer and three.js's GLTFLoader; tests check the structure against the specification.
"""
from __future__ import annotations

import base64
import json
import math
import struct
from pathlib import Path

import numpy as np

from ..outputs import write_atomic
from . import geometry

FLOAT, UINT32 = 5126, 5125  # accessor componentType
ARRAY_BUFFER, ELEMENT_ARRAY_BUFFER = 34962, 34963  # bufferView target
GLB_MAGIC, GLB_JSON, GLB_BIN = 0x46546C67, 0x4E4F534A, 0x004E4942


class _Buffer:
    """The one binary buffer, built view by view (each 4-byte aligned), with the accessors that read it."""

    def __init__(self, doc: dict):
        self.doc = doc
        self.chunks: list = []
        self.length = 0

    def accessor(self, array: np.ndarray, kind: str, component: int = FLOAT, target: int | None = None,
                 bounds: bool = False) -> int:
        array = np.ascontiguousarray(array, dtype="<f4" if component == FLOAT else "<u4")
        view = {"buffer": 0, "byteOffset": self.length, "byteLength": array.nbytes}
        if target is not None:
            view["target"] = target
        self.chunks.append(array.tobytes() + b"\0" * (-array.nbytes % 4))
        self.length += array.nbytes + (-array.nbytes % 4)
        self.doc["bufferViews"].append(view)
        width = {"SCALAR": 1, "VEC3": 3, "VEC4": 4}[kind]
        accessor = {"bufferView": len(self.doc["bufferViews"]) - 1, "componentType": component,
                    "count": int(array.size // width), "type": kind}
        if bounds:
            flat = array.reshape(-1, width).astype(float)
            accessor["min"] = [float(v) for v in flat.min(axis=0)]
            accessor["max"] = [float(v) for v in flat.max(axis=0)]
        self.doc["accessors"].append(accessor)
        return len(self.doc["accessors"]) - 1

    def bytes(self) -> bytes:
        return b"".join(self.chunks)


def gltf_document(scene, arrays: dict, folder: Path | None = None) -> tuple:
    """The glTF JSON (a dict, without its buffer's location) and the binary buffer."""
    time, position, orientation, names = _finite_frames(arrays)
    doc = {"asset": {"version": "2.0", "generator": "isaac export"}, "scene": 0,
           "scenes": [{"name": scene.name, "nodes": []}], "nodes": [], "meshes": [], "materials": [],
           "accessors": [], "bufferViews": [], "buffers": [], "animations": []}
    buffer = _Buffer(doc)
    roots = doc["scenes"][0]["nodes"]
    index = scene.body_index()
    colors = geometry.scene_colors(scene)
    size = geometry.plane_size(position)
    quats = _xyzw_continuous(orientation)
    body_nodes = []
    for b, name in enumerate(names):
        body = scene.bodies[index[name]]
        mesh = geometry.tessellate(body.shape, size, folder)
        doc["materials"].append(_material(body, colors[index[name]], mesh.two_sided))
        primitive = {"attributes": {"POSITION": buffer.accessor(mesh.positions, "VEC3", target=ARRAY_BUFFER,
                                                                 bounds=True),
                                    "NORMAL": buffer.accessor(mesh.normals, "VEC3", target=ARRAY_BUFFER)},
                     "indices": buffer.accessor(mesh.triangles.ravel(), "SCALAR", UINT32, ELEMENT_ARRAY_BUFFER),
                     "material": len(doc["materials"]) - 1, "mode": 4}
        doc["meshes"].append({"name": name, "primitives": [primitive]})
        doc["nodes"].append({"name": name, "mesh": len(doc["meshes"]) - 1,
                             "translation": [float(v) for v in position[0, b]],
                             "rotation": [float(v) for v in quats[0, b]]})
        body_nodes.append(len(doc["nodes"]) - 1)
        roots.append(body_nodes[-1])
    _cameras(doc, scene, position)
    _lights(doc, scene)
    _animation(doc, buffer, scene, time, position, quats, body_nodes)
    binary = buffer.bytes()
    doc["buffers"].append({"byteLength": len(binary)})
    return doc, binary


def write_gltf(path: Path, scene, arrays: dict, folder: Path | None = None) -> Path:
    """Write `.gltf` (JSON with the buffer as a data URI) or `.glb` (binary), by path's suffix."""
    path = Path(path)
    doc, binary = gltf_document(scene, arrays, folder)
    if path.suffix.lower() == ".glb":
        write_atomic(path, glb_bytes(doc, binary))
    else:
        doc["buffers"][0]["uri"] = "data:application/octet-stream;base64," + base64.b64encode(binary).decode()
        write_atomic(path, (json.dumps(doc, indent=1, allow_nan=False) + "\n").encode("utf-8"))
    return path


def glb_bytes(doc: dict, binary: bytes) -> bytes:
    """The binary container: a 12-byte header, a JSON chunk (space padded) and a BIN chunk (zero padded)."""
    text = json.dumps(doc, separators=(",", ":"), allow_nan=False).encode("utf-8")
    text += b" " * (-len(text) % 4)
    binary += b"\0" * (-len(binary) % 4)
    total = 12 + 8 + len(text) + 8 + len(binary)
    return (struct.pack("<III", GLB_MAGIC, 2, total) + struct.pack("<II", len(text), GLB_JSON) + text +
            struct.pack("<II", len(binary), GLB_BIN) + binary)


# ---- parts ------------------------------------------------------------------------------------------------

def _material(body, color, two_sided: bool) -> dict:
    return {"name": body.material or body.name, "doubleSided": bool(two_sided),
            "pbrMetallicRoughness": {"baseColorFactor": [float(c) for c in color] + [1.0],
                                     "metallicFactor": 0.0, "roughnessFactor": 0.6}}


def _cameras(doc: dict, scene, position: np.ndarray) -> None:
    cameras = [geometry.camera_of(scene, position, c.name) for c in scene.cameras] or \
        [geometry.framing_camera(position)]
    for camera in cameras:
        doc.setdefault("cameras", []).append({"name": camera["name"], "type": "perspective",
                                              "perspective": {"yfov": float(camera["fov"]), "znear": 0.01}})
        view = geometry.look_at_matrix(camera["position"], camera["look_at"], camera["up"])
        # a glTF camera looks down its -z with y up: its rotation is the inverse of the view's
        doc["nodes"].append({"name": camera["name"], "camera": len(doc["cameras"]) - 1,
                             "translation": [float(v) for v in camera["position"]],
                             "rotation": _matrix_to_xyzw(view[:3, :3].T)})
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)


def _lights(doc: dict, scene) -> None:
    lights = []
    for light in scene.lights:
        if light.type == "ambient":
            continue
        kind = {"distant": "directional", "point": "point", "spot": "spot"}[light.type]
        entry = {"name": light.name, "type": kind, "color": [float(c) for c in light.color],
                 "intensity": float(light.intensity)}
        if kind == "spot":
            entry["spot"] = {"innerConeAngle": 0.0, "outerConeAngle": math.radians(30.0)}
        lights.append(entry)
        node = {"name": light.name, "extensions": {"KHR_lights_punctual": {"light": len(lights) - 1}}}
        if kind != "directional":
            node["translation"] = [float(v) for v in light.position]
        if kind != "point":  # these shine down their -z: turn -z toward the target
            view = geometry.look_at_matrix(light.position, light.target, _up_for(light))
            node["rotation"] = _matrix_to_xyzw(view[:3, :3].T)
        doc["nodes"].append(node)
        doc["scenes"][0]["nodes"].append(len(doc["nodes"]) - 1)
    if lights:
        doc["extensionsUsed"] = ["KHR_lights_punctual"]
        doc["extensions"] = {"KHR_lights_punctual": {"lights": lights}}


def _animation(doc: dict, buffer: _Buffer, scene, time, position, quats, nodes: list) -> None:
    times = buffer.accessor(time - scene.time.start, "SCALAR", bounds=True)
    samplers, channels = [], []
    for b, node in enumerate(nodes):
        for path, values, kind in (("translation", position[:, b], "VEC3"), ("rotation", quats[:, b], "VEC4")):
            samplers.append({"input": times, "output": buffer.accessor(values, kind), "interpolation": "LINEAR"})
            channels.append({"sampler": len(samplers) - 1, "target": {"node": node, "path": path}})
    doc["animations"].append({"name": scene.name, "samplers": samplers, "channels": channels})


def _finite_frames(arrays: dict) -> tuple:
    """The frames before the first non-finite pose (a run that blew up keeps what it had)."""
    time = np.asarray(arrays["time"], float)
    position = np.asarray(arrays["position"], float)
    orientation = np.asarray(arrays["orientation"], float)
    ok = np.isfinite(position).all(axis=(1, 2)) & np.isfinite(orientation).all(axis=(1, 2))
    count = int(np.argmin(ok)) if not ok.all() else len(time)
    if count == 0:
        raise ValueError("the trajectory has no finite frame to export")
    return time[:count], position[:count], orientation[:count], [str(n) for n in arrays["bodies"]]


def _xyzw_continuous(orientation: np.ndarray) -> np.ndarray:
    """(T,B,4) w,x,y,z -> unit x,y,z,w with each frame's sign chosen to be nearest the previous frame's."""
    q = orientation / np.linalg.norm(orientation, axis=-1, keepdims=True)
    q = q.copy()
    for k in range(1, len(q)):
        flip = np.einsum("bi,bi->b", q[k], q[k - 1]) < 0
        q[k, flip] *= -1.0
    return q[..., [1, 2, 3, 0]]


def _matrix_to_xyzw(R: np.ndarray) -> list:
    """The unit quaternion (x, y, z, w) of a rotation matrix (Shepperd's method: the largest pivot)."""
    trace = R[0, 0] + R[1, 1] + R[2, 2]
    pivots = [trace, R[0, 0], R[1, 1], R[2, 2]]
    k = int(np.argmax(pivots))
    if k == 0:
        s = 2.0 * math.sqrt(1.0 + trace)
        w, x, y, z = s / 4, (R[2, 1] - R[1, 2]) / s, (R[0, 2] - R[2, 0]) / s, (R[1, 0] - R[0, 1]) / s
    elif k == 1:
        s = 2.0 * math.sqrt(1.0 + R[0, 0] - R[1, 1] - R[2, 2])
        w, x, y, z = (R[2, 1] - R[1, 2]) / s, s / 4, (R[0, 1] + R[1, 0]) / s, (R[0, 2] + R[2, 0]) / s
    elif k == 2:
        s = 2.0 * math.sqrt(1.0 + R[1, 1] - R[0, 0] - R[2, 2])
        w, x, y, z = (R[0, 2] - R[2, 0]) / s, (R[0, 1] + R[1, 0]) / s, s / 4, (R[1, 2] + R[2, 1]) / s
    else:
        s = 2.0 * math.sqrt(1.0 + R[2, 2] - R[0, 0] - R[1, 1])
        w, x, y, z = (R[1, 0] - R[0, 1]) / s, (R[0, 2] + R[2, 0]) / s, (R[1, 2] + R[2, 1]) / s, s / 4
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    return [float(x / norm), float(y / norm), float(z / norm), float(w / norm)]


def _up_for(light) -> tuple:
    direction = np.subtract(light.target, light.position)
    return (0.0, 0.0, 1.0) if abs(direction[1]) > 0.99 * np.linalg.norm(direction) else (0.0, 1.0, 0.0)
