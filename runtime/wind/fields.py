"""Wind stage, fields: the air velocity u(x, t) of every wind of the scene, summed.

A uniform wind blows along its direction d everywhere: u = s(t) d.
A source wind blows radially from its point o, inside a cone of half-angle `spread` about d:

    r = x - o,  e = r / |r|,  theta = angle(e, d)
    u = s(t) f(|r|) c(theta) e
    f(r) = (r0 / max(r, CORE r0))^p      p = 0 (none), 1 (inverse), 2 (inverse_square); r0 the `distance`
    c(theta) = 1 - smoothstep(spread, spread (1 + CONE_EDGE), theta)    full inside the cone, a soft edge

Turbulence I adds gusts u' = I |u| G(x, t) (turbulence.py): they scale with the local wind, so still air stays
still. s(t) is the wind's `speed` expression, which may call envelope(...), mic(), noise(...), gust(...).
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from isaac_lang import ir

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
    origin: np.ndarray  # (m,3) source points (0 for uniform winds)
    direction: np.ndarray  # (m,3) unit
    power: np.ndarray  # (m,) falloff exponent p
    reference: np.ndarray  # (m,) m, r0
    spread: np.ndarray  # (m,) rad
    turbulence: np.ndarray  # (m,) I
    speed: list  # (m,) expressions of t, m/s
    functions: list  # (m,) signal functions for E.evaluate
    gusts: list  # (m,) GustField or None
    speed_of_time: list = field(init=False)  # (m,) SpeedOfTime: `speed` compiled once

    def __post_init__(self):
        self.speed_of_time = [SpeedOfTime(s, f) for s, f in zip(self.speed, self.functions)]

    def speeds(self, t: float) -> np.ndarray:
        """(m,) s(t) of every wind."""
        return np.array([s(t) for s in self.speed_of_time])

    def speed_at(self, w: int, t: float) -> float:
        """s(t) of wind w (m/s), from its compiled expression."""
        return self.speed_of_time[w](t)

    def velocity(self, x: np.ndarray, t: float, only: int | None = None) -> np.ndarray:
        """(k,3) air velocity at points x (k,3): the sum of the winds (or wind `only`)."""
        x = np.asarray(x, dtype=float).reshape(-1, 3)
        total = None
        for w in (range(len(self.names)) if only is None else (only,)):
            s = self.speed_of_time[w](t)
            if s == 0.0:
                continue
            u = self._mean(w, x, s)
            if self.gusts[w] is not None:
                # u' = I |u| G(x, t)
                u += self.turbulence[w] * np.sqrt(np.einsum("ij,ij->i", u, u))[:, None] * self.gusts[w](x, t)
            # (the first wind is the total itself: 0 + u is u)
            total = u if total is None else total + u
        return np.zeros_like(x) if total is None else total

    def _mean(self, w: int, x: np.ndarray, s: float) -> np.ndarray:
        d = self.direction[w]
        if not self.is_source[w]:
            # u = s d at every point
            u = np.empty(x.shape)
            u[:] = s * d
            return u
        r = x - self.origin[w]
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
        origin=np.array([wind.origin if wind.origin is not None else (0.0, 0.0, 0.0) for wind in winds],
                        float).reshape(m, 3),
        direction=np.array([wind.direction for wind in winds], float).reshape(m, 3),
        power=np.array([FALLOFF_POWER[wind.falloff] for wind in winds]),
        reference=np.array([wind.reference_distance for wind in winds], float),
        spread=np.array([wind.spread for wind in winds], float),
        turbulence=np.array([wind.turbulence for wind in winds], float),
        speed=[wind.speed for wind in winds],
        functions=functions,
        gusts=gusts,
    )


def _wind_seed(seed: int, name: str) -> int:
    """A wind's own seed: the scene's seed mixed with the wind's name (stable across runs: no hash())."""
    import zlib

    return (int(seed) * 2654435761 + zlib.crc32(name.encode("utf-8"))) & 0xFFFFFFFF


def wind_seed(scene: ir.Scene, wind: ir.Wind) -> int:
    return _wind_seed(scene.seed, wind.name)
