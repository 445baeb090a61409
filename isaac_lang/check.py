"""Stage 3, check: rules that look across declarations, on the lowered IR. Each problem names its source."""
from __future__ import annotations

import math

from isaac_ir import ir
from isaac_ir.diagnostics import Reporter, SourcePos


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
    collide_against_exclude(scene, reporter)
    for sound in scene.sounds:
        if sound.trigger == "time" and not (scene.time.start <= sound.time <= scene.time.end):
            warnings.append(f"{sound.source}: sound `{sound.name}` is set outside the scene's time")
        never = never_fires(scene, sound)
        if never is not None:
            warnings.append(never)
            continue
        for name in sound.bodies:
            if not scene.body(name).collide and sound.trigger in ("collide", "contact"):
                warnings.append(f"{sound.source}: sound `{sound.name}` waits for `{name}`, which has `collide off`")
    warnings += unused_properties(scene)
    if scene.solver.step is not None and scene.solver.step > (scene.time.end - scene.time.start):
        warnings.append("the solver step is longer than the whole scene")
    return warnings


def _pairs(bodies) -> set:
    return {tuple(sorted((a, b))) for k, a in enumerate(bodies) for b in bodies[k + 1:] if a != b}


def _whole_run(scene: ir.Scene, start: float, end: float) -> bool:
    return start <= scene.time.start and end >= scene.time.end


def _window_text(start: float, end: float) -> str:
    if math.isinf(start) and math.isinf(end):
        return "for the whole run"
    return f"during {start:g} s .. {end:g} s"


def collide_against_exclude(scene: ir.Scene, reporter: Reporter) -> None:
    """A `collide` and an `exclude` that name one pair at overlapping times contradict each other: an error at
    the `collide` (neither is taken to win)."""
    for collide in scene.collides:
        pairs = _pairs(collide.bodies)
        for exclusion in scene.exclusions:
            shared = sorted(pairs & _pairs(exclusion.bodies))
            if shared and max(collide.start, exclusion.start) < min(collide.end, exclusion.end):
                a, b = shared[0]
                reporter.error(f"`collide` and `exclude` both name `{a}` and `{b}` at the same time "
                               f"(`collide` {_window_text(collide.start, collide.end)}, `exclude` "
                               f"{_window_text(exclusion.start, exclusion.end)})", SourcePos.parse(collide.source),
                               f"the `exclude` is at {exclusion.source}: give the two windows that do not overlap, "
                               f"or keep only one of them")


def never_fires(scene: ir.Scene, sound: ir.Sound) -> str | None:
    """The warning for a sound `on collide(a, b)` or `on contact(a, b)` whose pair never collides (excluded for the
    whole run: a body with `collide off`, neither body moving, an `exclude` without a window, a constraint on for
    the whole run that no `collide` overrides), positioned at the trigger, with a hint on its last line."""
    if sound.trigger not in ("collide", "contact") or len(sound.bodies) != 2 or sound.bodies[0] == sound.bodies[1]:
        return None
    a, b = sound.bodies
    pair = tuple(sorted((a, b)))
    where = sound.trigger_source or sound.source
    head = f"{where}: sound `{sound.name}` never plays: `{a}` and `{b}`"
    off = [name for name in (a, b) if not scene.body(name).collide]
    if off:
        return (f"{head} never collide: `{off[0]}` has `collide off`\n"
                f"hint: remove `collide off` from `{off[0]}` (declared at {scene.body(off[0]).source})")
    if all(scene.body(name).motion != "dynamic" for name in (a, b)):
        return (f"{head} never collide: neither of them is dynamic\n"
                f"hint: a pair collides only when one of its bodies is dynamic")
    for exclusion in scene.exclusions:
        if _whole_run(scene, exclusion.start, exclusion.end) and pair in _pairs(exclusion.bodies):
            return (f"{head} never collide: the `exclude` at {exclusion.source} excludes them for the whole run\n"
                    f"hint: take one of them out of that `exclude`, or give it a window")
    if any(pair in _pairs(c.bodies) for c in scene.collides):
        return None
    for constraint in scene.constraints:
        if not _whole_run(scene, constraint.start, constraint.end):
            continue
        if any(pair in _pairs(term.bodies) for term in constraint.terms):
            return (f"{head} never collide: constraint `{constraint.name}` joins them for the whole run (a "
                    f"joined pair does not collide)\n"
                    f"hint: write `collide {a}, {b}` to let them collide although `{constraint.name}` joins them")
    return None


def unused_properties(scene: ir.Scene) -> list[str]:
    """Warnings for what a scene sets that nothing uses (never silence): the air's drag on a body that does not
    move by forces, a drag or an area with `wind off`, an `air` density no body feels."""
    from isaac_lang.lower import AIR_DENSITY, DEFAULT_DRAG

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
