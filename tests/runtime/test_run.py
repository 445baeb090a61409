"""`isaac run` and `isaac plan` against the output contract of docs/design/architecture.md, and the embedding API."""
from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from isaac.cli import main
from isaac_runtime.outputs.outputset import MANIFEST
from isaac.api import Simulation

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def test_run_writes_the_contracted_files(tmp_path, capsys):
    out = tmp_path / "out"
    code = main(["run", str(SCENES / "selfassembly.isaac"), "--out", str(out), "--until", "1.5"])
    assert code == 0
    assert sorted(p.name for p in out.iterdir()) == [MANIFEST, "events.json", "ir.json", "report.json",
                                                        "trajectory.npz", "viewer.html"]
    with np.load(out / "trajectory.npz", allow_pickle=False) as data:
        T = len(data["time"])
        assert list(data["bodies"]) == ["a", "b"]
        assert data["position"].shape == (T, 2, 3) and data["orientation"].shape == (T, 2, 4)
        assert data["linear_velocity"].shape == (T, 2, 3) and data["angular_velocity"].shape == (T, 2, 3)
        assert data["constraint_error"].shape == (T,) and data["energy"].shape == (T,)
        assert data["time"][-1] == pytest.approx(1.5)
        assert np.allclose(np.diff(data["time"]), 0.01)
    report = json.loads((out / "report.json").read_text())
    for key in ("steps", "wall_time", "solver", "stages_run", "stages_skipped", "max_constraint_error",
                "energy_drift", "warnings", "step"):
        assert key in report
    # its spheres are free (and may touch) until the joint switches on
    assert "constraints" in report["stages_run"] and "collisions" in report["stages_run"]
    assert json.loads((out / "events.json").read_text()) == []
    assert json.loads((out / "ir.json").read_text())["schema"] == "isaac-ir/1"
    assert not [p for p in out.iterdir() if p.name.startswith(".") and p.name != MANIFEST]  # no temporaries
    assert not [p for p in out.parent.iterdir() if p.name.startswith(".")]  # beside it neither


def test_run_options_override_the_scene(tmp_path):
    out = tmp_path / "o"
    assert main(["run", str(SCENES / "pendulum.isaac"), "--out", str(out), "--until", "0.2", "--step", "0.002",
                 "--solver", "dynamics", "--set", "theta0=30deg"]) == 0
    report = json.loads((out / "report.json").read_text())
    assert report["step"] == 0.002 and report["steps"] == 100
    ir = json.loads((out / "ir.json").read_text())
    assert ir["bodies"][0]["position"][0] == pytest.approx(np.sin(np.radians(30)))


# a stabilization far too stiff for its step: without the error control (which would take every step in 16
# substeps, tests/runtime/test_error_control.py) it blows up within the first steps
BLOWS_UP = """scene bad {
  time 0 s .. 5 s
  solver dynamics { step 20 ms  stabilize 200 Hz  tolerance 0 }
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) }
  constraint hang nail(bob @ (-0.9, 0, 0), (0, 0, 0))
}
"""


def test_blow_up_exits_2_with_a_message_and_keeps_the_trajectory(tmp_path, capsys):
    scene = tmp_path / "bad.isaac"
    scene.write_text(BLOWS_UP)
    out = tmp_path / "out"
    assert main(["run", str(scene), "--out", str(out)]) == 2
    err = capsys.readouterr().err
    assert "numerical blow-up at t =" in err and "Traceback" not in err
    assert (out / "trajectory.npz").exists()


def test_plan_lists_stages(capsys):
    assert main(["plan", str(SCENES / "pendulum.isaac")]) == 0
    text = capsys.readouterr().out
    assert "on  constraints" in text and "off collisions" in text and "off audio" in text
    assert "rk4" in text


