"""Wind stage, compiled: the air velocity u(x, t) and the drag it puts on bodies, as kernels the compiled step
calls many steps at a time, with no Python per force evaluation (docs/design/physics.md section 7).

    WindModel          the winds and the bodies in them, as plain arrays: one compiled signature for every scene
    wind_model(wind)   built from a WindPlan (which stays the reference); empty_wind_model() without a wind
    speeds_table       s_w(t) of every wind at the times of a chunk of steps (Python: the speed expressions)
    wind_table         the same, followed by the source points o_w(t) and the directions d_w(t) (what the step
                       reads: a wind that moves is tabulated like its speed)
    air_velocity       u(x, t) at points, the sum of the winds (the audio graph's field)
    wind_drag          force model:      force, torque += F, tau
    wind_relax         procedural model: force <- phi (force + F), torque <- phi_w (torque + tau)
    wind_apply         each body by its own model (WindModel.model)

The equations are those of fields.py (u = s f(r) c(theta) e + I |u| G), turbulence.py (G: octaves of value
noise hashed with SplitMix64) and drag.py (F = 1/2 rho Cd A(n) |u_rel| u_rel at r_cp, the turning damping,
phi(kappa h)). The noise hashes each lattice point when it is read (no windows of cached values). Sums of three
products are added in the order numpy's einsum adds them (a contiguous axis: (0 + 2) + 1; a strided one:
(0 + 1) + 2), so the kernels give the numpy stage's numbers to the last bit but where numpy's own arccos and
expm1 round differently from the C library's (one ulp, in a cone's soft edge and in phi).

The speeds s_w(t) stay in Python (they may read a recording, the microphone, seeded noise): the caller tabulates
them once per chunk (speeds_table) and passes a row per force evaluation. A wind whose speed is 0 is skipped, as
WindFields.velocity skips it: zero the other winds' speeds to hear one wind alone. The time t is passed too: the
gusts G(x, t) follow it.

Speed: numba increfs and decrefs every array of the WindModel (37) in a function that takes it and calls another
function with it, ~10 ns an array at every call; in a function that calls only small helpers the counts are
pruned away. So the model goes to leaves only (velocity_at, with its gusts inlined; drag_on_body; relaxation),
the loops over the bodies are written out in each kernel, and no array view is taken (rows are read into tuples):
what is left is one count of each array at a kernel's entry.
"""
from __future__ import annotations

import math
from collections import namedtuple

import numpy as np

from isaac_ir import expr as E

from ..core.jit import inlined, kernel
from ..core.vec import cross3
from .drag import TINY_SPEED
from .fields import CONE_EDGE, CORE
from .turbulence import MIX1, MIX2, OCTAVES

# the model number of each body (WindModel.model)
FORCE, PROCEDURAL = 0, 1
# the hash's shifts, as uint64 (a uint64 shifted by a plain int would be promoted to float64)
_SHIFT11, _SHIFT27, _SHIFT30, _SHIFT31 = np.uint64(11), np.uint64(27), np.uint64(30), np.uint64(31)
# the top 53 bits of a hash, times this, are in [0, 2)
_UNIT = 2.0 / 2.0**53


