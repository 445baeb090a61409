"""Plan specialization: a scene pays only for what it uses.

1. The pendulum three ways: bare (one body, one nail), as shipped (scenes/pendulum.isaac: a camera, a light, a
   material) and with unused declarations (more materials, a sound whose trigger never fires, a wind no body
   feels, cameras, lights, an unused kind). Each variant in a fresh interpreter: the time of every stage
   (parse, load = parse + expand + lower + check, plan, first step, per step), the plan's stages on and off, and
   which optional modules got imported. Then side by side in this process: the bare step loop, and the whole
   in-process run (simulate, with its audio stage when the plan has one) of one simulated second.
2. The import cost of the command: `isaac run` on the pendulum under `python -X importtime`, the whole command's
   wall time, the interpreter's own start-up for reference, and whether soundfile, fcl, matplotlib or the
   audio, collision and wind stages were imported (they must not be). Beside it the whole processes the issues
   check: `isaac run scenes/pendulum.isaac` (cached core) and 4 s of `isaac live scenes/mobile.isaac` with its
   breath from scenes/assets/breath.wav (4 s paced, the rest start-up and outputs).
Writes specialization.csv and imports.csv.
"""
from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

from . import common

BARE = """scene pendulum {
  time 0 s .. 10 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  body bob sphere { radius 5 cm  mass 1 kg  at (0.866025403784, 0.5, 0) }
  constraint hang nail(bob @ (-0.866025403784, 0.5, 0), (0, 1, 0))
}
"""

UNUSED = """kind hinge(a, b, p) = point(a @ world p, b @ world p) + orient(a.z, b.x) + orient(a.z, b.y)
scene pendulum {
  time 0 s .. 10 s
  frames 100 Hz
  gravity (0, -9.81, 0) m/s2
  solver dynamics { integrator rk4  step 1 ms }
  camera main { at (0, 0.5, 3)  look (0, 0.5, 0)  fov 40 deg }
  camera side { at (3, 0.5, 0)  look (0, 0.5, 0) }
  light key distant { from (-1, 2, 3)  to (0, 0, 0)  intensity 0.8 }
  light fill point { at (2, 3, 1)  color (1, 0.9, 0.8) }
  material steel { density 7800 kg/m3  friction 0.4  restitution 0.6  young 200 GPa  loss 0.001 }
  material wood { density 600 kg/m3  friction 0.6  rayleigh (0.5, 1e-6) }
  material brass { density 8500 kg/m3 }
  wind breeze { direction (1, 0, 0)  speed 3 m/s  turbulence 0.2 }
  body bob sphere { radius 5 cm  mass 1 kg  at (0.866025403784, 0.5, 0)  material steel  collide off }
  sound ding on collide(bob) { play sine(440 Hz) * decay(0.5 s)  gain -6 dB }
  constraint hang nail(bob @ (-0.866025403784, 0.5, 0), (0, 1, 0))
}
"""

RUN_UNTIL = 1.0  # simulated seconds of the in-process `isaac run` timed side by side
ROUNDS = 5  # rounds of the side-by-side timing, the best of each variant kept
OPTIONAL = ("soundfile", "fcl", "matplotlib", "isaac_runtime.audio", "isaac_runtime.collide", "isaac_runtime.wind",
            "scipy.sparse", "tqdm")

