"""Stage 4a, budgets: what a scene asks of the machine, estimated when the plan is made, before anything is
allocated or stepped, so that `frames 1e9 Hz` or `step 1e-12 s` is a diagnostic and not a MemoryError or a run
that never ends.

    steps       (end - start) / step                                   the step loop's length
    work        steps x max(1, dynamic bodies)                         (about 3.5 us each, compiled)
    substeps    steps x substeps                                       procedural plan
    iterations  steps x substeps x iterations                          procedural plan
    frames      (end - start) x frame rate + 1                         recorded samples of the trajectory
    samples     (end - start) x audio rate x channels                  scenes with sounds
    bodies      bodies in the scene
    contacts    pairs of collidable bodies deep inside each other at the start (each pair a contact island's
                rows: their dense J M^-1 J^T grows as the square of their number)
    memory      bytes of the largest arrays: the trajectory (frames x bodies x 13 doubles, twice) and the audio
                (samples x 4 doubles)

Over a budget: a SceneError at the setting responsible (ir.Scene.origins: the `frames`, the `time`, the solver's
`step`, ...), saying what the scene asks for, the limit, and how to raise it: `isaac run --budget steps=1e8`, or
the environment variable ISAAC_BUDGET="steps=1e8,memory=8GB" (`--budget` sets it for the run). `NAME=off`
removes a limit. The defaults keep a run within minutes and 2 GiB.
"""
from __future__ import annotations

import math
import os
import re

import numpy as np

from isaac_ir.diagnostics import Diagnostic, SceneError, SourcePos

ENVIRONMENT = "ISAAC_BUDGET"
DEFAULTS = {
    "steps": 5e6,  # a pendulum at 1 ms for 83 minutes of scene time
    # body-steps: 100 links for 50,000 steps, about 15 s at the 3 us each a compiled step takes (a 10-link chain
    # measured at 2.9 us): an accepted scene runs within the 20 s a hostile input is allowed
    "work": 5e6,
    "substeps": 5e7,
    "iterations": 2e8,
    "frames": 1e6,  # 4.6 hours at 60 Hz
    "samples": 1e8,  # 38 minutes of mono sound at 44.1 kHz
    "bodies": 20_000,
    "contacts": 1_000,
    "memory": 2 * 2**30,  # bytes
}
# what each budget counts, for the message
COUNTS = {"steps": "steps", "work": "body-steps", "substeps": "substeps", "iterations": "solver iterations",
          "frames": "frames", "samples": "audio samples", "bodies": "bodies", "contacts": "pairs of bodies inside "
          "each other at the start", "memory": "bytes of arrays"}
# a step shorter than this fraction of the largest time is below the clock's resolution (a double has 16 digits)
CLOCK_RESOLUTION = 1e-12
# a pair of bodies counts as inside each other when the spheres they hold overlap by this fraction of the smaller
OVERLAP_FRACTION = 0.1
_SIZE = re.compile(r"^\s*([0-9.eE+-]+)\s*([kMGT]i?B|B)?\s*$")
_UNITS = {None: 1, "B": 1, "kB": 1e3, "MB": 1e6, "GB": 1e9, "TB": 1e12, "kiB": 2**10, "KiB": 2**10,
          "MiB": 2**20, "GiB": 2**30, "TiB": 2**40}


class BudgetError(SceneError):
    """A scene that asks for more than a budget allows (exit 2)."""


# ---- the limits ------------------------------------------------------------------------------------------------

def parse_budgets(text: str) -> dict:
    """`steps=1e8,memory=8GB` -> {"steps": 1e8, "memory": 8e9}; `NAME=off`: no limit. ValueError on a bad one."""
    limits = {}
    for item in filter(None, (part.strip() for part in text.split(","))):
        name, sep, value = item.partition("=")
        name = name.strip()
        if not sep or name not in DEFAULTS:
            raise ValueError(f"`{item}`: budgets are NAME=VALUE with NAME one of {', '.join(DEFAULTS)}")
        limits[name] = _limit_value(name, value.strip())
    return limits


def _limit_value(name: str, value: str) -> float:
    if value.lower() in ("off", "none", "inf"):
        return math.inf
    match = _SIZE.match(value) if name == "memory" else None
    try:
        number = float(match.group(1)) * _UNITS[match.group(2)] if match else float(value)
    except ValueError:
        number = math.nan
    if not (number > 0 and math.isfinite(number)):
        raise ValueError(f"`{name}={value}`: a budget is a number above 0 (or `off`)"
                         + (", e.g. 8GB" if name == "memory" else ""))
    return number


