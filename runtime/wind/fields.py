"""Wind stage, fields: the air velocity u(x, t) of every wind of the scene, summed.

A uniform wind blows along its direction d everywhere: u = s(t) d.
A source wind blows radially from its point o, inside a cone of half-angle `spread` about d:

    r = x - o,  e = r / |r|,  theta = angle(e, d)
    u = s(t) f(|r|) c(theta) e
    f(r) = (r0 / max(r, CORE r0))^p      p = 0 (none), 1 (inverse), 2 (inverse_square); r0 the `distance`
    c(theta) = 1 - smoothstep(spread, spread (1 + CONE_EDGE), theta)    full inside the cone, a soft edge

Turbulence I adds gusts u' = I |u| G(x, t) (turbulence.py): they scale with the local wind, so still air stays
still. s(t) is the wind's `speed` expression, which may call envelope(...), mic(), noise(...), gust(...).
A source's point o and a wind's direction d may be expressions of t (a moving source, a turning fan): d is made
a unit vector at each instant, d = d(t) / |d(t)|.
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from isaac_ir import expr as E
from isaac_ir import ir

from .speed import SpeedOfTime
from .turbulence import GustField

# the falloff is held constant inside this fraction of the reference distance (no infinite speed at the source)
CORE = 0.1
# the cone's edge: the speed fades to 0 between `spread` and spread * (1 + CONE_EDGE)
CONE_EDGE = 0.25
FALLOFF_POWER = {"none": 0.0, "inverse": 1.0, "inverse_square": 2.0}


@dataclass
class WindFields:
    """Every wind of the scene (m of them), in arrays; speed expressions with their signal functions."""

    names: list  # (m,)
    is_source: np.ndarray  # (m,) bool: blows from a point
    origin: np.ndarray  # (m,3) source points (0 for uniform winds); at t = 0 for a moving one
    direction: np.ndarray  # (m,3) unit; at t = 0 for a turning one
    power: np.ndarray  # (m,) falloff exponent p
    reference: np.ndarray  # (m,) m, r0
    spread: np.ndarray  # (m,) rad
    turbulence: np.ndarray  # (m,) I
    speed: list  # (m,) expressions of t, m/s
    functions: list  # (m,) signal functions for E.evaluate
    gusts: list  # (m,) GustField or None
    paths: list = None  # (m,) (origin expression or None, direction expression or None): the winds that move
    speed_of_time: list = field(init=False)  # (m,) SpeedOfTime: `speed` compiled once

    def __post_init__(self):
        self.speed_of_time = [SpeedOfTime(s, f) for s, f in zip(self.speed, self.functions)]
        if self.paths is None:
            self.paths = [(None, None)] * len(self.names)
        self.moves = [o is not None or d is not None for o, d in self.paths]
        # the same numbers as Python floats and ranges, for the per-call path (no numpy scalar per use)
        self._every_wind = range(len(self.names))
        self._blows_from_a_point = [bool(b) for b in self.is_source]
        self._direction_floats = [tuple(map(float, d)) for d in self.direction]
        self._turbulence_floats = [float(i) for i in self.turbulence]
        self._rows: dict = {}  # k -> scratch of _rows_for

    def speeds(self, t: float) -> np.ndarray:
        """(m,) s(t) of every wind."""
        return np.array([s(t) for s in self.speed_of_time])

    def speed_at(self, w: int, t: float) -> float:
        """s(t) of wind w (m/s), from its compiled expression."""
        return self.speed_of_time[w](t)

    def pose_at(self, w: int, t: float) -> tuple:
        """(o (3,), d (3,) unit) of wind w at time t: its expressions where it moves, its constants elsewhere."""
        origin, direction = self.paths[w]
        o = self.origin[w] if origin is None else np.asarray(E.evaluate(origin, {"t": float(t)}), float)
        if direction is None:
            return o, self.direction[w]
        d = np.asarray(E.evaluate(direction, {"t": float(t)}), float)
        # d = d(t) / |d(t)|
        return o, d / np.sqrt(d @ d)

    def velocity(self, x: np.ndarray, t: float, only: int | None = None) -> np.ndarray:
        """(k,3) air velocity at points x (k,3): the sum of the winds (or wind `only`). A new array."""
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        if len(x) == 1:
            return np.array([self.velocity_at_one_point(x, t, only)])
        total = None
        for w in (self._every_wind if only is None else (only,)):
            s = self.speed_of_time[w](t)
            if s == 0.0:
                continue
            u = self._source(w, x, s, t) if self._blows_from_a_point[w] else self._uniform(w, x, s, t)
            # (the first wind is the total itself: 0 + u is u)
            total = u if total is None else total + u
        return np.zeros_like(x) if total is None else total

    def velocity_at_one_point(self, x: np.ndarray, t: float, only: int | None = None) -> tuple:
        """The air velocity at one point x (1,3), as three floats: velocity()'s sums, taken on floats."""
        total = None
        for w in (self._every_wind if only is None else (only,)):
            s = self.speed_of_time[w](t)
            if s == 0.0:
                continue
            if self._blows_from_a_point[w]:
                u = tuple(self._source(w, x, s, t)[0].tolist())
            else:
                u = self._uniform_at_one_point(w, x, s, t)
            total = u if total is None else (total[0] + u[0], total[1] + u[1], total[2] + u[2])
        return (0.0, 0.0, 0.0) if total is None else total

    def _uniform(self, w: int, x: np.ndarray, s: float, t: float) -> np.ndarray:
        """u = s d + I |s d| G(x, t) at points x (k,3)."""
        direction_rows, mean = self._rows_for(len(x))
        rows = direction_rows[w] if not self.moves[w] else np.repeat(self.pose_at(w, t)[1][None, :], len(x), 0)
        # u = s d at every point
        if self.gusts[w] is None:
            return np.multiply(rows, s)
        np.multiply(rows, s, mean)
        # u' = I |u| G(x, t), added to the mean
        _, scale = self._uniform_mean(w, s, t)
        u = self.gusts[w](x, t)
        np.multiply(u, scale, u)
        np.add(u, mean, u)
        return u

    def _rows_for(self, k: int) -> tuple:
        """Scratch for k points: the winds' directions, one row per point (m,k,3), and a (k,3) buffer."""
        rows = self._rows.get(k)
        if rows is None:
            if len(self._rows) >= 8:
                self._rows.clear()
            rows = self._rows[k] = (np.repeat(self.direction[:, None, :], k, axis=1), np.empty((k, 3)))
        return rows

    def _uniform_at_one_point(self, w: int, x: np.ndarray, s: float, t: float) -> tuple:
        """u = s d + I |s d| G(x, t) at one point x (1,3), three floats."""
        mean, scale = self._uniform_mean(w, s, t)
        if scale is None:
            return mean
        # u' = I |u| G(x, t), added to the mean
        g0, g1, g2 = self.gusts[w].at_one_point(x, t)
        return mean[0] + scale * g0, mean[1] + scale * g1, mean[2] + scale * g2

    def _uniform_mean(self, w: int, s: float, t: float) -> tuple:
        """A uniform wind's mean u = s d (three floats: the same at every point) and its gusts' scale I |u|
        (None without gusts)."""
        d0, d1, d2 = self._direction_floats[w] if not self.moves[w] else self.pose_at(w, t)[1].tolist()
        # u = s d
        mean = (s * d0, s * d1, s * d2)
        if self.gusts[w] is None:
            return mean, None
        # I |u|, |u| = sqrt(u . u) with its terms added in np.einsum's order (as a source wind's rows of |u|)
        size = math.sqrt(mean[0] * mean[0] + mean[2] * mean[2] + mean[1] * mean[1])
        return mean, self._turbulence_floats[w] * size

    def _source(self, w: int, x: np.ndarray, s: float, t: float) -> np.ndarray:
        """u = s f(|r|) c(theta) e + I |u| G(x, t)."""
        u = self._source_mean(w, x, s, t)
        if self.gusts[w] is not None:
            # u' = I |u| G(x, t)
            u += self.turbulence[w] * np.sqrt(np.einsum("ij,ij->i", u, u))[:, None] * self.gusts[w](x, t)
        return u

    def _source_mean(self, w: int, x: np.ndarray, s: float, t: float) -> np.ndarray:
        o, d = self.pose_at(w, t) if self.moves[w] else (self.origin[w], self.direction[w])
        r = x - o
        dist = np.sqrt(np.einsum("ij,ij->i", r, r))
        e = r / np.maximum(dist, 1e-300)[:, None]
        if not dist.all():
            e[dist == 0] = d  # at the source itself the air goes along d
        theta = np.arccos(np.clip(e @ d, -1.0, 1.0))
        r0 = self.reference[w]
        # f = (r0 / max(r, CORE r0))^p
        falloff = (r0 / np.maximum(dist, CORE * r0)) ** self.power[w]
        return (s * falloff * cone(theta, self.spread[w]))[:, None] * e


