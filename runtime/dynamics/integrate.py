"""The dynamics plan's step loop, compiled: many steps per call, frames recorded inside it.

    dx/dt = v      dq/dt = 0.5 (0, w) q      dv/dt = a      dw/dt = alpha

RK4 (classic Runge-Kutta), MIDPOINT (explicit RK2) and EULER (semi-implicit: velocities first, then positions
with the new velocities, the orientation turned exactly by w h). Quaternions are renormalized at every stage.
After each step: kinematic bodies exactly on their paths, the projection of the held rows (projection.py),
rows that finished assembling join them, and a check for a blow-up (a non-finite state, or a speed beyond
RUNAWAY_SPEED). A scene at rest stops being integrated while its inputs stay constant (core/rest.py). The time
table has 2 rows per step (t, t + h/2, t + h at rows 2i, 2i+1, 2i+2).

Error control (RK4, `tolerance` > 0). The slope at the end of a step, k5 = f(y1), which the next step needs as its
first, gives an embedded third-order solution for free (the nodes 0, 1/2, 1/2, 1, 1; weights 1/6, 2/9, 4/9, 0, 1/6
meet the four conditions of order 3), so the local error of the step is estimated by

    e = y1 - y1* = h (k2 / 9 - k3 / 9 + (k4 - k5) / 6)

measured on the velocities in the kinetic-energy norm, relative to the larger E of the scene's energy scale
(the yardstick of report.json's energy drift) and its kinetic energy:

    err = sqrt(sum m |e_v|^2 + e_w . I e_w) / sqrt(2 E)

A step whose err passes the tolerance is taken again from its start in N = 2, 4, .. MAX_SUBSTEPS substeps, N^3 >=
err / tolerance (the estimate is O(h^4) a step, N substeps add N (h/N)^4); a step of smooth motion is never taken
again, and its result is the plain RK4 step's. Substeps read the time table's row of the step's start, so they are
taken only while the inputs are constant over the step (core/rest.py inputs_still) and no wind blows; a step over
the tolerance that cannot be refined is counted (report.json `steps_over_tolerance`).

`run(m, act, s, y, table, integrator, h, steps, frame_step, frames, status, entering, rest_after, carry,
tolerance, energy_scale)` advances y by `steps` steps of h from t0 (step i at t0 + i h, no accumulated sum); after
step frame_step[f] (0: before the first) it records frame f: frames.y[f] the state, frames.energy[f],
frames.error[f] the largest |C| of the active rows and frames.worst[f] that row. status (4,) <- (code, step, body or
row or contact, detail): code 0 done, RUNAWAY_BODY, RUNAWAY_ROW, CONTACT (core/record.py after_step; CONTACT: the
collision stage must look, detail the change, core/contact.py). s.start holds the state at the start of the last
step. Returns the steps taken.
"""
from __future__ import annotations

import math

from ..core.bodies import copy_state, normalize_quaternions, place_kinematic
from ..core.contact import add_impulses
from ..core.data import (COUNTER_KEPT, COUNTER_OVER, COUNTER_REFINED, COUNTER_SLOPE, COUNTER_STILL,
                         COUNTER_SUBSTEPS, COUNTER_TURNED_BACK)
from ..core.jit import entry, inlined, kernel
from ..core.record import DONE, after_step, record
from ..core.rest import inputs_still, rests, resumes, still_after, still_at_end
from ..core.vec import dot3, rotate, rotate_t
from .accelerations import accelerations
from ..core.projection import project, settle_rows