WindModel = namedtuple("WindModel", [
    # per wind (m): the field
    "is_source",  # (m,) bool: blows from a point (else uniform)
    "origin",  # (m,3) the source point
    "direction",  # (m,3) unit
    "power",  # (m,) falloff exponent p (0, 1, 2)
    "reference",  # (m,) r0, m
    "core",  # (m,) CORE r0: the falloff is held inside it
    "spread",  # (m,) cone half-angle, rad
    "cone_edge",  # (m,) max(spread CONE_EDGE, 1e-9): the soft edge's width
    "turbulence",  # (m,) I
    # per wind: the gusts G(x, t) (zeros for a wind without)
    "has_gusts",  # (m,) bool
    "gust_time",  # (m,) T, s
    "gust_length",  # (m,) L = GUST_SPEED T, m
    "gust_k",  # (m,3,O,3) unit direction of component c, octave o
    "gust_salt",  # (m,3,O) int64: the bits of salt * GOLDEN mod 2^64 (the salt's part of the lattice hash)
    "gust_frequency",  # (m,O) 2^o
    "gust_offset",  # (m,O) 0.37 o
    "gust_amplitude",  # (m,O) GAIN^o / fbm_norm
    # per body in the wind (k)
    "body",  # (k,) int64: its row in the scene's bodies (in y, R, force, torque, air)
    "model",  # (k,) int64: FORCE or PROCEDURAL
    "air_density",  # (k,) rho, kg/m3
    "mass",  # (k,) kg
    "moments",  # (k,3) principal moments, kg m2
    "cd",  # (k,)
    "area0",  # (k,) A = area0 + face . |n| + side sqrt(1 - n_z^2)
    "face",  # (k,3)
    "side",  # (k,)
    "half",  # (k,3) half extents H
    "sweep",  # (k,3,3) J_kj, m^4
    "spin",  # (k,3) K_j, m^5
    "size",  # (k,) cross dimension d, m (aeolian tones)
    "half_rho_cd",  # (k,) 1/2 rho Cd
    "rho_cd",  # (k,) rho Cd
    "spin_drag",  # (k,3) 1/2 rho Cd K
    "spin_rate",  # (k,3) rho Cd K (the procedural model's turning rate)
    "arm",  # (k,3) -CP_SHIFT H: r_cp = arm * n
    "shaped",  # (k,) bool: A depends on n
    "turning",  # (k,) bool: the wind can turn it
])


# ---- building the model ----------------------------------------------------------------------------------------

def wind_model(wind) -> WindModel:
    """The arrays of a WindPlan (its fields, bodies and constants), for the kernels; None gives the empty model."""
    if wind is None:
        return empty_wind_model()
    f, b, c = wind.fields, wind.bodies, wind.constants
    k = len(b.body)
    rho = np.full(k, float(wind.air_density))
    model = np.full(k, PROCEDURAL if wind.model == "procedural" else FORCE, dtype=np.int64)
    shaped = np.any(b.face != 0, axis=1) | (b.side != 0)
    turning = np.any(b.half != 0, axis=1) | np.any(b.sweep != 0, axis=(1, 2)) | np.any(b.spin != 0, axis=1)
    winds = dict(
        is_source=f.is_source, origin=f.origin, direction=f.direction, power=f.power, reference=f.reference,
        # CORE r0 and the cone's edge, as fields.py computes them at every call
        core=CORE * f.reference, spread=f.spread, cone_edge=np.maximum(f.spread * CONE_EDGE, 1e-9),
        turbulence=f.turbulence, **_gust_arrays(f.gusts))
    bodies = dict(
        body=b.body, model=model, air_density=rho, mass=b.mass, moments=b.moments, cd=b.cd, area0=b.area0,
        face=b.face, side=b.side, half=b.half, sweep=b.sweep, spin=b.spin, size=b.size,
        half_rho_cd=c.half_rho_cd, rho_cd=c.rho_cd, spin_drag=c.spin_drag,
        # rho Cd K, as relaxation_factors multiplies it
        spin_rate=rho[:, None] * b.cd[:, None] * b.spin, arm=c.arm, shaped=shaped, turning=turning)
    return _typed(WindModel(**winds, **bodies))


def empty_wind_model() -> WindModel:
    """No wind, no body in it: the kernels do nothing, with the signature of every other scene."""
    return _typed(WindModel(**{name: np.zeros(_EMPTY_SHAPES.get(name, (0,))) for name in WindModel._fields}))


_EMPTY_SHAPES = {"origin": (0, 3), "direction": (0, 3), "gust_k": (0, 3, OCTAVES, 3), "gust_salt": (0, 3, OCTAVES),
                 "gust_frequency": (0, OCTAVES), "gust_offset": (0, OCTAVES), "gust_amplitude": (0, OCTAVES),
                 "moments": (0, 3), "face": (0, 3), "half": (0, 3), "sweep": (0, 3, 3), "spin": (0, 3),
                 "spin_drag": (0, 3), "spin_rate": (0, 3), "arm": (0, 3)}
_BOOL = ("is_source", "has_gusts", "shaped", "turning")
_INT = ("body", "model", "gust_salt")


