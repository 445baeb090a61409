"""A blow-up, diagnosed: when the step loop stops on a body that ran away or a constraint whose error grew past
any joint's, what ran away in its units, what acted on it, and a hint drawn from those measurements
(NumericalError; Simulation raises it, run.py prints its hint)."""
from __future__ import annotations

import math

import numpy as np

from .core import data as D
from .core.bodies import RUNAWAY_SPEED
from .core.record import RUNAWAY_BODY, RUNAWAY_CONSTRAINT_ERROR

# omega h within which an explicit step holds a row assembling at omega (critically damped: a double root at -omega,
# which takes less than the 2.78 of RK4's real axis). Measured on a nail closing 10 cm at 200 Hz at 20 ms
# (tests/runtime/test_contact_fixes.py): RK4 runs at omega h = 2 (by its stabilization or its step) and blows up at
# 2.76; half that for midpoint and Euler
STABLE_OMEGA_H = {"rk4": 2.0, "midpoint": 1.0, "euler": 1.0}


def _size(vector) -> float:
    """|vector| without overflow in its squares (a runaway speed of 1e300 m/s is 1e300, not inf)."""
    largest = float(np.max(np.abs(vector)))
    if not 0.0 < largest < math.inf:
        return largest
    return largest * float(np.linalg.norm(np.asarray(vector) / largest))


def _down(value: float) -> float:
    """value rounded down to two significant digits (a limit said in round figures stays within it)."""
    if not value > 0.0:
        return value
    scale = 10.0 ** (math.floor(math.log10(value)) - 1)
    return math.floor(value / scale) * scale


class NumericalError(Exception):
    """The simulation became meaningless: says when (time and step) and what (body or constraint), with the units of
    what was measured; `hint` says what the measurements point to (run.py prints it after the message)."""

    def __init__(self, time: float, step: int, culprit: str, detail: str, source: str | None = None,
                 hint: str | None = None):
        self.time, self.step, self.culprit, self.detail = time, step, culprit, detail
        self.source = source  # "file:line:col" of the culprit's declaration, when known
        self.hint = hint
        declared = f" (declared at {source})" if source else ""
        super().__init__(f"numerical blow-up at t = {time:.6g} s (step {step}): {culprit}{declared}: {detail}")


def failure(sim) -> NumericalError:
    """The blow-up the step loop stopped on (sim._status), measured: what ran away, in its units, and what
    acted on it. It never fails, and always names a body or a constraint with the position of its declaration
    (a contact's row names no declaration: the fastest body is named with it)."""
    try:
        found = _measured_failure(sim)
    except Exception:  # the diagnosis of a state that is already broken: say the least that is sure
        found = _plain_failure(sim)
    return found if found.source else _with_fastest_body(sim, found)


def _measured_failure(sim) -> NumericalError:
    code, step, which = (int(v) for v in sim._status[:3])
    if code == RUNAWAY_BODY:
        return body_failure(sim, which)
    error, _ = sim.constraint_errors()
    return constraint_failure(sim, which, error)


def _plain_failure(sim) -> NumericalError:
    code, _, which = (int(v) for v in sim._status[:3])
    bodies = sim.plan.scene.bodies
    if code == RUNAWAY_BODY and 0 <= which < len(bodies):
        return NumericalError(sim.state.t, sim.state.steps, f"body `{bodies[which].name}`", "it ran away",
                              bodies[which].source)
    return NumericalError(sim.state.t, sim.state.steps, "a constraint or contact", "its error grew past any joint's")


def _fastest_body(sim) -> int | None:
    """The index of the body moving fastest (a non-finite speed first), or None without a moving body."""
    y = np.asarray(sim.state.y, float)
    if len(y) == 0:
        return None
    speed = np.abs(y[:, D.V]).max(axis=1) + np.abs(y[:, D.W]).max(axis=1)
    return int(np.argmax(np.where(np.isfinite(speed), speed, np.inf)))