RK4, MIDPOINT, EULER = 0, 1, 2
INTEGRATORS = {"rk4": RK4, "midpoint": MIDPOINT, "euler": EULER}
GRID = 2  # time-table rows per step
END = 4  # s.k[END]: the slope at the end of the last step, the next step's first (error control)
MAX_SUBSTEPS = 16  # the most substeps a step over the tolerance is taken again in

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
def one_step(m, act, s, y, table, integrator, j, h, stride, known, end):
    """One step of h from grid row j whose end is row j + stride (GRID; 0 for a substep of a step with constant
    inputs): the scheme's slopes k_i at y0 + c_i h k_{i-1} (time t + c_i h: grid row j + stride c_i) into s.k, y
    their sum, the kinematic bodies on their paths and the projection; with `end`, then s.k[END] the slope at the
    result (the multipliers and the turned-back count left those of the step: its impulses and contact checks read
    them). `known`: the first slope is s.k[END], the last step's end slope at this very state (y's kinematic bodies
    already at t). s.y0 <- y with the kinematic bodies at t. One call site for the slope, in one loop, so that the
    right-hand side is compiled once for every scheme, stage and end slope."""
    stages = 4 if integrator == RK4 else 2 if integrator == MIDPOINT else 1
    copy_state(y, s.ys)
    turned = 0
    for i in range(stages + 2):
        if i == stages:
            _finish(m, act, s, y, table, integrator, j + stride, h, stages)
            continue
        if i == stages + 1:
            if not end:
                break
            copy_state(y, s.ys)
            turned, row, target = _keep_multipliers(s), j + stride, END
        else:
            c, _ = _scheme(integrator, i)
            if i > 0:
                _stage(s.y0, s.k[i - 1], c * h, s.ys)
            row, target = j + int(stride * c), i
        if i == 0 and known:
            copy_state(s.k[END], s.k[0])
        else:
            _slope(m, act, s, s.ys, table, row, s.k[target])
        if i == 0:
            copy_state(s.ys, s.y0)  # after the first slope: it placed the kinematic bodies at t
    if end:
        _restore_multipliers(s, turned)


@inlined
def _finish(m, act, s, y, table, integrator, j, h, stages):
    """y <- the step's result from its slopes, the kinematic bodies at grid row j, the held rows projected."""
    if integrator == EULER:
        _semi_implicit_euler(s, y, h)
    else:
        _runge_kutta(s, y, h, integrator, stages)
    place_kinematic(m.kinematic, table, j, y)
    project(m, act, s, y, table, j, False, h if integrator == EULER else 0.0)
    settle_rows(m, act, s, y)


@kernel
def _keep_multipliers(s):
    """s.lam_step <- the step's multipliers; returns its turned-back count."""
    for r in range(len(s.lam)):
        s.lam_step[r] = s.lam[r]
    return s.counters[COUNTER_TURNED_BACK]


@kernel
def _restore_multipliers(s, turned):
    for r in range(len(s.lam)):
        s.lam[r] = s.lam_step[r]
    s.counters[COUNTER_TURNED_BACK] = turned


@kernel
def _embedded(k, b, c, h):
    """Component c of body b of e = y1 - y1*, the RK4 step less its embedded third-order solution."""
    # e = h (k2 / 9 - k3 / 9 + (k4 - k5) / 6)
    return h * ((k[1, b, c] - k[2, b, c]) / 9.0 + (k[3, b, c] - k[END, b, c]) / 6.0)


@kernel
def step_error(m, s, y, h, energy_scale):
    """The estimated local error of the RK4 step just taken to y (module docstring), s.k[1..3] its slopes and
    s.k[END] the slope at its end (R current at y): sqrt(sum m |e_v|^2 + e_w . I e_w) / sqrt(2 E), E the larger of
    the scene's energy scale and the kinetic energy at y."""
    error, kinetic = 0.0, 0.0
    k = s.k
    for b in range(len(y) - 1):
        if not m.bodies.dynamic[b]:
            continue
        ev = (_embedded(k, b, 7, h), _embedded(k, b, 8, h), _embedded(k, b, 9, h))
        ew = (_embedded(k, b, 10, h), _embedded(k, b, 11, h), _embedded(k, b, 12, h))
        v, w = (y[b, 7], y[b, 8], y[b, 9]), (y[b, 10], y[b, 11], y[b, 12])
        # m |e_v|^2 + e_w . I e_w and m |v|^2 + w . I w, I = R I_b R^T
        u, uw = rotate_t(s.R, b, ew), rotate_t(s.R, b, w)
        error += m.bodies.mass[b] * dot3(ev, ev) + dot3(u, rotate(m.bodies.inertia, b, u))
        kinetic += 0.5 * (m.bodies.mass[b] * dot3(v, v) + dot3(uw, rotate(m.bodies.inertia, b, uw)))
    return math.sqrt(error / (2.0 * max(energy_scale, kinetic)))


