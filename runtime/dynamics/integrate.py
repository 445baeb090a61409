"""The dynamics plan's step loop, compiled: many steps per call, frames recorded inside it.

    dx/dt = v      dq/dt = 0.5 (0, w) q      dv/dt = a      dw/dt = alpha

RK4 (classic Runge-Kutta), MIDPOINT (explicit RK2) and EULER (semi-implicit: velocities first, then positions
with the new velocities, the orientation turned exactly by w h). Quaternions are renormalized at every stage.
After each step: kinematic bodies exactly on their paths, the projection of the held rows (projection.py),
rows that finished assembling join them, and a check for a blow-up (a non-finite state, or a speed beyond
RUNAWAY_SPEED). A scene at rest stops being integrated while its inputs stay constant (core/rest.py). The time
table has 2 rows per step (t, t + h/2, t + h at rows 2i, 2i+1, 2i+2).

`run(m, act, s, y, table, integrator, h, steps, frame_step, frames, status, entering, rest_after, carry)` advances
y by `steps` steps of h from t0 (step i at t0 + i h, no accumulated sum); after step frame_step[f] (0: before the
first) it records frame f: frames.y[f] the state, frames.energy[f], frames.error[f] the largest |C| of the active
rows and frames.worst[f] that row. status (4,) <- (code, step, body or row or contact, detail): code 0 done,
RUNAWAY_BODY, RUNAWAY_ROW, CONTACT (core/record.py after_step; CONTACT: the collision stage must look, detail the change,
core/contact.py). s.start holds the state at the start of the last step. Returns the steps taken.
"""
from __future__ import annotations

import math

from ..core.bodies import copy_state, normalize_quaternions, place_kinematic
from ..core.contact import add_impulses
from ..core.data import COUNTER_KEPT, COUNTER_TURNED_BACK
from ..core.jit import entry, inlined, kernel
from ..core.record import DONE, after_step, record
from ..core.rest import rests, still_after, still_at_end, still_at_start
from .accelerations import accelerations
from .projection import project, settle_rows

RK4, MIDPOINT, EULER = 0, 1, 2
INTEGRATORS = {"rk4": RK4, "midpoint": MIDPOINT, "euler": EULER}
GRID = 2  # time-table rows per step

@inlined
def _slope(m, act, s, y, table, j, k):
    """k (n+1,13) <- dy/dt at state y, grid row j: (v, 0.5 (0, w) q, a, alpha)."""
    accelerations(m, act, s, y, table, j, s.acc)
    for b in range(len(y)):
        w, x, yy, z = y[b, 3], y[b, 4], y[b, 5], y[b, 6]
        ox, oy, oz = y[b, 10], y[b, 11], y[b, 12]
        for c in range(3):
            k[b, c] = y[b, 7 + c]
        # dq/dt = 0.5 (0, w) * q
        k[b, 3] = 0.5 * (-ox * x - oy * yy - oz * z)
        k[b, 4] = 0.5 * (ox * w + oy * z - oz * yy)
        k[b, 5] = 0.5 * (-ox * z + oy * w + oz * x)
        k[b, 6] = 0.5 * (ox * yy - oy * x + oz * w)
        for c in range(6):
            k[b, 7 + c] = s.acc[b, c]


@kernel
def _stage(y0, k, scale, out):
    """out <- y0 + scale k, quaternions renormalized."""
    for b in range(len(y0)):
        for c in range(13):
            out[b, c] = y0[b, c] + scale * k[b, c]
    normalize_quaternions(out)


@kernel
def _scheme(integrator, i):
    """(c_i, b_i) of stage i of an explicit Runge-Kutta scheme whose stage i starts from y0 + c_i h k_{i-1}:
    RK4 (0, 1/2, 1/2, 1; weights 1/6, 1/3, 1/3, 1/6) and the explicit midpoint rule (0, 1/2; weights 0, 1);
    semi-implicit Euler takes the one slope at c = 0."""
    if integrator == RK4:
        return (0.0, 0.5, 0.5, 1.0)[i], (1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0)[i]
    if integrator == MIDPOINT:
        return (0.0, 0.5)[i], (0.0, 1.0)[i]
    return 0.0, 1.0