def _typed(model: WindModel) -> WindModel:
    """Every field C-contiguous, of its one dtype (bool, int64 or float64), whatever the scene."""
    def typed(name, value):
        dtype = np.bool_ if name in _BOOL else np.int64 if name in _INT else np.float64
        return np.ascontiguousarray(value, dtype=dtype)

    return WindModel(*(typed(name, value) for name, value in zip(WindModel._fields, model)))


def _gust_arrays(gusts: list) -> dict:
    """The GustFields' constants stacked by wind; zeros for a wind without gusts."""
    m = len(gusts)
    out = dict(has_gusts=np.zeros(m, bool), gust_time=np.ones(m), gust_length=np.ones(m),
               gust_k=np.zeros((m, 3, OCTAVES, 3)), gust_salt=np.zeros((m, 3, OCTAVES), np.int64),
               gust_frequency=np.zeros((m, OCTAVES)), gust_offset=np.zeros((m, OCTAVES)),
               gust_amplitude=np.zeros((m, OCTAVES)))
    for w, field in enumerate(gusts):
        if field is None:
            continue
        if field.k.shape != (3, OCTAVES, 3):
            raise ValueError(f"the compiled gusts have {OCTAVES} octaves, wind {w}'s field has {field.k.shape[1]}")
        out["has_gusts"][w] = True
        out["gust_time"][w], out["gust_length"][w] = field.time_scale, field.length
        out["gust_k"][w] = field.k
        out["gust_salt"][w] = field.salt_mix[:, :, 0].view(np.int64)
        out["gust_frequency"][w] = field.frequency[0, :, 0]
        out["gust_offset"][w] = field.offset[0, :, 0]
        out["gust_amplitude"][w] = field.amplitude[0, :, 0]
    return out


# ---- the speeds, tabulated ---------------------------------------------------------------------------------------

def speeds_table(wind, times) -> np.ndarray:
    """(G, m) s_w(t) of every wind at each of the G times, WindFields.speed_at's values. Each wind's expression
    is evaluated on the array of times at once when it can be (checked against speed_at at the first and last
    time), else time by time."""
    times = np.ascontiguousarray(times, dtype=float).reshape(-1)
    m = 0 if wind is None else len(wind.fields.names)
    table = np.empty((len(times), m))
    for w in range(m):
        column = _speeds_at_once(wind.fields, w, times)
        table[:, w] = column if column is not None else [wind.fields.speed_at(w, float(t)) for t in times]
    return table


def wind_table(wind, times) -> np.ndarray:
    """(G, 7m): speeds_table's s_w(t), then o_w(t) (3 per wind), then the unit d_w(t) (3 per wind), at each of
    the G times; a wind that does not move repeats its constants."""
    times = np.ascontiguousarray(times, dtype=float).reshape(-1)
    fields = wind.fields
    m = len(fields.names)
    origins = np.repeat(fields.origin.reshape(1, 3 * m), len(times), axis=0)
    directions = np.repeat(fields.direction.reshape(1, 3 * m), len(times), axis=0)
    for w, (origin, direction) in enumerate(fields.paths):
        if origin is not None:
            origins[:, 3 * w:3 * w + 3] = _vectors_of_time(origin, times)
        if direction is not None:
            d = _vectors_of_time(direction, times)
            # d = d(t) / |d(t)|
            directions[:, 3 * w:3 * w + 3] = d / np.sqrt(np.einsum("ij,ij->i", d, d))[:, None]
    return np.hstack((speeds_table(wind, times), origins, directions))


def _vectors_of_time(node, times: np.ndarray) -> np.ndarray:
    """(G, 3) a vector expression of t at each time (one vectorized evaluation when it takes one)."""
    try:
        value = E.evaluate(node, {"t": times})
        return np.ascontiguousarray(np.stack([np.broadcast_to(np.asarray(c, float), times.shape) for c in value],
                                             axis=1))
    except (E.EvaluationError, ValueError, TypeError):
        return np.array([np.asarray(E.evaluate(node, {"t": float(t)}), float) for t in times]).reshape(-1, 3)