def _with_fastest_body(sim, found: NumericalError) -> NumericalError:
    try:
        b = _fastest_body(sim)
        body = sim.plan.scene.bodies[b] if b is not None else None
    except Exception:  # (the same reason as in failure)
        body = None
    if body is None:
        return found
    return NumericalError(found.time, found.step, found.culprit, f"{found.detail}; the fastest body: `{body.name}`",
                          body.source, found.hint)


def body_failure(sim, b: int) -> NumericalError:
    s, name = sim.state, sim.plan.names[b]
    y = s.y[b]
    v, w = _size(y[D.V]), _size(y[D.W])
    parts = (("position", D.X, "m"), ("orientation", D.Q, ""), ("velocity", D.V, "m/s"),
             ("angular velocity", D.W, "rad/s"))
    broken = [label for label, columns, _ in parts if not np.all(np.isfinite(y[columns]))]
    if broken:
        detail = f"its {' and '.join(broken)} {'is' if len(broken) == 1 else 'are'} no longer finite"
    elif np.any(np.abs(y[D.V]) >= RUNAWAY_SPEED):
        detail = f"its speed passed {RUNAWAY_SPEED:g} m/s (|v| = {v:.3g} m/s)"
    else:
        detail = f"its angular speed passed {RUNAWAY_SPEED:g} rad/s (|w| = {w:.3g} rad/s)"
    held, touching = acting_on(sim, b)
    acting = [f"constraint `{c}`" for c in held] + [f"contact with `{o}`" for o in touching]
    if acting:
        detail += f"; acting on it: {', '.join(acting)}"
    return NumericalError(s.t, s.steps, f"body `{name}`", detail, sim.plan.scene.bodies[b].source,
                          body_hint(sim, b, held, touching))


def acting_on(sim, b: int) -> tuple:
    """([constraints], [bodies in contact]) acting on body b in the rows of the last step, by name."""
    held, touching = [], []
    act, c = sim.rows_now, sim.plan.constraints
    if act is not None and c is not None:
        rows = act.rows[act.rows < len(c.row_constraint)]
        on = rows[(c.row_bodies[rows] == b).any(axis=1)]
        held = list(dict.fromkeys(c.names[i] for i in c.row_constraint[on].tolist()))
    if sim.collider is not None:
        for contact in sim.collider.lasting.contacts.values():
            if b in (contact.a, contact.b):
                other = contact.b if contact.a == b else contact.a
                label = sim.plan.names[other] if other >= 0 else "the world"
                if label not in touching:
                    touching.append(label)
    return held, touching


def _assembling(sim, names: list) -> list:
    """[(constraint, omega rad/s, f Hz)] of the named constraints whose rows follow a stabilization curve in
    the last step (not held; every row under `stabilization baumgarte`), stiffest first."""
    act, c = sim.rows_now, sim.plan.constraints
    if act is None or c is None or not names:
        return []
    cons = sim.compiled.model.constraints
    found = {}
    for i, r in enumerate(act.rows.tolist()):
        if r >= len(c.row_constraint) or (act.held[i] and sim.plan.scene.solver.stabilization != "baumgarte"):
            continue
        name = c.names[c.row_constraint[r]]
        if name in names:
            found[name] = max(found.get(name, 0.0), math.sqrt(max(float(cons.ks[r]), 0.0)))
    return sorted(((n, om, om / (2 * math.pi)) for n, om in found.items()), key=lambda e: -e[1])


def stiffness_hint(sim, names: list) -> str | None:
    """What the step does to a row assembling at omega: omega h beyond the integrator's stable reach."""
    options = sim.plan.scene.solver
    if sim.plan.solver != "dynamics":
        return None
    reach = STABLE_OMEGA_H.get(options.integrator, 2.0)
    h = sim.plan.step
    for name, omega, frequency in _assembling(sim, names):
        if omega * h <= reach:
            continue
        refined = (options.integrator == "rk4" and options.tolerance > 0)
        control = (" (the error control refines a step 16 times at most)" if refined else
                   " (`tolerance 0`: the error control is off)" if options.integrator == "rk4" else "")
        return (f"constraint `{name}` assembles at {frequency:.3g} Hz (omega = {omega:.3g} rad/s): omega h = "
                f"{omega * h:.3g} at the {h * 1e3:.3g} ms step{control}, beyond the {reach:g} within which "
                f"{options.integrator} holds it; give it `stabilize {_down(reach / (2 * math.pi * h)):g} Hz` "
                f"or less, or a step of {_down(reach / omega * 1e3):g} ms or less")
    return None