def current_limits() -> dict:
    """The defaults, with ISAAC_BUDGET's values over them (a bad value there is a usage error)."""
    limits = dict(DEFAULTS)
    text = os.environ.get(ENVIRONMENT, "")
    if text.strip():
        try:
            limits.update(parse_budgets(text))
        except ValueError as error:
            raise BudgetError([Diagnostic(f"{ENVIRONMENT}: {error}", None)]) from None
    return limits


# ---- the estimates ---------------------------------------------------------------------------------------------

def check_budgets(scene, solver: str, step: float, end: float, step_reason: str, limits: dict | None = None):
    """Raise BudgetError when the plan about to be made (its solver, step and end) asks for more than the limits
    (current_limits() when not given) allow. Nothing is allocated here."""
    limits = current_limits() if limits is None else limits
    start, rate = scene.time.start, scene.time.frame_rate
    span = max(0.0, end - start)
    if 1.0 / rate < step:  # the plan cuts steps at frames: then the frame rate sets the step
        step, step_reason = 1.0 / rate, "frames"
    steps = _whole(span / step - 1e-9, math.ceil)
    from_step = {"--step": "--step", "frames": "frames"}.get(step_reason) or (
        "solver.step" if "scene" in step_reason else "time")
    dynamic = sum(1 for b in scene.bodies if b.motion == "dynamic")
    frames = _whole(span * rate + 1e-9, math.floor) + 1
    samples = span * scene.audio.rate * scene.audio.channels if scene.sounds else 0.0
    asked = [("frames", frames, "frames"), ("samples", samples, "audio.rate"), ("bodies", len(scene.bodies), "scene"),
             ("memory", _memory(frames, len(scene.bodies), samples), "frames" if frames * len(scene.bodies)
              > samples else "audio.rate"),
             ("steps", steps, from_step), ("work", steps * max(1, dynamic), from_step)]
    if solver == "procedural":
        substeps = steps * scene.solver.substeps
        asked += [("substeps", substeps, "solver.substeps"),
                  ("iterations", substeps * scene.solver.iterations, "solver.iterations")]
    for name, value, setting in asked:
        if value > limits[name]:
            raise _over(scene, name, value, limits[name], setting, span, step)
    _check_clock(scene, step, start, end, step_reason)
    _check_overlaps(scene, limits["contacts"])


def _whole(value: float, rounding) -> float:
    """rounding(value), or value itself when it is too large to be an integer (inf: over every budget)."""
    return float(rounding(value)) if math.isfinite(value) else math.inf


def _memory(frames: int, bodies: int, samples: float) -> float:
    # the trajectory: position 3, orientation 4, velocities 3 + 3 doubles per body and frame, recorded and copied
    # out once; the audio: the mix, its channels and two working copies of doubles
    return 2 * frames * max(bodies, 1) * 13 * 8 + 4 * samples * 8


def _over(scene, name: str, value: float, limit: float, setting: str, span: float, step: float) -> BudgetError:
    where = setting if setting == "--step" else setting if scene.origin(setting) else "time"
    pos = SourcePos.parse(scene.origin(where) or "") if where != "--step" else None
    cause = _cause(scene, name, where, span, step)
    message = (f"{cause} asks for {_number(value, name)} {COUNTS[name]}, more than the budget of "
               f"{_number(limit, name)}")
    # the next power of ten above what the scene asks for; `off` when that is past what a double holds
    raise_to = _number(10.0 ** math.ceil(math.log10(value)), name) if 0 < value < 1e308 else "off"
    hint = (f"if you mean it, raise the budget: `--budget {name}={raise_to}` (or the environment variable "
            f"{ENVIRONMENT}={name}={raise_to}); docs/budgets.md lists the budgets")
    return BudgetError([Diagnostic(message, pos, hint)])


def _cause(scene, name: str, where: str, span: float, step: float) -> str:
    if where == "--step":
        return f"--step {_g(step)} s over {_g(span)} s"
    if where == "frames" and name in ("steps", "work"):
        return f"{_g(scene.time.frame_rate)} frames per second (a step each, at least) over {_g(span)} s"
    if name in ("steps", "work", "substeps", "iterations"):
        return f"a step of {_g(step)} s over {_g(span)} s" + (
            f" with {scene.solver.substeps} substeps" if name in ("substeps", "iterations") else "") + (
            f" and {scene.solver.iterations} iterations" if name == "iterations" else "") + (
            f" for {sum(1 for b in scene.bodies if b.motion == 'dynamic')} dynamic bodies" if name == "work" else "")
    if name == "frames":
        return f"{_g(scene.time.frame_rate)} frames per second over {_g(span)} s"
    if name == "samples":
        return f"sound at {_g(scene.audio.rate)} Hz over {_g(span)} s"
    if name == "memory":
        return f"recording {len(scene.bodies)} bodies at {_g(scene.time.frame_rate)} Hz over {_g(span)} s"
    return f"a scene of {len(scene.bodies)} bodies"


