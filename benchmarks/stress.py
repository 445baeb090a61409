"""The stability stress suite: cases meant to break a solver, each with bounds stated before it runs.

Every case ends in one of:
    within bounds    finite, and every bound holds
    numerical error  the runtime stopped with its NumericalError (when, which body or constraint): acceptable
    OUT OF BOUNDS    finite, but a bound fails with no error raised                                  (a failure)
    SILENT NaN       a non-finite number in the state with no error raised                           (a failure)
    BUG              any other exception                                                             (a failure)
Bounds: `error` the largest active constraint error (Simulation.constraint_errors: m or rad) sampled every
~10 ms after `settle` seconds; `energy` the largest |E(t) - E(0)| / (m g extent) (report.json's yardstick),
for cases that conserve energy. The state is checked for NaN in every array (x, q, v, w) at every sample.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from . import common

LONG_STEPS = 1_000_000  # the pendulum's long run
QUICK_LONG_STEPS = 10_000


@dataclass
class Stress:
    name: str
    what: str
    text: str | None = None  # scene text, or
    scene: str | None = None  # scenes/NAME.isaac
    overrides: dict = field(default_factory=dict)
    plans: tuple = ("dynamics", "procedural")
    step: float | None = None  # None: the scene's
    until: float = 2.0
    quick_until: float | None = None
    error: float = math.inf  # bound on the constraint error after settle
    energy: float = math.inf  # bound on the relative energy drift
    settle: float = 0.0
    frames: float | None = None  # a frame rate low enough for the step (the plan cuts steps at one frame)

    def load(self):
        if self.text is not None:
            scene = common.load_source(self.text, f"{self.name}.isaac", self.overrides or None)
        else:
            scene = common.load(self.scene, self.overrides or None)
        return common.configured(scene, frame_rate=self.frames)

    def bounds(self) -> str:
        parts = []
        if math.isfinite(self.error):
            parts.append(f"error <= {self.error:g}" + (f" after {self.settle:g} s" if self.settle else ""))
        if math.isfinite(self.energy):
            parts.append(f"energy drift <= {self.energy:g}")
        return ", ".join(parts) or "finite"


HEADER = """scene {name} {{
  time 0 s .. {end} s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics {{ integrator rk4  step 1 ms }}
"""


def two_links(light: float, heavy: float) -> str:
    return HEADER.format(name="massratio", end=3) + f"""
  body link0 box {{ size (0.2, 0.02, 0.02) m  mass {light} kg  at (0.1, 0, 0)  collide off }}
  body link1 box {{ size (0.2, 0.02, 0.02) m  mass {heavy} kg  at (0.3, 0, 0)  collide off }}
  constraint anchor nail(link0 @ (-0.1, 0, 0), (0, 0, 0))
  constraint joint point(link0 @ (0.1, 0, 0), link1 @ (-0.1, 0, 0))
}}
"""


def alternating_chain(links: int, light: float, heavy: float) -> str:
    lines = [HEADER.format(name="alternating", end=3)]
    for i in range(links):
        mass = heavy if i % 2 else light
        lines.append(f"  body link{i} box {{ size (0.2, 0.02, 0.02) m  mass {mass} kg  at ({0.1 + 0.2 * i:.6g}, 0, 0)"
                     f"  collide off }}")
    lines.append("  constraint anchor nail(link0 @ (-0.1, 0, 0), (0, 0, 0))")
    for i in range(links - 1):
        lines.append(f"  constraint joint{i} point(link{i} @ (0.1, 0, 0), link{i + 1} @ (-0.1, 0, 0))")
    return "\n".join(lines) + "\n}\n"


REDUNDANT_WINDMILL = """
kind windmill3(blade, tower, pivot) =
    point(blade @ world pivot, tower @ world pivot) + orient(blade.z, x) + orient(blade.z, y) + orient(blade.x, z)