def _speeds_at_once(fields, w: int, times: np.ndarray):
    """s_w at all the times from one vectorized evaluation, or None when the expression does not take an array
    of times (a signal function that wants a float argument) or disagrees with speed_at at either end."""
    if len(times) == 0:
        return np.empty(0)
    try:
        value = E.evaluate(fields.speed[w], {"t": times}, fields.functions[w])
        column = np.broadcast_to(np.asarray(value, dtype=float), times.shape)
    except (E.EvaluationError, ValueError, TypeError):
        return None
    for g in (0, len(times) - 1):
        expected = fields.speed_at(w, float(times[g]))
        if not (column[g] == expected or (math.isnan(expected) and math.isnan(column[g]))):
            return None
    return column


# ---- three-term sums in numpy's order ------------------------------------------------------------------------------

@kernel
def _contiguous_sum(a0, a1, a2):
    """a0 + a1 + a2 as np.einsum adds a contiguous axis of three (two lanes: (a0 + a2) + a1)."""
    return (a0 + a2) + a1


@kernel
def _norm(a):
    """|a| = sqrt(a . a), np.einsum("ij,ij->i")'s sum."""
    return math.sqrt(_contiguous_sum(a[0] * a[0], a[1] * a[1], a[2] * a[2]))


@kernel
def _rows(R, i):
    """Body i's rotation R[i] (n,3,3) as three row tuples (no array view: a view costs a reference count)."""
    return ((R[i, 0, 0], R[i, 0, 1], R[i, 0, 2]), (R[i, 1, 0], R[i, 1, 1], R[i, 1, 2]),
            (R[i, 2, 0], R[i, 2, 1], R[i, 2, 2]))


@kernel
def _row3(a, j):
    """(a[j, 0], a[j, 1], a[j, 2]) of a (k,3) array."""
    return (a[j, 0], a[j, 1], a[j, 2])


@kernel
def _to_world(R, a):
    """R a for R as row tuples, np.einsum("kij,kj->ki")'s sums."""
    return (_contiguous_sum(R[0][0] * a[0], R[0][1] * a[1], R[0][2] * a[2]),
            _contiguous_sum(R[1][0] * a[0], R[1][1] * a[1], R[1][2] * a[2]),
            _contiguous_sum(R[2][0] * a[0], R[2][1] * a[1], R[2][2] * a[2]))


@kernel
def _to_body(R, a):
    """R^T a for R as row tuples, np.einsum("kji,kj->ki")'s sums (a strided axis: added in order)."""
    return (R[0][0] * a[0] + R[1][0] * a[1] + R[2][0] * a[2], R[0][1] * a[0] + R[1][1] * a[1] + R[2][1] * a[2],
            R[0][2] * a[0] + R[1][2] * a[1] + R[2][2] * a[2])


# ---- gusts: fractal value noise, hashed on demand -------------------------------------------------------------------

@kernel
def _splitmix(z):
    """SplitMix64's finaliser (uint64, wrapping modulo 2^64)."""
    z = (z ^ (z >> _SHIFT30)) * MIX1
    z = (z ^ (z >> _SHIFT27)) * MIX2
    return z ^ (z >> _SHIFT31)


@kernel
def lattice_value(cell, salt_mix):
    """The lattice value in [-1, 1) at the integer `cell` (a float): z = i + salt GOLDEN (mod 2^64), hashed;
    its top 53 bits as a float in [0, 2), minus 1. salt_mix: the int64 bits of salt * GOLDEN."""
    z = np.uint64(np.int64(cell)) + np.uint64(salt_mix)
    return np.float64(_splitmix(z) >> _SHIFT11) * _UNIT - 1.0


@kernel
def _octave(s, salt_mix, amplitude):
    """amplitude n(s), n(s) = a + (b - a) S(f): a, b the lattice values at floor(s) and one above, f = s - floor(s)."""
    cell = np.floor(s)
    f = s - cell
    a = lattice_value(cell, salt_mix)
    rise = lattice_value(cell + 1.0, salt_mix) - a
    # S(f) = f^3 (f (6 f - 15) + 10)
    fade = (f * f * f) * ((f * 6.0 - 15.0) * f + 10.0)
    return amplitude * (a + rise * fade)


@inlined
def _gust_component(wm, w, c, x, phase):
    """G_c = sum_o amplitude_o n(s), s = 2^o (t / T + x . k_oc / L) + 0.37 o, the octaves added in order."""
    total = 0.0
    k = wm.gust_k
    for o in range(k.shape[2]):
        # x . k / L
        along = _contiguous_sum(k[w, c, o, 0] * x[0], k[w, c, o, 1] * x[1], k[w, c, o, 2] * x[2]) / wm.gust_length[w]
        s = (along + phase) * wm.gust_frequency[w, o] + wm.gust_offset[w, o]
        term = _octave(s, wm.gust_salt[w, c, o], wm.gust_amplitude[w, o])
        total = term if o == 0 else total + term
    return total


