"""RenderMan RIB export (RISpec 3.2): the high-quality path. One frame per file, or a whole sequence in one.

    write_rib(out / "rib", scene, arrays, RibOptions(motion_blur=True))

Each frame: display, format, perspective projection with the scene's camera, optional motion blur, the lights
as the standard light shaders (distantlight, pointlight, spotlight, ambientlight), then each body in its own
attribute block: name, colour, `plastic`, its body-to-world transform (two under MotionBegin when blurred) and
its primitive. Spheres, cylinders and capsules are RenderMan quadrics (exact, no facets); boxes, planes and
meshes are PointsPolygons. Renders with any RISpec renderer (3Delight, Aqsis, PRMan in RSL mode, Pixie).

Coordinates: the IR's world is right-handed, y up; RenderMan's camera space is left-handed, looking down +z.
The camera transform is gluLookAt's view matrix V followed by `Scale 1 1 -1`. RIB matrices act on row vectors
(p' = p M), so every matrix is written transposed, translation in the last row.
"""
from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..outputs import write_atomic
from . import geometry

# a little ambient light so that nothing is black (the viewer does the same)
AMBIENT = 0.1
# the six faces of a box as quads of its corners (bit 2: x, bit 1: y, bit 0: z), counter-clockwise from outside
BOX_FACES = ((0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3))


@dataclass
class RibOptions:
    width: int = 960
    height: int = 540
    frames: slice | None = None  # which frames of the trajectory (indices); None: all
    sequence: bool = False  # one file with every frame, instead of one file per frame
    motion_blur: bool = False
    shutter: float = 0.5  # open for this fraction of a frame (a 180-degree shutter)
    samples: int = 4  # pixel samples per axis
    camera: str | None = None  # by name; default the scene's first


def write_rib(folder: Path, scene, arrays: dict, options: RibOptions | None = None,
              scene_folder: Path | None = None) -> list:
    """Write the frames as `NAME.0000.rib`... (or one `NAME.rib`) into folder; returns the paths."""
    options = options or RibOptions()
    folder = Path(folder)
    frames = range(len(arrays["time"]))[options.frames or slice(None)]
    shapes = _Shapes(scene, arrays, scene_folder)
    digits = max(4, len(str(len(arrays["time"]) - 1)))
    texts = [(k, rib_frame(scene, arrays, k, options, shapes, digits)) for k in frames]
    if options.sequence:
        path = folder / f"{scene.name}.rib"
        write_atomic(path, (_header(scene) + "".join(text for _, text in texts)).encode("utf-8"))
        return [path]
    paths = []
    for k, text in texts:
        path = folder / f"{scene.name}.{k:0{digits}d}.rib"
        write_atomic(path, (_header(scene) + text).encode("utf-8"))
        paths.append(path)
    return paths


def rib_frame(scene, arrays: dict, k: int, options: RibOptions, shapes: "_Shapes | None" = None,
              digits: int = 4) -> str:
    """The RIB of frame k: FrameBegin .. FrameEnd."""
    shapes = shapes or _Shapes(scene, arrays, None)
    time = np.asarray(arrays["time"], float)
    position = np.asarray(arrays["position"], float)
    camera = geometry.camera_of(scene, position, options.camera)
    lines = [f"# frame {k}: t = {_num(time[k])} s",
             f"FrameBegin {k}",
             f'  Display "{scene.name}.{k:0{digits}d}.tif" "file" "rgba"',
             f"  Format {options.width} {options.height} 1",
             f"  PixelSamples {options.samples} {options.samples}",
             f'  Projection "perspective" "fov" [{_num(math.degrees(_rib_fov(camera["fov"], options)))}]',
             "  Clipping 0.01 1000"]
    blur_to = _blur_time(time, k, options)
    if blur_to is not None:
        lines.append(f"  Shutter 0 {_num(blur_to - time[k])}")
    view = geometry.look_at_matrix(camera["position"], camera["look_at"], camera["up"])
    lines += [f'  # camera `{camera["name"]}`: right-handed view, then z flipped into RenderMan\'s camera space',
              "  Scale 1 1 -1", f"  ConcatTransform {_matrix(view)}", "  WorldBegin"]
    lines += ["    " + line for line in _light_lines(scene, camera)]
    for b, name in enumerate(shapes.names):
        lines += ["    " + line for line in _body_lines(scene, arrays, shapes, b, name, k, blur_to)]
    lines += ["  WorldEnd", "FrameEnd", ""]
    return "\n".join(lines)


