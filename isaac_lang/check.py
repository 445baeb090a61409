"""Stage 3, check: rules that look across declarations, on the lowered IR. Each problem names its source."""
from __future__ import annotations

import math

from . import ir
from .diagnostics import Reporter, SourcePos


def check(scene: ir.Scene, reporter: Reporter) -> list[str]:
    """Record errors in reporter; return warnings (strings) that do not stop a run."""
    warnings: list[str] = []
    for body in scene.bodies:
        if body.motion == "dynamic" and body.inertia is None:
            reporter.error(f"body `{body.name}` needs an `inertia` (its shape gives none)",
                           SourcePos.parse(body.source),
                           "write `inertia (Ixx, Iyy, Izz) kg*m2`")
    for constraint in scene.constraints:
        if constraint.start >= scene.time.end:
            warnings.append(f"{constraint.source}: constraint `{constraint.name}` starts after the scene ends")
    for exclusion in scene.exclusions:
        if len(set(exclusion.bodies)) != len(exclusion.bodies):
            reporter.error("a body is named twice in `exclude`", SourcePos.parse(exclusion.source))
    for sound in scene.sounds:
        if sound.trigger == "time" and not (scene.time.start <= sound.time <= scene.time.end):
            warnings.append(f"{sound.source}: sound `{sound.name}` is set outside the scene's time")
        for name in sound.bodies:
            if not scene.body(name).collide and sound.trigger in ("collide", "contact"):
                warnings.append(f"{sound.source}: sound `{sound.name}` waits for `{name}`, which has `collide off`")
    warnings += unused_properties(scene)
    if scene.solver.step is not None and scene.solver.step > (scene.time.end - scene.time.start):
        warnings.append("the solver step is longer than the whole scene")
    return warnings


def unused_properties(scene: ir.Scene) -> list[str]:
    """Warnings for what a scene sets that nothing uses (never silence): the air's drag on a body that does not
    move by forces, a drag or an area with `wind off`, an `air` density no body feels."""
    from .lower import AIR_DENSITY, DEFAULT_DRAG

    warnings = []
    for body in scene.bodies:
        response = body.wind
        drag_given = response.area is not None or response.drag != DEFAULT_DRAG[body.shape.type]
        if response.enabled and body.motion != "dynamic":
            warnings.append(f"{body.source}: body `{body.name}` is {body.motion}: the air's drag on it is not used")
        elif not response.enabled and drag_given:
            warnings.append(f"{body.source}: body `{body.name}` has `wind off`: its `drag` and `area` are not used")
    feels_air = any(b.wind.enabled and b.motion == "dynamic" for b in scene.bodies)
    if scene.air_density != AIR_DENSITY and not feels_air:
        warnings.append(f"the scene's `air` ({scene.air_density:g} kg/m3) is not used: no body feels the air "
                        f"(give one a `drag`)")
    return warnings