""" + HEADER.format(name="windmill3", end=4) + """
  body tower static box { size (0.2, 2, 0.2) m  at (0, -1.2, -0.2) }
  body blade box { size (2, 0.2, 0.05) m  mass 3 kg  at (0.5, 0, 0) }
  constraint joint windmill3(blade, tower, (0, 0, 0) m)
}
"""

# a parallelogram four-bar of hinges (point + two orientation rows each) swinging from 30 degrees: a closed
# loop, and 20 rows on 18 degrees of freedom with one left free, so 3 rows are redundant
FOUR_BAR = """
kind hinge(a, b, p) = point(a @ world p, b @ world p) + orient(a.z, b.x) + orient(a.z, b.y)
kind pivot(a, p) = nail(a @ world p) + orient(a.z, x) + orient(a.z, y)
""" + HEADER.format(name="fourbar", end=3) + """
  body crank box { size (0.02, 0.5, 0.02) m  mass 0.5 kg  at (0.125, -0.216506, 0)  orient (0, 0, 30)  collide off }
  body coupler box { size (1, 0.02, 0.02) m  mass 1 kg  at (0.75, -0.433013, 0)  collide off }
  body rocker box { size (0.02, 0.5, 0.02) m  mass 0.5 kg  at (1.125, -0.216506, 0)  orient (0, 0, 30)  collide off }
  constraint a pivot(crank, (0, 0, 0) m)
  constraint b hinge(crank, coupler, (0.25, -0.433013, 0) m)
  constraint c hinge(coupler, rocker, (1.25, -0.433013, 0) m)
  constraint d pivot(rocker, (1, 0, 0) m)
}
"""


def switching(count: int, gap: float) -> str:
    """`count` spheres in a row, all but the first held by nails until 0.5 s, when the nails end and the ball
    joints between neighbours start: 2 count - 2 constraints switch at one instant. With gap > 0 the joints'
    points start that far apart and the joints pull them shut (with the default, step-tied stabilization)."""
    arm = 0.05 - gap / 2
    lines = [HEADER.format(name="switching", end=2)]
    for i in range(count):
        lines.append(f"  body s{i} sphere {{ radius 4 cm  mass 0.1 kg  at ({0.1 * i:.6g}, 0, 0)  collide off }}")
    lines.append("  constraint root nail(s0)")  # at its centre: s0 stays put while the others are held
    for i in range(1, count):
        lines.append(f"  constraint hold{i} nail(s{i})  until 0.5 s")
        lines.append(f"  constraint join{i} point(s{i - 1} @ ({arm:.6g}, 0, 0), s{i} @ ({-arm:.6g}, 0, 0))  from 0.5 s")
    return "\n".join(lines) + "\n}\n"


def driven(kind: str) -> str:
    """A bob hung from a kinematic body driven hard: shaken at 30 Hz by 5 cm (1800 m/s2), spun at 20 rev/s with
    the bob on its rim (1600 m/s2 centripetal), or dragged through keyframe corners (velocity jumps of 2 m/s)."""
    paths = {"shaken": "at (0.05 m * sin(2 * pi * t / (1 / 30) s), 1 m, 0 m)",
             "spun": "at (0, 1, 0) m  orient euler(0, 0, (7200 * t / 1 s) deg)",
             "corners": "at keys linear { 0 s: (0, 1, 0) m, 0.5 s: (1, 1, 0) m, 1 s: (0, 1, 0) m, "
                        "1.5 s: (1, 1, 0) m, 2 s: (0, 1, 0) m }"}
    arm = "(0.1, 0, 0)" if kind == "spun" else "(0, 0, 0)"
    start = "(0.1, 0.5, 0)" if kind == "spun" else "(0, 0.5, 0)"
    return HEADER.format(name=kind, end=2) + f"""
  body hand kinematic sphere {{ radius 2 cm  {paths[kind]} }}
  body bob sphere {{ radius 5 cm  mass 1 kg  at {start} m  collide off }}
  constraint hang point(bob @ (0, 0.5, 0), hand @ {arm})
}}
"""


def euler_chain() -> str:
    """scenes/chain.isaac with semi-implicit Euler at 1 ms (it ran away at 2.8 s before the Euler projection took
    its correction as an impulse: dynamics/projection.py)."""
    text = (common.SCENES / "chain.isaac").read_text()
    solver = "integrator rk4  step 0.5 ms"
    assert solver in text, "scenes/chain.isaac's solver line changed: update benchmarks/stress.py euler_chain"
    return text.replace(solver, "integrator euler  step 1 ms")


def cases(long_steps: int) -> list:
    out = []
    for name in ("pendulum", "windmill", "chain"):
        for h, label in ((1 / 60, "60"), (1 / 30, "30")):
            out.append(Stress(f"large step {name} 1/{label} s", f"scenes/{name}.isaac at h = 1/{label} s", scene=name,
                              step=h, until=4.0, error=1e-2, energy=0.1, frames=30.0))
    # bounds are for stability (the joint holds, energy stays put), the same for both plans; the numbers
    # themselves are in the table
    out += [
        Stress("mass ratio 1:100", "2 links, 0.1 kg holding 10 kg", two_links(0.1, 10.0), error=1e-3, energy=1e-2),
        Stress("mass ratio 1:10,000", "2 links, 0.01 kg holding 100 kg", two_links(0.01, 100.0), error=1e-3,
               energy=1e-2),
        Stress("mass ratio 1:10,000 alternating", "10 links alternating 1 kg and 0.1 g",
               alternating_chain(10, 1.0, 1e-4), error=1e-3, energy=1e-2),
        Stress("semi-implicit Euler chain", "scenes/chain.isaac, Euler 1 ms, 10 s", euler_chain(),
               plans=("dynamics",), until=10.0, quick_until=4.0, error=1e-3, energy=1e-2),
        Stress("1000-link chain", "scenes/chain.isaac --set links=1000, 1 ms", scene="chain",
               overrides={"links": "1000"}, step=1e-3, until=0.1, quick_until=0.01, error=1e-3, energy=1e-2),
        Stress("redundant: windmill + third orientation row", "3 orientation rows for 2 DOF", REDUNDANT_WINDMILL,
               until=4.0, error=1e-4, energy=1e-2),
        Stress("redundant: closed loop (four-bar of hinges)", "20 rows, 18 DOF, 1 free", FOUR_BAR, until=3.0,
               error=1e-4, energy=1e-2),
        Stress("99 constraints switching at once", "49 nails end, 49 closed joints start at 0.5 s",
               switching(50, 0.0), until=2.0, error=1e-3),
        Stress("99 constraints switching at once, 1 cm apart", "the same, each joint's points 1 cm apart",
               switching(50, 0.01), until=2.0, error=1e-3, settle=1.0),
        Stress("kinematic: shaken at 30 Hz", "hand 5 cm at 30 Hz (180 g)", driven("shaken"), error=1e-2),
        Stress("kinematic: spun at 20 rev/s", "bob on the rim of a spinning hand", driven("spun"), error=1e-2),
        Stress("kinematic: keyframe corners", "velocity jumps of 2 m/s", driven("corners"), error=1e-2),
        Stress(f"pendulum, {long_steps:.0e} steps", "scenes/pendulum.isaac, RK4 1 ms", scene="pendulum",
               plans=("dynamics",), step=1e-3, until=long_steps * 1e-3, error=1e-6, energy=1e-4),
    ]
    return out


class Watch:
    """Observer: every `every` steps the constraint error, energy and finiteness of the whole state."""

    def __init__(self, sim, case: Stress, every: int):
        from isaac_runtime.core.build import energy_scale

        self.case, self.every, self.calls = case, every, 0
        self.e0, self.scale = sim.energy(), energy_scale(sim.plan)
        self.error = self.energy = 0.0
        self.nan_at = None

    def __call__(self, sim, h) -> None:
        self.calls += 1
        if self.calls % self.every == 0:
            self.look(sim)

    def look(self, sim) -> None:
        s = sim.state
        if self.nan_at is None and not all(np.isfinite(a).all() for a in (s.x, s.q, s.v, s.w)):
            self.nan_at = s.t
        error, _ = sim.constraint_errors()
        if s.t >= self.case.settle - 1e-12:
            self.error = max(self.error, error) if math.isfinite(error) else math.inf
        self.energy = max(self.energy, abs(sim.energy() - self.e0) / self.scale)


def run_case(case: Stress, plan: str, quick: bool) -> dict:
    from isaac_runtime.simulation import NumericalError, Simulation

    until = case.quick_until if (quick and case.quick_until) else case.until
    row = {"case": case.name, "what": case.what, "plan": plan, "step": math.nan, "until": until, "steps": 0,
           "reached": 0.0, "wall_s": math.nan, "outcome": "BUG", "error": math.nan, "energy_drift": math.nan,
           "bounds": case.bounds(), "redundant_rows_seen": "", "message": ""}
    try:
        sim = Simulation(common.plan_for(case.load(), plan, case.step, until))
        row["step"] = sim.plan.step
        if case.step is not None and abs(sim.plan.step - case.step) > 1e-12:
            raise AssertionError(f"the plan took a step of {sim.plan.step:g} s, not {case.step:g} s")
        watch = Watch(sim, case, max(1, int(round(0.01 / sim.plan.step))))
        sim.observers.append(watch)
        begin = time.perf_counter()
        try:
            sim.advance_to(sim.plan.start + until)
            watch.look(sim)
            row["outcome"] = verdict(case, watch)
        except NumericalError as error:
            row["outcome"], row["message"] = "numerical error", str(error)
        row["wall_s"] = time.perf_counter() - begin
        row.update(steps=sim.state.steps, reached=sim.state.t - sim.plan.start, error=watch.error,
                   energy_drift=watch.energy, redundant_rows_seen=sim.rank_deficient())
        if watch.nan_at is not None and row["outcome"] != "numerical error":
            row["outcome"], row["message"] = "SILENT NaN", f"non-finite state at t = {watch.nan_at:g} s"
    except Exception as error:  # noqa: BLE001
        row["message"] = f"{type(error).__name__}: {error}"
    return row


def verdict(case: Stress, watch: Watch) -> str:
    if watch.nan_at is not None:
        return "SILENT NaN"
    energy_ok = watch.energy <= case.energy or not math.isfinite(case.energy)
    return "within bounds" if watch.error <= case.error and energy_ok else "OUT OF BOUNDS"


PASSING = ("within bounds", "numerical error")
KEYS = ["case", "plan", "outcome", "step", "until", "reached", "steps", "wall_s", "error", "energy_drift", "bounds",
        "redundant_rows_seen", "message", "what"]


def run(quick: bool = False, out: Path | None = None, long_steps: int | None = None) -> dict:
    long_steps = long_steps or (QUICK_LONG_STEPS if quick else LONG_STEPS)
    rows = []
    for case in cases(long_steps):
        for plan in case.plans:
            rows.append(run_case(case, plan, quick))
            r = rows[-1]
            common.log(f"  {r['case']:<48}{r['plan']:<11}{r['outcome']:<16}error {r['error']:.2e}  "
                       f"energy {r['energy_drift']:.2e}  {r['wall_s']:.1f} s  {r['message'][:90]}")
    result = {"rows": rows, "all_pass": all(r["outcome"] in PASSING for r in rows)}
    if out is not None:
        common.write_csv(out / "stress.csv", rows, KEYS)
    return result