@inlined
def _slopes(m, act, s, y, table, j, h, integrator):
    """The scheme's slopes k_i at y0 + c_i h k_{i-1} (time t + c_i h: grid row j + 2 c_i), into s.k; s.y0 <- y
    with the kinematic bodies at t. One call site for the slope, in a loop, so that the right-hand side is compiled
    once for every scheme and stage."""
    stages = 4 if integrator == RK4 else 2 if integrator == MIDPOINT else 1
    copy_state(y, s.ys)
    for i in range(stages):
        c, _ = _scheme(integrator, i)
        if i > 0:
            _stage(s.y0, s.k[i - 1], c * h, s.ys)
        _slope(m, act, s, s.ys, table, j + int(GRID * c), s.k[i])
        if i == 0:
            copy_state(s.ys, s.y0)  # after the first slope: it placed the kinematic bodies at t
    return stages


@kernel
def _runge_kutta(s, y, h, integrator, stages):
    """y <- y0 + h sum_i b_i k_i, quaternions renormalized."""
    for b in range(len(y)):
        for e in range(13):
            total = 0.0
            for i in range(stages):
                total += _scheme(integrator, i)[1] * s.k[i, b, e]
            y[b, e] = s.y0[b, e] + h * total
    normalize_quaternions(y)


@kernel
def _semi_implicit_euler(s, y, h):
    """v += h a(x, v); x += h v_new; q turned by w_new for h (exact for constant w), renormalized."""
    for b in range(len(y) - 1):
        for c in range(13):
            y[b, c] = s.y0[b, c]
        for c in range(6):
            y[b, 7 + c] += h * s.k[0, b, 7 + c]
        for c in range(3):
            y[b, c] += h * y[b, 7 + c]
        ox, oy, oz = y[b, 10], y[b, 11], y[b, 12]
        speed = math.sqrt(ox * ox + oy * oy + oz * oz)
        half = 0.5 * h * speed
        # dq = (cos(|w| h / 2), sin(|w| h / 2) w / |w|), q <- dq * q
        scale = math.sin(half) / speed if speed > 1e-12 else 0.5 * h
        dw, dx, dy, dz = math.cos(half), scale * ox, scale * oy, scale * oz
        w, x, yy, z = y[b, 3], y[b, 4], y[b, 5], y[b, 6]
        y[b, 3] = dw * w - dx * x - dy * yy - dz * z
        y[b, 4] = dw * x + dx * w + dy * z - dz * yy
        y[b, 5] = dw * yy - dx * z + dy * w + dz * x
        y[b, 6] = dw * z + dx * yy - dy * x + dz * w
    normalize_quaternions(y)


@inlined
def one_step(m, act, s, y, table, integrator, j, h):
    """One step of h from grid row j, then the kinematic bodies on their paths and the projection."""
    stages = _slopes(m, act, s, y, table, j, h, integrator)
    if integrator == EULER:
        _semi_implicit_euler(s, y, h)
    else:
        _runge_kutta(s, y, h, integrator, stages)
    place_kinematic(m.kinematic, table, j + GRID, y)
    project(m, act, s, y, table, j + GRID, False)
    settle_rows(m, act, s, y)


@entry
def run(m, act, s, y, table, integrator, h, steps, frame_step, frames, status, entering, rest_after, carry):
    """Advance y by `steps` steps of h (module docstring); `entering` an epoch, first the held rows onto their
    manifold (a row that switched on with its points together but moving apart is held from this instant). A step
    after which the collision stage must look ends the call before its frame is recorded (status CONTACT). After
    `rest_after` steps in a row at rest (core/rest.py; 0: never) the steps leave the state as it is while the
    inputs stay constant; `carry`: the active rows are those of the last call, whose count of such steps goes on."""
    status[0], status[1], status[2], status[3] = DONE, 0, -1, 0
    s.counters[COUNTER_KEPT] = 0  # (a factor in Lx from an earlier call may be of other rows)
    if entering:
        project(m, act, s, y, table, 0, True)
    f = 0
    while f < len(frame_step) and frame_step[f] == 0:
        record(m, act, s, y, table, 0, frames, f)
        f += 1
    still = still_at_start(s, y, carry and not entering)  # steps in a row, inputs constant, every body at rest
    done = steps
    for step in range(steps):
        copy_state(y, s.start)
        s.counters[COUNTER_TURNED_BACK] = 0
        if not rests(s, table, GRID * step, GRID, rest_after, still):
            one_step(m, act, s, y, table, integrator, GRID * step, h)
            still = still_after(m, act, s, y, table, GRID * step, GRID, h, still)
        if len(m.pairs.a):
            add_impulses(act, m.constraints, s.lam, act.local, h, s.impulse)
        taken, f = after_step(m, act, s, y, table, GRID * (step + 1), step, frame_step, frames, f, status)
        if taken >= 0:
            done = taken
            break
    still_at_end(s, y, still)
    return done