def cone(theta, spread: float):
    """c(theta) = 1 - smoothstep(spread, spread (1 + CONE_EDGE), theta): 1 inside the cone, 0 well outside."""
    edge = max(spread * CONE_EDGE, 1e-9)
    u = np.clip((np.asarray(theta) - spread) / edge, 0.0, 1.0)
    return 1.0 - u * u * (3.0 - 2.0 * u)


def falloff_law(distance, reference: float, falloff: str):
    """The stated law alone, for tests and docs: (r0 / max(r, CORE r0))^p."""
    return (reference / np.maximum(np.asarray(distance, float), CORE * reference)) ** FALLOFF_POWER[falloff]


def compile_fields(winds, functions: list, seed: int) -> WindFields:
    """Arrays of the scene's winds; functions[w] are wind w's signal functions (envelope, mic, noise, gust)."""
    m = len(winds)
    gusts = [GustField(_wind_seed(seed, wind.name), wind.gust_scale) if wind.turbulence > 0 else None
             for wind in winds]
    return WindFields(
        names=[wind.name for wind in winds],
        is_source=np.array([wind.type == "source" for wind in winds], dtype=bool),
        origin=np.array([_at_start(wind.origin) if wind.origin is not None else (0.0, 0.0, 0.0) for wind in winds],
                        float).reshape(m, 3),
        direction=np.array([_direction_at_start(wind.direction) for wind in winds], float).reshape(m, 3),
        power=np.array([FALLOFF_POWER[wind.falloff] for wind in winds]),
        reference=np.array([wind.reference_distance for wind in winds], float),
        spread=np.array([wind.spread for wind in winds], float),
        turbulence=np.array([wind.turbulence for wind in winds], float),
        speed=[wind.speed for wind in winds],
        functions=functions,
        gusts=gusts,
        paths=[(_path(wind.origin), _path(wind.direction)) for wind in winds],
    )


def _path(value):
    """The expression of a wind's point or direction that follows t, or None for a constant."""
    return value if isinstance(value, E.Expr) else None


def _at_start(value):
    """A constant, or an expression of t at t = 0."""
    return E.evaluate(value, {"t": 0.0}) if isinstance(value, E.Expr) else value


def _direction_at_start(direction):
    """A constant direction as lowered (already unit), or d(0) / |d(0)| of one that follows t."""
    if not isinstance(direction, E.Expr):
        return direction
    d = np.asarray(E.evaluate(direction, {"t": 0.0}), float)
    return d / np.sqrt(d @ d)


def _wind_seed(seed: int, name: str) -> int:
    """A wind's own seed: the scene's seed mixed with the wind's name (stable across runs: no hash())."""
    import zlib

    return (int(seed) * 2654435761 + zlib.crc32(name.encode("utf-8"))) & 0xFFFFFFFF


def wind_seed(scene: ir.Scene, wind: ir.Wind) -> int:
    return _wind_seed(scene.seed, wind.name)