@inlined
def gust(wm, w, x, t):
    """G(x, t) of wind w at the point x (a 3-tuple): three independent unit-RMS fractal noises."""
    phase = t / wm.gust_time[w]
    return (_gust_component(wm, w, 0, x, phase), _gust_component(wm, w, 1, x, phase),
            _gust_component(wm, w, 2, x, phase))


# ---- the field -----------------------------------------------------------------------------------------------------

@kernel
def _pose(wm, w, speeds):
    """(o, d) of wind w now: from the row of wind_table (speeds, then 3m of points, then 3m of directions) when
    it has them, else the model's constants (a row of speeds_table alone)."""
    m = wm.is_source.shape[0]
    if speeds.shape[0] == 7 * m:
        o, d = 3 * w + m, 3 * w + 4 * m
        return (speeds[o], speeds[o + 1], speeds[o + 2]), (speeds[d], speeds[d + 1], speeds[d + 2])
    return _row3(wm.origin, w), _row3(wm.direction, w)


@kernel
def _uniform_mean(wm, w, s, speeds):
    """u = s d."""
    d = _pose(wm, w, speeds)[1]
    return (s * d[0], s * d[1], s * d[2])


@kernel
def _cone(theta, spread, edge):
    """c(theta) = 1 - smoothstep(spread, spread + edge, theta)."""
    u = min(max((theta - spread) / edge, 0.0), 1.0)
    return 1.0 - u * u * (3.0 - 2.0 * u)


@kernel
def _falloff(q, p):
    """q^p for p = 0, 1, 2 as numpy's power takes them (1, q, q q), any other p by pow."""
    if p == 0.0:
        return 1.0
    if p == 1.0:
        return q
    if p == 2.0:
        return q * q
    return q**p


@kernel
def _source_mean(wm, w, s, x, speeds):
    """u = s f(|r|) c(theta) e, r = x - o, e = r / |r| (d at the source itself)."""
    o, d = _pose(wm, w, speeds)
    r = (x[0] - o[0], x[1] - o[1], x[2] - o[2])
    dist = _norm(r)
    if dist == 0.0:
        e = d
    else:
        reach = max(dist, 1e-300)
        e = (r[0] / reach, r[1] / reach, r[2] / reach)
    # theta = angle(e, d)
    theta = math.acos(min(max(e[0] * d[0] + e[1] * d[1] + e[2] * d[2], -1.0), 1.0))
    # f = (r0 / max(r, CORE r0))^p
    falloff = _falloff(wm.reference[w] / max(dist, wm.core[w]), wm.power[w])
    scale = s * falloff * _cone(theta, wm.spread[w], wm.cone_edge[w])
    return (scale * e[0], scale * e[1], scale * e[2])


@kernel
def velocity_at(wm, x, speeds, t):
    """u(x, t) at one point x (3-tuple): the sum of the winds, those with s_w = 0 left out."""
    total = (0.0, 0.0, 0.0)
    first = True
    for w in range(wm.is_source.shape[0]):
        s = speeds[w]
        if s == 0.0:
            continue
        u = _source_mean(wm, w, s, x, speeds) if wm.is_source[w] else _uniform_mean(wm, w, s, speeds)
        if wm.has_gusts[w]:
            # u' = I |u| G(x, t), added to the mean
            scale = wm.turbulence[w] * _norm(u)
            g = gust(wm, w, x, t)
            u = (u[0] + scale * g[0], u[1] + scale * g[1], u[2] + scale * g[2])
        # (the first wind is the total itself: 0 + u is u)
        total = u if first else (total[0] + u[0], total[1] + u[1], total[2] + u[2])
        first = False
    return total


@kernel
def air_velocity(wm, points, speeds, t, out):
    """out (p,3) <- u(x, t) at the points (p,3); speeds (m,) the winds' s_w(t)."""
    for p in range(points.shape[0]):
        u = velocity_at(wm, (points[p, 0], points[p, 1], points[p, 2]), speeds, t)
        out[p, 0], out[p, 1], out[p, 2] = u[0], u[1], u[2]