def _number(value: float, name: str = "") -> str:
    """5e6, 2.4e11, 1000, 2GiB: as a budget is written."""
    if name == "memory" and value >= 2**30:
        return f"{value / 2**30:.3g}GiB"
    if value >= 1e6:
        return _g(value)
    return f"{int(value)}" if value == int(value) else _g(value)


def _g(value: float) -> str:
    """A number as the scene would write it: 0.2, 1e9, 2.5e-12."""
    return f"{value:.3g}".replace("e+0", "e").replace("e+", "e").replace("e-0", "e-")


def _check_clock(scene, step: float, start: float, end: float, step_reason: str) -> None:
    """A step the clock can count: t + step must differ from t by more than rounding, all through the run."""
    largest = max(abs(start), abs(end), 1.0)
    if step >= CLOCK_RESOLUTION * largest:
        return
    setting = "solver.step" if "scene" in step_reason and scene.origin("solver.step") else "time"
    pos = None if step_reason == "--step" else SourcePos.parse(scene.origin(setting) or "")
    who = "--step" if step_reason == "--step" else "the step"
    message = (f"{who} of {_g(step)} s is below the resolution of the clock at t = {_g(largest)} s (steps shorter than "
               f"{_g(CLOCK_RESOLUTION * largest)} s there do not add up)")
    raise BudgetError([Diagnostic(message, pos, "take a longer step, or start the scene's time nearer 0 s")])


def _check_overlaps(scene, limit: float) -> None:
    """Pairs of collidable bodies deep inside each other at the start (the spheres each shape holds, `_CORE`,
    overlapping by more than OVERLAP_FRACTION of the smaller): each pair is a contact from the first step on, and a heap of them is
    one contact island whose dense matrices grow as the square of their number."""
    chosen = [b for b in scene.bodies if b.collide and b.shape.type in _CORE]
    if len(chosen) < 2 or not math.isfinite(limit):
        return
    centres = np.array([_start_position(b, scene.time.start) for b in chosen])
    core = np.array([_CORE[b.shape.type](b.shape) for b in chosen])
    axis = int(np.argmax(np.ptp(centres, axis=0)))  # sweep along the axis the bodies spread most along
    lo, hi = centres[:, axis] - core, centres[:, axis] + core
    order = np.argsort(lo)
    lo_sorted = lo[order]
    count, first = 0, None
    for k, i in enumerate(order):
        near = order[k + 1:np.searchsorted(lo_sorted, hi[i], side="right")]
        if not len(near):
            continue
        depth = core[i] + core[near] - np.linalg.norm(centres[near] - centres[i], axis=1)
        inside = near[depth > OVERLAP_FRACTION * np.minimum(core[i], core[near])]
        if len(inside):
            count += len(inside)
            first = first or (chosen[i], chosen[int(inside[0])])
        if count > limit:
            a, b = first
            raise BudgetError([Diagnostic(
                f"the bodies start with more pairs inside each other than the budget of {_number(limit)} (the "
                f"first: `{a.name}` and `{b.name}`): each pair is a contact from the first step on",
                SourcePos.parse(a.source), f"place the bodies apart; if you mean it, raise the budget: `--budget "
                f"contacts={_number(10 * limit)}`; docs/budgets.md lists the budgets")])


def _start_position(body, t: float):
    from isaac_ir import expr as E

    with np.errstate(all="ignore"):
        value = np.asarray(E.evaluate(body.position, {"t": t}), float).reshape(-1)
    return value if value.shape == (3,) and np.all(np.isfinite(value)) else np.full(3, np.inf)


# how far the farthest point of a shape is from its centre
# the radius of the sphere about a shape's centre that the shape holds: two of them overlapping means the shapes
# surely do (bounding spheres counted 10 cm cubes 13 cm apart, which do not touch, as inside each other)
_CORE = {
    "sphere": lambda s: s.radius,
    "box": lambda s: 0.5 * min(s.size),
    "capsule": lambda s: s.radius,
    "cylinder": lambda s: min(s.radius, 0.5 * s.length),
}