def test_readme_command_runs_the_pendulum_without_sound_or_meshes(tmp_path):
    # the command a newcomer runs; a scene without sound never imports soundfile, without meshes never fcl, and
    # a 3-row system (a dense solve) never scipy.sparse
    code = ("import sys; from isaac.cli import main; rc = main(['run', sys.argv[1], '--out', sys.argv[2], "
            "'--until', '0.1']); assert 'soundfile' not in sys.modules and 'fcl' not in sys.modules; "
            "assert 'scipy.sparse' not in sys.modules, 'scipy.sparse imported'; sys.exit(rc)")
    done = subprocess.run([sys.executable, "-c", code, str(SCENES / "pendulum.isaac"), str(tmp_path)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr


def test_api_steps_and_takes_live_inputs():
    sim = Simulation.from_text("""
let length = 1 m
scene api {
  time 0 s .. 2 s
  gravity (0, -9.81, 0)
  body hand kinematic sphere { radius 2 cm  at (0, 1, 0) }
  body bob sphere { radius 5 cm  mass 1 kg  at (length, 1, 0) }
  constraint string point(bob @ (-length, 0, 0), hand @ (0, 0, 0))
}""")
    sim.advance_to(0.1)
    assert sim.state.t == pytest.approx(0.1)
    bob = sim.body("bob")
    # drive the kinematic hand from outside: the bob follows (the string keeps its length)
    sim.set_pose("hand", (0.5, 1.5, 0))
    sim.advance_to(0.6)
    distance = np.linalg.norm(sim.state.x[bob] - sim.state.x[sim.body("hand")])
    assert distance == pytest.approx(1.0, abs=1e-4)
    # a parameter changed mid-run re-plans the scene and keeps the state of the bodies
    x_before = sim.state.x[bob].copy()
    sim.set_parameter("length", "2 m")
    assert sim.state.t == pytest.approx(0.6)
    assert np.allclose(sim.state.x[bob], x_before)
    with pytest.raises(ValueError):
        sim.set_pose("bob", (0, 0, 0))


def test_the_compiled_step_loads_in_the_background_from_the_cache_only():
    # a warm cache (this process has run the step): a fresh process loads those overloads in a thread, and its
    # first call finds them there; a dispatcher that nothing cached starts no thread
    Simulation.from_file(SCENES / "pendulum.isaac", until=0.01).advance_to(0.01)
    code = """
import threading
import numba
from isaac_runtime.core.jit import OPTIONS, _cached_signatures, load_in_background
from isaac_runtime.dynamics.integrate import run
cached = _cached_signatures(run)
assert cached, "the step is cached"
load_in_background(run)
for thread in threading.enumerate():
    if thread.name == "isaac-load-core":
        thread.join()
assert set(map(tuple, run.signatures)) == set(map(tuple, cached))
fresh = numba.njit(**OPTIONS)(lambda x: x + 1)  # (not cached: nothing to load)
before = threading.active_count()
load_in_background(fresh)
assert threading.active_count() == before and not fresh.signatures
"""
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr



def test_a_cached_run_loads_the_core_without_numbas_implementations_and_moves_as_after_a_refresh(tmp_path):
    # numba's refresh (every typing and lowering implementation it has: a third of a cached run's start) is for
    # compiling; a fresh process that loads the cached step never makes it, and its motion is that of a process
    # that made it first. A scene with contacts and one with a wind: every entry point is loaded, none compiled.
    for scene in ("cradle", "mobile"):
        Simulation.from_file(SCENES / f"{scene}.isaac", until=0.2).advance_to(0.2)  # (the cache warm)
    code = """
import sys
from pathlib import Path
import numpy as np
how, out = sys.argv[1], sys.argv[2]
if how == "refresh":
    from numba.core.registry import cpu_target
    cpu_target.target_context.refresh()
from isaac.api import Simulation
for scene in sys.argv[3:]:
    sim = Simulation.from_file(scene, until=0.2)
    sim.advance_to(0.2)
    np.save(f"{out}/{how}-{Path(scene).stem}.npy", sim.state.y)
assert ("numba.cpython.unicode" in sys.modules) == (how == "refresh"), "numba's implementations"
# (importlib.metadata, which imports email, runs its code only when numba reads its extensions' entry points)
assert ("email" in sys.modules) == (how == "refresh"), "the extensions' entry points"
"""
    scenes = [str(SCENES / f"{scene}.isaac") for scene in ("cradle", "mobile")]
    for how in ("refresh", "cached"):
        done = subprocess.run([sys.executable, "-c", code, how, str(tmp_path), *scenes], capture_output=True,
                              text=True)
        assert done.returncode == 0, done.stderr
        assert "compiling" not in done.stderr
    for scene in ("cradle", "mobile"):
        assert np.array_equal(np.load(tmp_path / f"refresh-{scene}.npy"), np.load(tmp_path / f"cached-{scene}.npy"))


def test_an_entry_point_initialises_numbas_extensions_only_when_it_compiles(tmp_path):
    # numba initialises the extensions installed beside it before a dispatcher's first call; an entry point does
    # so only before it compiles: a process that compiles it initialises them, one that loads it from the cache not
    (tmp_path / "one_more.py").write_text("from isaac_runtime.core.jit import entry\n\n\n@entry\n"
                                          "def one_more(x):\n    return x + 1\n")
    code = """
import sys
sys.path.insert(0, sys.argv[1])
from one_more import one_more
import numba.core.entrypoints
assert one_more(41) == 42
print(numba.core.entrypoints._already_initialized, "email" in sys.modules)
"""
    lists = set(jit_symbols().glob("isaac-symbols-*.txt"))
    said = [subprocess.run([sys.executable, "-c", code, str(tmp_path)], capture_output=True, text=True)
            for _ in range(2)]
    for path in set(jit_symbols().glob("isaac-symbols-*.txt")) - lists:
        path.unlink()  # (one_more's, beside the core's)
    assert [done.returncode for done in said] == [0, 0], said[0].stderr + said[1].stderr
    assert [done.stdout.split() for done in said] == [["True", "True"], ["False", "False"]]


def test_a_cached_library_is_rebuilt_from_its_symbol_list_and_parses_its_linking_module_only_when_linked(
        tmp_path):
    # numba parses the cached step's module for linking (about 1 MB of LLVM bitcode) only to learn the symbols it
    # defines; the core keeps their names in a list beside the cache. A fresh process without the list parses the
    # module once and writes the list; the next one reads the list and parses nothing, and the module can still
    # be had (linking), with the same functions the list names. Both move the pendulum alike.
    Simulation.from_file(SCENES / "pendulum.isaac", until=0.01).advance_to(0.01)  # (the cache warm)
    code = """
import sys
import llvmlite.binding as ll
import numpy as np
parsed = []
real_parse = ll.parse_bitcode
ll.parse_bitcode = lambda data: parsed.append(len(data)) or real_parse(data)
from isaac_runtime.core import jit
from isaac_runtime.dynamics.integrate import run
from isaac.api import Simulation
sim = Simulation.from_file(sys.argv[1], until=0.2)
sim.advance_to(0.2)
np.save(sys.argv[2], sim.state.y)
(overload,) = run.overloads.values()
library = overload.library
assert isinstance(library, jit._CachedLibrary) and library._shared_module is None
print(len(parsed))
module = library._get_module_for_linking()
defined = {f.name for f in module.functions if not f.is_declaration}
assert defined and defined <= jit._defined_names(library.link_bitcode)
"""
    listed = sorted(jit_symbols().glob("isaac-symbols-*.txt"))
    assert listed, "the warm cache's symbol lists"
    for path in listed:
        path.unlink()
    counts = []
    for k in range(2):
        done = subprocess.run([sys.executable, "-c", code, str(SCENES / "pendulum.isaac"),
                               str(tmp_path / f"state-{k}.npy")],
                              capture_output=True, text=True)
        assert done.returncode == 0, done.stderr
        assert "compiling" not in done.stderr
        counts.append(int(done.stdout.split()[-1]))
    assert counts[0] >= 1 and counts[1] == 0  # (the first parsed each entry's module once, for its list)
    states = [np.load(tmp_path / f"state-{k}.npy") for k in range(2)]
    assert np.array_equal(states[0], states[1])
    written = sorted(jit_symbols().glob("isaac-symbols-*.txt"))
    assert written and set(written) <= set(listed)  # (the pendulum's entries': the warm cache may hold more)


def jit_symbols() -> Path:
    from isaac_runtime.core import jit

    return jit._SYMBOLS

def test_a_bound_entry_calls_the_compiled_overload_after_its_first_call():
    # the step loop's later calls skip numba's typing of every argument; the motion is the dispatcher's own
    bound = Simulation.from_file(SCENES / "cradle.isaac", until=0.5)
    bound.advance_to(0.5)
    assert bound.stepper._run.call is not None
    typed = Simulation.from_file(SCENES / "cradle.isaac", until=0.5)
    typed.stepper._run = typed.stepper._run.dispatcher  # (every call typed by numba)
    typed.advance_to(0.5)
    assert np.array_equal(bound.state.x, typed.state.x) and np.array_equal(bound.state.v, typed.state.v)
    assert [e["time"] for e in bound.events] == [e["time"] for e in typed.events]