# ---- drag ------------------------------------------------------------------------------------------------------------

@kernel
def _area(wm, j, n):
    """A(n) = area0 + face . |n| + side sqrt(1 - n_z^2) for the body-frame unit direction n."""
    face = _row3(wm.face, j)
    lateral = math.sqrt(max(0.0, 1.0 - n[2] * n[2]))
    return wm.area0[j] + _contiguous_sum(face[0] * abs(n[0]), face[1] * abs(n[1]), face[2] * abs(n[2])) \
        + wm.side[j] * lateral


@kernel
def _damping(wm, j, speed, n):
    """D_j = rho Cd |u_rel| sum_k |n_k| J_kj."""
    J = wm.sweep
    rate = wm.rho_cd[j] * speed
    a0, a1, a2 = abs(n[0]), abs(n[1]), abs(n[2])
    return (rate * (a0 * J[j, 0, 0] + a1 * J[j, 1, 0] + a2 * J[j, 2, 0]),
            rate * (a0 * J[j, 0, 1] + a1 * J[j, 1, 1] + a2 * J[j, 2, 1]),
            rate * (a0 * J[j, 0, 2] + a1 * J[j, 1, 2] + a2 * J[j, 2, 2]))


@kernel
def drag_on_body(wm, j, u, v, w, R):
    """(F, tau, |u_rel|, A, D) on body j of the model: u the air velocity at it, v, w its velocity and world
    angular velocity (3-tuples), R its rotation (three row tuples). F, tau in the world frame, D about the body
    axes."""
    # u_rel = u - v
    rel = (u[0] - v[0], u[1] - v[1], u[2] - v[2])
    speed = _norm(rel)
    zero = (0.0, 0.0, 0.0)
    if not (wm.shaped[j] or wm.turning[j]):
        # F = 1/2 rho Cd area0 |u_rel| u_rel, no torque
        scale = wm.half_rho_cd[j] * wm.area0[j] * speed
        return (scale * rel[0], scale * rel[1], scale * rel[2]), zero, speed, wm.area0[j], zero
    inverse = max(speed, TINY_SPEED)
    # n = R^T u_rel / |u_rel|
    rel_body = _to_body(R, rel)
    n = (rel_body[0] / inverse, rel_body[1] / inverse, rel_body[2] / inverse)
    area = _area(wm, j, n)
    # F = 1/2 rho Cd A |u_rel| u_rel
    scale = wm.half_rho_cd[j] * area * speed
    force = (scale * rel[0], scale * rel[1], scale * rel[2])
    if not wm.turning[j]:
        return force, zero, speed, area, zero
    # r_cp = R (-CP_SHIFT H n)
    a = _row3(wm.arm, j)
    arm = _to_world(R, (a[0] * n[0], a[1] * n[1], a[2] * n[2]))
    damping = _damping(wm, j, speed, n)
    # tau_b = -D w_b - 1/2 rho Cd K |w_b| w_b;  tau = r_cp x F + R tau_b
    wb = _to_body(R, w)
    K = _row3(wm.spin_drag, j)
    turning = (-damping[0] * wb[0] - K[0] * abs(wb[0]) * wb[0], -damping[1] * wb[1] - K[1] * abs(wb[1]) * wb[1],
               -damping[2] * wb[2] - K[2] * abs(wb[2]) * wb[2])
    lever = cross3(arm, force)
    spun = _to_world(R, turning)
    return force, (lever[0] + spun[0], lever[1] + spun[1], lever[2] + spun[2]), speed, area, damping


@kernel
def _phi(z):
    """(1 - exp(-z)) / z, 1 - z / 2 below z = 1e-8."""
    if z < 1e-8:
        return 1.0 - 0.5 * z
    return -math.expm1(-z) / z