# run in a fresh interpreter: stage times and imports of one variant (JSON on stdout)
PROBE = r"""
import json, sys, time
t0 = time.perf_counter()
from isaac_lang.syntax import parse_text
from isaac_ir.diagnostics import Reporter
from isaac_lang.load import load_text
from isaac_runtime.plan import compile_plan, PlanOptions
from isaac.api import Simulation
t_import = time.perf_counter() - t0
text = sys.stdin.read()
best = lambda f: min((lambda s: (f(), time.perf_counter() - s)[1])(time.perf_counter()) for _ in range(3))
t_parse = best(lambda: parse_text(text, "p.isaac", Reporter()))
scene = load_text(text, "p.isaac").scene
t_load = best(lambda: load_text(text, "p.isaac"))
t_plan = best(lambda: compile_plan(scene, PlanOptions()))
plan = compile_plan(scene, PlanOptions())
sim = Simulation(plan)
s = time.perf_counter(); sim.step(); t_first = time.perf_counter() - s
per = []
for _ in range(3):
    s = time.perf_counter(); sim.advance_to(sim.state.t + 0.1); per.append((time.perf_counter() - s) / 100)
mods = [m for m in %r if m in sys.modules]
print(json.dumps({"import_s": t_import, "parse_s": t_parse, "load_s": t_load, "plan_s": t_plan, "first_step_s": t_first,
                  "step_s": min(per), "stages_on": [k for k, v in plan.stages().items() if v],
                  "stages_off": [k for k, v in plan.stages().items() if not v], "optional_imported": mods}))
"""


def variants() -> list:
    return [("bare", BARE), ("as shipped", (common.SCENES / "pendulum.isaac").read_text()), ("unused declarations", UNUSED)]


def _env() -> dict:
    env = dict(os.environ)
    env["PYTHONPATH"] = os.pathsep.join(filter(None, [str(common.REPO), env.get("PYTHONPATH", "")]))
    return env


def fresh(text: str) -> dict:
    done = subprocess.run([sys.executable, "-c", PROBE % (OPTIONAL,)], input=text, capture_output=True, text=True,
                          env=_env(), cwd=common.SCENES, timeout=600)
    if done.returncode != 0:
        return {"error": done.stderr.strip().splitlines()[-1] if done.stderr.strip() else f"exit {done.returncode}"}
    return json.loads(done.stdout.strip().splitlines()[-1])


def side_by_side(texts: list, window: float, run_until: float) -> list:
    """Per variant, measured in this process alternating between variants, best of ROUNDS: the time per step of
    the bare step loop (Simulation.step), and the whole in-process `isaac run` (simulate: plan, the audio stage
    when there is one, recording every frame) for `run_until` simulated seconds."""
    from isaac_runtime.run import RunOptions, simulate
    from isaac.api import Simulation

    scenes = [common.load_source(t, "p.isaac") for _, t in texts]
    sims = [Simulation(common.plan_for(scene, "dynamics")) for scene in scenes]
    step = [math.inf] * len(sims)
    run = [math.inf] * len(sims)
    for _ in range(ROUNDS):
        for k, sim in enumerate(sims):
            steps, begin = 0, time.perf_counter()
            while steps < 3 or time.perf_counter() - begin < window:
                sim.step()
                steps += 1
            step[k] = min(step[k], (time.perf_counter() - begin) / steps)
            begin = time.perf_counter()
            simulate(scenes[k], RunOptions(until=run_until))
            run[k] = min(run[k], time.perf_counter() - begin)
    return list(zip(step, run))


LIVE_UNTIL = 4.0  # s of `isaac live scenes/mobile.isaac --mic scenes/assets/breath.wav` (issue 16's check)