@kernel
def substeps_for(error, tolerance):
    """The fewest substeps N (a power of 2, at most MAX_SUBSTEPS) with N^3 >= error / tolerance."""
    n = 2
    while n < MAX_SUBSTEPS and n * n * n * tolerance < error:
        n *= 2
    return n


@inlined
def refine(m, s, y, table, j, h, tolerance, energy_scale):
    """After an RK4 step of h from grid row j under error control (module docstring): the substeps to take it
    again in from s.start (y back there), or 1 to keep it."""
    error = step_error(m, s, y, h, energy_scale)
    if not error > tolerance:
        return 1
    if len(m.wind.body) or not inputs_still(table, j, GRID):
        s.counters[COUNTER_OVER] += 1
        return 1
    n = substeps_for(error, tolerance)
    s.counters[COUNTER_REFINED] += 1
    s.counters[COUNTER_SUBSTEPS] += n
    if n * n * n * tolerance < error:
        s.counters[COUNTER_OVER] += 1
    return n


@entry
def run(m, act, s, y, table, integrator, h, steps, frame_step, frames, status, entering, rest_after, carry,
        same_inputs, tolerance, energy_scale):
    """Advance y by `steps` steps of h (module docstring); `entering` an epoch, first the held rows onto their
    manifold (a row that switched on with its points together but moving apart is held from this instant). A step
    after which the collision stage must look ends the call before its frame is recorded (status CONTACT). After
    `rest_after` steps in a row at rest (core/rest.py; 0: never) the steps leave the state as it is while the
    inputs stay constant; `carry`: the active rows are those of the last call, whose count of such steps and kept
    factor go on; `same_inputs`: table row 0 is the row the last call ended at (its last slope goes on too).
    `tolerance` > 0: RK4 steps under error control, relative to `energy_scale` (module docstring)."""
    status[0], status[1], status[2], status[3] = DONE, 0, -1, 0
    if not carry:
        # a factor in Lx from an earlier call may be of other rows. With the same rows it is kept, as it would be
        # between two steps of one call (solve_again checks that it serves): a run steps alike whether a call
        # covers one frame or many (a live run calls once a frame)
        s.counters[COUNTER_KEPT] = 0
    if entering:
        project(m, act, s, y, table, 0, True, 0.0)
    f = 0
    while f < len(frame_step) and frame_step[f] == 0:
        record(m, act, s, y, table, 0, frames, f)
        f += 1
    resumed = resumes(s, y, carry and not entering)
    still = s.counters[COUNTER_STILL] if resumed else 0  # steps in a row, inputs constant, every body at rest
    done = steps
    controlled = integrator == RK4 and tolerance > 0.0
    # s.k[END] holds the slope at y (so it does at the call's start when the last call's last step left it there:
    # computed again, a sliding contact's friction iterations start from other multipliers, and the run would not
    # step alike whether a call covers one frame or many)
    known = resumed and same_inputs and controlled and s.counters[COUNTER_SLOPE] == 1
    for step in range(steps):
        copy_state(y, s.start)
        s.counters[COUNTER_TURNED_BACK] = 0
        if rests(s, table, GRID * step, GRID, rest_after, still):
            known = False
        else:
            pieces, piece = 1, 0  # the step, or the substeps it is taken again in (one call site of the step)
            while piece < pieces:
                one_step(m, act, s, y, table, integrator, GRID * step, h / pieces, GRID if pieces == 1 else 0,
                         known, controlled)
                known, piece = controlled, piece + 1
                if controlled and pieces == 1:
                    pieces = refine(m, s, y, table, GRID * step, h, tolerance, energy_scale)
                    if pieces > 1:
                        copy_state(s.start, y)
                        copy_state(s.k[0], s.k[END])  # (the slope at the start: the first substep's first)
                        piece = 0
            still = still_after(m, act, s, y, table, GRID * step, GRID, h, still)
        if len(m.pairs.a):
            add_impulses(act, m.constraints, s.lam, act.local, h, s.impulse)
        taken, f = after_step(m, act, s, y, table, GRID * (step + 1), step, frame_step, frames, f, status)
        if taken >= 0:
            done = taken
            break
    s.counters[COUNTER_SLOPE] = 1 if known else 0
    still_at_end(s, y, still)
    return done