@kernel
def relaxation(wm, j, speed, area, damping, wb, h):
    """(phi, phi_w) of body j: kappa = rho Cd A |u_rel| / m, kappa_w = max_a (D_a + rho Cd K_a |w_a|) / I_a."""
    kappa = wm.rho_cd[j] * area * speed / wm.mass[j]
    kappa_w = 0.0
    for a in range(3):
        rate = (damping[a] + wm.spin_rate[j, a] * abs(wb[a])) / max(wm.moments[j, a], 1e-300)
        # (np.max: a NaN wins)
        kappa_w = rate if a == 0 or rate > kappa_w or rate != rate else kappa_w
    return _phi(kappa * h), _phi(kappa_w * h)


# ---- the stage: every body in the wind ---------------------------------------------------------------------------
# (the loops over the bodies are written out in each kernel: a helper that took the WindModel and called another
# would incref and decref each of its arrays at every call, ~0.3 us; the helpers below take numbers and arrays of
# the state only)

@kernel
def _state(y, R, i):
    """Body i's x, v, w (3-tuples) from its packed state row [x q v w], and its rotation as row tuples."""
    return (y[i, 0], y[i, 1], y[i, 2]), (y[i, 7], y[i, 8], y[i, 9]), (y[i, 10], y[i, 11], y[i, 12]), _rows(R, i)


@kernel
def _store_air(air, i, u, speed):
    """air[i] <- (u, |u - v|)."""
    air[i, 0], air[i, 1], air[i, 2], air[i, 3] = u[0], u[1], u[2], speed


@kernel
def _add(out, i, a):
    """out[i] += a."""
    out[i, 0], out[i, 1], out[i, 2] = out[i, 0] + a[0], out[i, 1] + a[1], out[i, 2] + a[2]


@kernel
def _add_and_scale(out, i, a, phi):
    """out[i] <- phi (out[i] + a)."""
    out[i, 0], out[i, 1], out[i, 2] = phi * (out[i, 0] + a[0]), phi * (out[i, 1] + a[1]), phi * (out[i, 2] + a[2])


@kernel
def wind_drag(wm, y, R, speeds, t, force, torque, air):
    """Force model. y (n,13) the bodies' packed states [x q v w], R (n,3,3) their rotations, speeds (m,) s_w(t):
    force, torque (n,3) += the drag on every body in the wind (the torque on those the wind can turn);
    air[i] (n,4) <- (u, |u - v|) at those bodies."""
    for j in range(wm.body.shape[0]):
        i = wm.body[j]
        x, v, w, Ri = _state(y, R, i)
        u = velocity_at(wm, x, speeds, t)
        F, tau, speed, _, _ = drag_on_body(wm, j, u, v, w, Ri)
        _store_air(air, i, u, speed)
        _add(force, i, F)
        if wm.turning[j]:
            _add(torque, i, tau)


@kernel
def wind_relax(wm, y, R, speeds, t, h, force, torque, air):
    """Procedural model over a step h: force[i] <- phi (force[i] + F), torque[i] <- phi_w (torque[i] + tau) for
    every body in the wind (phi = phi(kappa h), phi_w = phi(kappa_w h)); air as wind_drag."""
    for j in range(wm.body.shape[0]):
        i = wm.body[j]
        x, v, w, Ri = _state(y, R, i)
        u = velocity_at(wm, x, speeds, t)
        F, tau, speed, area, damping = drag_on_body(wm, j, u, v, w, Ri)
        _store_air(air, i, u, speed)
        phi, phi_w = relaxation(wm, j, speed, area, damping, _to_body(Ri, w), h)
        _add_and_scale(force, i, F, phi)
        _add_and_scale(torque, i, tau, phi_w)


@kernel
def wind_apply(wm, y, R, speeds, t, h, force, torque, air):
    """Each body in the wind by its own model (wm.model): wind_drag's arithmetic or wind_relax's."""
    for j in range(wm.body.shape[0]):
        i = wm.body[j]
        x, v, w, Ri = _state(y, R, i)
        u = velocity_at(wm, x, speeds, t)
        F, tau, speed, area, damping = drag_on_body(wm, j, u, v, w, Ri)
        _store_air(air, i, u, speed)
        if wm.model[j] == PROCEDURAL:
            phi, phi_w = relaxation(wm, j, speed, area, damping, _to_body(Ri, w), h)
            _add_and_scale(force, i, F, phi)
            _add_and_scale(torque, i, tau, phi_w)
        else:
            _add(force, i, F)
            if wm.turning[j]:
                _add(torque, i, tau)