def body_hint(sim, b: int, held: list, touching: list) -> str:
    s, name = sim.state, sim.plan.names[b]
    start = sim._initial[b]
    v0, w0 = _size(start[D.V]), _size(start[D.W])
    if not (v0 < RUNAWAY_SPEED and w0 < RUNAWAY_SPEED):
        return (f"`{name}` starts at |v| = {v0:.3g} m/s, |w| = {w0:.3g} rad/s, beyond the {RUNAWAY_SPEED:g} "
                f"a run allows: give it a slower `velocity` or `spin`")
    stiff = stiffness_hint(sim, held)
    if stiff is not None:
        return stiff
    said = ""
    frame = _last_frame_speeds(sim, b)
    if frame is not None:
        t, v, w = frame
        said = (f"at the last frame (t = {t:.6g} s) `{name}` moved at {v:.3g} m/s and turned at {w:.3g} rad/s, "
                f"{s.t - t:.3g} s before the blow-up; ")
    acting = ", ".join([f"constraint `{c}`" for c in held] + [f"the contact with `{o}`" for o in touching])
    if acting:
        return (f"{said}look at what acted on it then: {acting} (`isaac run --until {s.t:.6g}` and the "
                f"viewer show the motion up to it)")
    return (f"{said}nothing held or touched it: look at the forces, springs and winds on it "
            f"(`isaac run --until {s.t:.6g}` and the viewer show the motion up to it)")


def _last_frame_speeds(sim, b: int):
    """(time, |v| m/s, |w| rad/s) of body b at the last frame handed on, or None."""
    last = sim._last_delivered
    if last is None:
        return None
    t, y = last
    return t, _size(y[b, D.V]), _size(y[b, D.W])


def constraint_failure(sim, row: int, error: float) -> NumericalError:
    c = sim.plan.constraints
    rows = c.row_constraint if c is not None else ()
    if 0 <= row < len(rows):
        name = c.names[rows[row]]
        source = next((k.source for k in sim.plan.scene.constraints if k.name == name), None)
        culprit = f"constraint `{name}`"
    else:  # a contact's row
        name, source, culprit = None, None, f"contact {_contact_pair(sim, row)}"
    J = sim.compiled.scratch.J
    unit = "rad" if 0 <= row < len(J) and not np.any(J[row, :, :3]) else "m"
    hint = stiffness_hint(sim, [name]) if name is not None else None
    if hint is None:
        hint = (f"a {'joint' if name else 'contact'} more than {RUNAWAY_CONSTRAINT_ERROR:g} {unit} apart is no "
                f"longer held: look at what pulls it apart (`isaac run --until {sim.state.t:.6g}` and the "
                f"viewer show the motion up to it)")
    return NumericalError(sim.state.t, sim.state.steps, culprit, source=source, hint=hint,
                          detail=f"its error grew to {error:.3g} {unit}")


def _contact_pair(sim, row: int) -> str:
    """`a`-`b` of the contact whose row is global row `row`, or `?`."""
    if sim.collider is None or row < 0:
        return "`?`"
    k = int(sim.compiled.model.constraints.row_instance[row])
    for key, instance in sim.collider.lasting.instance_of.items():
        if instance == k:
            contact = sim.collider.lasting.contacts.get(key)
            if contact is not None:
                names = [sim.plan.names[i] if i >= 0 else "world" for i in (contact.a, contact.b)]
                return f"`{names[0]}`-`{names[1]}`"
    return "`?`"