# ---- parts ------------------------------------------------------------------------------------------------

class _Shapes:
    """What does not change from frame to frame: colours, plane size, mesh files read once."""

    def __init__(self, scene, arrays: dict, scene_folder: Path | None):
        self.names = [str(n) for n in arrays["bodies"]]
        self.index = scene.body_index()
        self.colors = geometry.scene_colors(scene)
        self.plane_size = geometry.plane_size(np.asarray(arrays["position"], float))
        self.folder = scene_folder
        self._meshes: dict = {}

    def mesh(self, shape) -> tuple:
        if shape.file not in self._meshes:
            path = Path(shape.file) if self.folder is None else Path(self.folder) / shape.file
            self._meshes[shape.file] = geometry.read_mesh(path)
        vertices, triangles = self._meshes[shape.file]
        return vertices * shape.scale + np.asarray(shape.offset, float), triangles


def _header(scene) -> str:
    return (f"##RenderMan RIB\n# {scene.name}: written by `isaac export --format rib`\n"
            f"version 3.04\n")


def _light_lines(scene, camera: dict) -> list:
    lines, handle = [], 1
    ambient = sum(light.intensity for light in scene.lights if light.type == "ambient")
    lines.append(f'LightSource "ambientlight" {handle} "intensity" [{_num(AMBIENT + ambient)}]')
    lights = [light for light in scene.lights if light.type != "ambient"]
    if not lights:  # no lights in the scene: a headlight, as the viewer
        lines.append(f'LightSource "distantlight" 2 "intensity" [0.85] "from" {_vec(camera["position"])} '
                     f'"to" {_vec(camera["look_at"])}')
    for light in lights:
        handle += 1
        common = f'"intensity" [{_num(_intensity(light, camera))}] "lightcolor" {_vec(light.color)}'
        if light.type == "distant":
            lines.append(f'LightSource "distantlight" {handle} {common} "from" {_vec(light.position)} '
                         f'"to" {_vec(light.target)}')
        elif light.type == "point":
            lines.append(f'LightSource "pointlight" {handle} {common} "from" {_vec(light.position)}')
        else:
            lines.append(f'LightSource "spotlight" {handle} {common} "from" {_vec(light.position)} '
                         f'"to" {_vec(light.target)} "coneangle" [{_num(math.radians(30.0))}]')
    return lines


def _intensity(light, camera: dict) -> float:
    """pointlight and spotlight fall off as 1/d^2: scale them so that the scene's intensity is what arrives
    at the camera's look-at point (as the viewer shows it)."""
    if light.type == "distant":
        return light.intensity
    d2 = float(np.sum((np.asarray(light.position) - np.asarray(camera["look_at"])) ** 2))
    return light.intensity * max(d2, 1e-6)


def _body_lines(scene, arrays: dict, shapes: _Shapes, b: int, name: str, k: int, blur_to) -> list:
    body = scene.bodies[shapes.index[name]]
    position = np.asarray(arrays["position"], float)
    orientation = np.asarray(arrays["orientation"], float)
    lines = ["AttributeBegin", f'  Attribute "identifier" "name" ["{name}"]',
             f"  Color {_vec(shapes.colors[shapes.index[name]])}", '  Surface "plastic" "Ks" [0.3] "roughness" [0.2]']
    now = geometry.matrices(position[k, b], orientation[k, b])
    if blur_to is not None and body.motion != "static":
        p, q = _pose_at(arrays, b, blur_to)
        later = geometry.matrices(p, q)
        lines += [f"  MotionBegin [0 {_num(blur_to - float(arrays['time'][k]))}]",
                  f"    ConcatTransform {_matrix(now)}", f"    ConcatTransform {_matrix(later)}", "  MotionEnd"]
    else:
        lines.append(f"  ConcatTransform {_matrix(now)}")
    lines += ["  " + line for line in _primitive(body.shape, shapes)]
    lines.append("AttributeEnd")
    return lines