def command_imports(out_dir: Path) -> tuple:
    """(summary row, top imports) of `isaac run scenes/pendulum.isaac` under -X importtime."""
    args = ["-m", "isaac.cli", "run", str(common.SCENES / "pendulum.isaac"), "--until", "0.01", "--quiet",
            "--no-viewer", "--out", str(out_dir)]
    begin = time.perf_counter()
    done = subprocess.run([sys.executable, "-X", "importtime", *args], capture_output=True, text=True, env=_env(),
                          timeout=600)
    traced = time.perf_counter() - begin
    imports = _parse_importtime(done.stderr)
    wall = min(_wall([sys.executable, *args]) for _ in range(3))
    bare = min(_wall([sys.executable, "-c", "pass"]) for _ in range(3))
    # issue 13's and issue 16's checks, whole processes: the shipped pendulum's run, and 4 s of the mobile live
    pendulum = min(_wall([sys.executable, "-m", "isaac.cli", "run", str(common.SCENES / "pendulum.isaac"),
                          "--quiet", "--out", str(out_dir / "pendulum")]) for _ in range(3))
    live = min(_wall([sys.executable, "-m", "isaac.cli", "live", str(common.SCENES / "mobile.isaac"), "--mic",
                      str(common.SCENES / "assets" / "breath.wav"), "--until", str(LIVE_UNTIL), "--port", "0",
                      "--no-browser", "--no-viewer", "--quiet", "--out", str(out_dir / "live")]) for _ in range(2))
    names = {i["module"] for i in imports}
    packages: dict = {}
    for i in imports:  # own import time summed per top-level package
        package = i["module"].split(".")[0]
        packages[package] = packages.get(package, 0) + i["self_us"]
    top = sorted(({"module": k, "cumulative_us": v} for k, v in packages.items()), key=lambda i: -i["cumulative_us"])
    row = {"command": "isaac run scenes/pendulum.isaac --until 0.01", "exit": done.returncode, "wall_s": wall,
           "python_startup_s": bare, "imports_s": sum(packages.values()) / 1e6, "run_pendulum_s": pendulum,
           "live_mobile_s": live, "live_until_s": LIVE_UNTIL,
           "modules": len(imports), "traced_wall_s": traced,
           **{f"imports {m}": m in names for m in OPTIONAL}}
    return row, top[:12]


def _wall(cmd) -> float:
    begin = time.perf_counter()
    subprocess.run(cmd, capture_output=True, env=_env(), timeout=600)
    return time.perf_counter() - begin


def _parse_importtime(stderr: str) -> list:
    """`import time: self [us] | cumulative | imported package` lines; nesting is two spaces per level."""
    out = []
    for line in stderr.splitlines():
        if not line.startswith("import time:") or "imported package" in line:
            continue
        self_us, cumulative, name = line[len("import time:"):].split("|", 2)
        name = name[1:] if name.startswith(" ") else name
        out.append({"module": name.strip(), "depth": (len(name) - len(name.lstrip())) // 2,
                    "self_us": int(self_us), "cumulative_us": int(cumulative)})
    return out


def run(quick: bool = False, out: Path | None = None) -> dict:
    rows = []
    texts = variants()
    for label, text in texts:
        info = fresh(text)
        info = {"variant": label, **{k: (", ".join(v) if isinstance(v, list) else v) for k, v in info.items()}}
        rows.append(info)
        common.log(f"  {label:<22}" + "  ".join(f"{k}={v:.4g}" if isinstance(v, float) else f"{k}={v}"
                                              for k, v in info.items() if k != "variant"))
    for row, (step, whole) in zip(rows, side_by_side(texts, 0.2 if quick else 1.0, RUN_UNTIL)):
        row["step_s_side_by_side"], row[f"run_{RUN_UNTIL:g}s_side_by_side"] = step, whole
    with tempfile.TemporaryDirectory() as tmp:
        command, top = command_imports(Path(tmp))
    common.log(f"  command: {command['wall_s']:.2f} s wall (python alone {command['python_startup_s']:.2f} s; "
               f"pendulum run {command['run_pendulum_s']:.2f} s, {LIVE_UNTIL:g} s live "
               f"{command['live_mobile_s']:.2f} s), "
               f"imports {command['imports_s']:.2f} s; optional imported: "
               f"{[k[8:] for k, v in command.items() if k.startswith('imports ') and v]}")
    result = {"variants": rows, "command": command, "top_imports": top}
    if out is not None:
        common.write_csv(out / "specialization.csv", rows)
        common.write_csv(out / "imports.csv", [command] + [{"command": f"  package {t['module']}", "imports_s":
                                                             t["cumulative_us"] / 1e6} for t in top])
    return result