def _primitive(shape, shapes: _Shapes) -> list:
    kind = shape.type
    if kind == "sphere":
        r = _num(shape.radius)
        return [f"Sphere {r} -{r} {r} 360"]
    if kind == "cylinder":
        r, h = _num(shape.radius), _num(shape.length / 2)
        return [f"Cylinder {r} -{h} {h} 360", f"Disk {h} {r} 360", "AttributeBegin", "  ReverseOrientation",
                f"  Disk -{h} {r} 360", "AttributeEnd"]
    if kind == "capsule":
        r, h = _num(shape.radius), _num(shape.length / 2)
        return [f"Cylinder {r} -{h} {h} 360",
                "TransformBegin", f"  Translate 0 0 {h}", f"  Sphere {r} 0 {r} 360", "TransformEnd",
                "TransformBegin", f"  Translate 0 0 -{h}", f"  Sphere {r} -{r} 0 360", "TransformEnd"]
    if kind == "box":
        half = np.asarray(shape.size, float) / 2.0
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * half
        return _points_polygons(corners, BOX_FACES)
    if kind == "plane":
        mesh = geometry.plane(shape.normal or (0.0, 1.0, 0.0), shapes.plane_size)
        k = geometry.PLANE_TILES + 1
        corners = mesh.positions[[0, (k - 1) * k, k * k - 1, k - 1]]  # the square's four corners, in order
        return [f'Polygon "P" {_vec(corners.ravel())}']
    if kind == "mesh":
        vertices, triangles = shapes.mesh(shape)
        return _points_polygons(vertices, triangles)
    if kind == "compound":  # each part in its place: body frame = offset + at + R (part frame)
        lines = []
        for part in shape.parts:
            place = geometry.matrices(np.asarray(shape.offset, float) + np.asarray(part.position, float),
                                      np.asarray(part.orientation, float))
            lines += ["TransformBegin", f"  ConcatTransform {_matrix(place)}"]
            lines += ["  " + line for line in _primitive(part.shape, shapes)] + ["TransformEnd"]
        return lines
    raise ValueError(f"shape: unknown type {kind!r}")


def _points_polygons(vertices: np.ndarray, faces) -> list:
    faces = [list(map(int, f)) for f in faces]
    counts = " ".join(str(len(f)) for f in faces)
    indices = " ".join(str(i) for f in faces for i in f)
    return [f"PointsPolygons [{counts}]", f"  [{indices}]", f'  "P" {_vec(np.asarray(vertices).ravel())}']


def _blur_time(time: np.ndarray, k: int, options: RibOptions):
    """When the shutter closes, or None without motion blur (or with a single frame)."""
    if not options.motion_blur or len(time) < 2:
        return None
    dt = float(time[1] - time[0]) if k + 1 >= len(time) else float(time[k + 1] - time[k])
    return float(time[k]) + options.shutter * dt


def _pose_at(arrays: dict, b: int, t: float) -> tuple:
    """Body b's position and orientation at time t, between frames: linear and normalized-linear."""
    time = np.asarray(arrays["time"], float)
    k = int(np.clip(np.searchsorted(time, t) - 1, 0, len(time) - 2))
    a = float(np.clip((t - time[k]) / (time[k + 1] - time[k]), 0.0, 1.0))
    p0, p1 = arrays["position"][k, b], arrays["position"][k + 1, b]
    q0, q1 = arrays["orientation"][k, b], arrays["orientation"][k + 1, b]
    q1 = q1 if np.dot(q0, q1) >= 0 else -q1
    q = (1 - a) * q0 + a * q1
    return (1 - a) * p0 + a * p1, q / np.linalg.norm(q)


def _rib_fov(fov_vertical: float, options: RibOptions) -> float:
    """RenderMan's "fov" spans the shorter side of the image; the IR's is vertical."""
    if options.width >= options.height:
        return fov_vertical
    return 2.0 * math.atan(math.tan(fov_vertical / 2.0) * options.width / options.height)


def _matrix(m: np.ndarray) -> str:
    return "[" + " ".join(_num(v) for v in np.asarray(m).T.ravel()) + "]"


def _vec(values) -> str:
    return "[" + " ".join(_num(v) for v in np.asarray(values, float).ravel()) + "]"


def _num(x: float) -> str:
    """Six significant digits, no negative zero: golden files stay stable across machines."""
    text = f"{float(x):.6g}"
    return "0" if text in ("-0", "0") or (abs(float(x)) < 5e-13) else text
