"""Fuzzing: mutations of the example scenes must give a valid IR or a SceneError whose every diagnostic has a
position, never another exception (a traceback is a bug in isaac, not in the scene), never a hang, and never the
contents of a file the scene may not read. Mutants that load are also run for a few steps: they finish, stop on a
numerical error, or are refused by a budget; their report is valid JSON.

The mutations: token edits (delete, duplicate, swap, truncate, insert, replace, a line of another scene spliced
in), numbers made hostile (0, -1, extremes, nan, inf, subnormals), a number replaced by a long or deep expression
(a sum of thousands of terms, hundreds of unary minuses, a power tower, deep brackets), and a file name replaced by
a trick (a FIFO, /dev/zero, /proc, a path outside the folder, a file too large, not UTF-8, a broken mesh).

The default run is derandomized (the same examples every time, a few seconds); `-m slow` explores 10,000 fresh
ones for `check` and 1,000 for `run`. The counts of a fresh fuzz, one line per failure and the totals:

    python -m tests.lang.test_fuzz --check 10000 --run 1000 [--seed 1] [--whole]
"""
from __future__ import annotations

import atexit
import functools
import json
import os
import random
import re
import shutil
import signal
import tempfile
import traceback
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from isaac_ir import ir
from isaac_ir.diagnostics import SceneError
from isaac_lang.expand import Limits
from isaac_lang.load import load_text

SCENES_DIR = Path(__file__).resolve().parents[2] / "scenes"
DATA_DIR = Path(__file__).resolve().parent / "data"
SECRET = "fuzz-secret-never-shown"
# seconds a mutant may take (the bound is 20 s for a whole `isaac` process)
TIME_LIMIT = 20.0
# how far past its start a mutant that loads is run (s), and the budgets it runs under
RUN_SPAN = 0.05
RUN_BUDGETS = "memory=512MB,steps=2e5,work=2e6"

# words, numbers (with exponents), `..`, strings, comments, whitespace, any other single character
TOKEN = re.compile(r'[A-Za-z_][A-Za-z0-9_]*(?:\{[^}\s]*\}[A-Za-z0-9_]*)*|\d+(?:\.\d+)?(?:[eE][+-]?\d+)?|\.\.|"[^"\n]*"'
                   r"|(?:#|//)[^\n]*|\s+|.", re.S)
NUMBER = re.compile(r"\d")
KEYWORDS = ["scene", "let", "include", "material", "body", "constraint", "kind", "force", "wind", "sound", "camera",
            "light", "solver", "exclude", "part", "use", "for", "in", "during", "from", "until", "on", "world", "keys",
            "static", "kinematic", "sphere", "box", "plane", "mesh", "nail", "point", "orient", "weld", "gear", "rope",
            "tx", "rz", "t", "pi", "sin", "envelope", "modal", "impulse", "always", "collide", "spring", "load"]
NUMBERS = ["0", "1", "-1", "0.5", ".5", "1e400", "1e-400", "1e308", "100000000", "2147483648", "3.14159", "0.0"]
# numbers at the edges of what a double holds, and the values that are not numbers
HOSTILE_NUMBERS = ["0", "-0", "-1", "1e308", "-1e308", "1e-308", "5e-324", "1e-320", "1e400", "1e-400", "(0/0)",
                   "(1/0)", "(-1/0)", "1e12", "1e-12", "9007199254740993", "1e9", "1e-9"]
UNITS = ["m", "cm", "kg", "s", "ms", "deg", "rad", "Hz", "N", "kg/m3", "m/s2", "N*s/m", "GPa", "dB", "rad/s"]
GARBAGE = list("{}()[],;:@.=+-*/^#\"'\\$%&|~`?!<>") + ["..", "->", "\n", "\t", "é", "∞", "\x00", "{i}", "x{", "}{",
                                                         "\f", "\r", "\u2028", "\ufeff"]
INSERTS = KEYWORDS + NUMBERS + UNITS + GARBAGE
# file names a scene may write in place of one of its own: each must be refused or reported, never read past
TRICK_FILES = ['"/etc/passwd"', '"/dev/zero"', '"/dev/urandom"', '"/proc/self/environ"', '"../secret.isaac"',
               '"pipe.isaac"', '"huge.isaac"', '"bin.isaac"', '"."', '""', '"link.isaac"', '"empty.obj"',
               '"flat.obj"', '"nan.obj"', '"text.obj"', '"pipe.obj"', '"../secret.obj"', '"bin.wav"']
# lines with a file in them, spliced in anywhere
FILE_LINES = ['include "pipe.isaac"', 'include "../secret.isaac"', 'include "bin.isaac"',
              'body rock mesh { file "flat.obj"  mass 1 kg  inertia (1, 1, 1) kg*m2 }',
              'body rock mesh { file "nan.obj"  density 1000 kg/m3 }',
              'material grit { texture "/dev/urandom" }']
TETRA = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n"


# ---- the workspace: the seeds and the trick files, in a temporary folder ---------------------------------------

def make_workspace(root: Path) -> dict:
    """Copies of the seed folders under root (each with the trick files beside the seeds, a secret beside the
    folders); {path of each seed: its text}."""
    (root / "secret.isaac").write_text(f"let {SECRET} = 1\n{SECRET}\n")
    (root / "secret.obj").write_text(f"# {SECRET}\n" + TETRA)
    seeds = {}
    for source, name in ((SCENES_DIR, "scenes"), (DATA_DIR, "data")):
        folder = root / name
        shutil.copytree(source, folder, ignore=shutil.ignore_patterns("*.golden", "__pycache__"))
        seeds.update({p: p.read_text(encoding="utf-8") for p in sorted(folder.glob("*.isaac"))})
        _trick_files(folder)
    return seeds


def _trick_files(folder: Path) -> None:
    os.mkfifo(folder / "pipe.isaac")
    os.mkfifo(folder / "pipe.obj")
    (folder / "huge.isaac").write_bytes(b"# padding\n" * 450_000)  # 4.5 MB: over the 4 MiB a scene file may be
    (folder / "bin.isaac").write_bytes(b"let a = 1\nlet \xff\xfe = 2\n")
    (folder / "bin.wav").write_bytes(b"RIFF\xff\xff\xff\xffWAVEjunk")
    (folder / "empty.obj").write_text("")
    (folder / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 3\nf 2 4 3\n")
    (folder / "nan.obj").write_text(TETRA.replace("v 1 0 0", "v nan 0 0"))
    (folder / "text.obj").write_text("Dear reader, this is a letter.\n")
    os.symlink("../secret.isaac", folder / "link.isaac")


_WORKSPACE = Path(tempfile.mkdtemp(prefix="isaac-fuzz-"))
atexit.register(shutil.rmtree, _WORKSPACE, True)
SEEDS = make_workspace(_WORKSPACE)
PATHS = sorted(SEEDS)
LINES = sorted({line for text in SEEDS.values() for line in text.splitlines() if line.strip()}) + FILE_LINES


# ---- the mutations ---------------------------------------------------------------------------------------------

def tokens(text: str) -> list:
    return TOKEN.findall(text)


def long_expression(rng: random.Random) -> str:
    """A long or deep expression of numbers (and of t: then only a path can hold it, else it is an error)."""
    leaf = rng.choice(["1", "0.001", "t / 1 s", "2", "x"])
    n = rng.choice([50, 250, 1000, 5000])
    kind = rng.choice(["sum", "minus", "tower", "brackets", "calls", "product"])
    if kind == "sum":
        return "(" + " + ".join([leaf] * n) + ")"
    if kind == "product":
        return "(" + " * ".join(["1.0001"] * n) + ")"
    if kind == "minus":
        return "(" + "-" * min(n, 600) + leaf + ")"
    if kind == "tower":
        return "(" + "^".join(["1.0001"] * min(n, 300)) + ")"
    depth = min(n, 400)
    return ("sin(" * depth if kind == "calls" else "(1 + " * depth) + leaf + ")" * depth


# every kind of mutation; those that mostly keep a scene loadable (for the runs)
KINDS = ["delete", "duplicate", "swap", "truncate", "insert", "replace", "splice", "number", "number", "expression",
         "file"]
MILD = ["number", "number", "number", "expression", "duplicate"]


def mutate(rng: random.Random, kinds=KINDS, most: int = 4) -> tuple:
    """(seed path, mutated text): 1 to `most` mutations of one seed."""
    path = rng.choice(PATHS)
    toks = tokens(SEEDS[path])
    for _ in range(rng.randint(1, most)):
        if not toks:
            break
        i = rng.randrange(len(toks))
        kind = rng.choice(kinds)
        if kind == "delete":
            del toks[i]
        elif kind == "duplicate":
            toks.insert(i, toks[i])
        elif kind == "swap":
            j = rng.randrange(len(toks))
            toks[i], toks[j] = toks[j], toks[i]
        elif kind == "truncate":
            toks = toks[:i]
        elif kind == "splice":  # a line of another scene, dropped anywhere
            toks.insert(i, "\n" + rng.choice(LINES) + "\n")
        elif kind in ("number", "expression", "file"):
            _replace_one(toks, rng, kind)
        else:
            word = rng.choice(INSERTS) if rng.random() < 0.8 else "".join(
                chr(rng.randrange(1, 0x3000)) for _ in range(rng.randint(1, 3)))
            piece = f" {word} " if rng.random() < 0.5 else word
            if kind == "insert":
                toks.insert(i, piece)
            else:
                toks[i] = piece
    return path, "".join(toks)


def _replace_one(toks: list, rng: random.Random, kind: str) -> None:
    """A number token made hostile or long, or a quoted name made a trick file."""
    wanted = (lambda tok: tok.startswith('"')) if kind == "file" else (lambda tok: bool(NUMBER.match(tok)))
    places = [k for k, tok in enumerate(toks) if wanted(tok)]
    if not places:
        return
    k = rng.choice(places)
    if kind == "file":
        toks[k] = rng.choice(TRICK_FILES)
    elif kind == "number":
        toks[k] = rng.choice(HOSTILE_NUMBERS)
    else:
        toks[k] = long_expression(rng)


# ---- the outcomes ----------------------------------------------------------------------------------------------

class Hang(Exception):
    """A mutant took longer than TIME_LIMIT."""


class _deadline:
    """Raise Hang in the main thread after `seconds` (SIGALRM; compiled kernels return to Python between calls)."""

    def __init__(self, seconds: float):
        self.seconds = seconds

    def __enter__(self):
        def expire(signum, frame):
            raise Hang(f"over {self.seconds:g} s")

        self.previous = signal.signal(signal.SIGALRM, expire)
        signal.setitimer(signal.ITIMER_REAL, self.seconds)

    def __exit__(self, *exc):
        signal.setitimer(signal.ITIMER_REAL, 0)
        signal.signal(signal.SIGALRM, self.previous)


def load_outcome(path: Path, text: str):
    """The loaded scene, or None after a SceneError whose every diagnostic is positioned; AssertionError (or the
    exception itself) otherwise."""
    try:
        with _deadline(TIME_LIMIT):
            loaded = load_text(text, path.name, folder=path.parent, limits=Limits(max_items=2000))
    except SceneError as error:
        assert error.diagnostics, "a SceneError without diagnostics"
        for diagnostic in error.diagnostics:
            pos = diagnostic.pos
            assert pos is not None, f"no position: {diagnostic.message}"
            assert pos.file and pos.line >= 1 and pos.col >= 1, f"bad position {pos}: {diagnostic.message}"
        shown = error.format()  # printing the diagnostics must work too
        assert SECRET not in shown, "a file the scene may not read was shown"
        return None
    ir.to_json(loaded.scene)
    return loaded


def check_outcome(path: Path, text: str) -> None:
    """Either a scene whose IR prints, or a SceneError with positioned diagnostics; nothing else."""
    load_outcome(path, text)


def run_outcome(path: Path, text: str, out: Path, span: float = RUN_SPAN, budgets: str | None = RUN_BUDGETS) -> str:
    """A mutant that loads, run `span` past its start (None: to its end, under the default budgets when `budgets`
    is None): `complete`, `blow-up`, `refused` (a SceneError: a budget, an extra, a constraint no pose satisfies),
    or `loads no scene`; its report is strict JSON."""
    loaded = load_outcome(path, text)
    if loaded is None:
        return "loads no scene"
    _warm_up()
    from isaac.options import budget_environment
    from isaac_runtime.run import RunOptions, simulate, write_outputs

    scene = loaded.scene
    until = None if span is None else min(scene.time.end, scene.time.start + span)
    options = RunOptions(until=until, folder=path.parent, viewer=False)
    try:
        with _deadline(TIME_LIMIT), budget_environment([budgets] if budgets else []):
            result = simulate(scene, options)
            out.mkdir(parents=True, exist_ok=True)
            write_outputs(scene, result, out)
    except SceneError as error:
        assert all(d.message for d in error.diagnostics)
        return "refused"
    json.loads((out / "report.json").read_text(), parse_constant=_no_constant)
    return "blow-up" if result.error is not None else "complete"


def hostile_mutant():
    """The hypothesis strategy of (seed path, mutant), every kind of mutation."""
    return st.randoms(use_true_random=False).map(mutate)


def mutated_scene():
    """(seed path, mutant) without long expressions: tests/lang/test_parse_loop.py compares the parse trees of
    two parsers with recursive code, which a sum of 5,000 terms would take beyond Python's recursion limit."""
    shallow = [kind for kind in KINDS if kind != "expression"]
    return st.randoms(use_true_random=False).map(lambda rng: mutate(rng, shallow))


@functools.lru_cache(maxsize=None)
def _warm_up() -> None:
    """The compiled core loaded (or compiled, after a change to it: a minute) before any mutant's clock starts."""
    from isaac_runtime.run import RunOptions, simulate

    simulate(load_text((SCENES_DIR / "pendulum.isaac").read_text(), "pendulum.isaac").scene, RunOptions(until=0.01))


def mild_mutant(rng: random.Random) -> tuple:
    """A mutant for the runs: one or two mutations that keep most scenes loadable (numbers, expressions)."""
    return mutate(rng, MILD, 2)


def _no_constant(name: str):
    raise AssertionError(f"report.json holds {name}")


@settings(max_examples=300, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow])
@given(hostile_mutant())
def test_mutated_scenes_load_or_report(case):
    check_outcome(*case)


@pytest.mark.slow
@settings(max_examples=10_000, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(hostile_mutant())
def test_mutated_scenes_load_or_report_at_scale(case):
    check_outcome(*case)


@settings(max_examples=25, derandomize=True, deadline=None, database=None,
          suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture])
@given(st.randoms(use_true_random=False).map(mild_mutant))
def test_mutated_scenes_run_or_stop_cleanly(tmp_path, case):
    run_outcome(*case, tmp_path / "out")


@pytest.mark.slow
@settings(max_examples=1_000, deadline=None, suppress_health_check=[HealthCheck.too_slow,
                                                                     HealthCheck.function_scoped_fixture])
@given(st.randoms(use_true_random=False).map(mild_mutant))
def test_mutated_scenes_run_or_stop_cleanly_at_scale(tmp_path, case):
    run_outcome(*case, tmp_path / "out")


def test_the_tokenizer_round_trips():
    for text in SEEDS.values():
        assert "".join(tokens(text)) == text


def test_a_deep_gain_is_read_without_recursion():
    """The fuzzer's find: `gain` was told dB from its text, the repr of its parse tree (recursive)."""
    gain = "(" + " + ".join(["1"] * 3000) + ") * 0 - 6 dB"
    sound = load_text(f"scene s {{ sound a on always {{ play sine(440 Hz)  gain {gain} }} }}").scene.sounds[0]
    assert sound.gain == pytest.approx(10 ** (-6 / 20), rel=1e-12)


def test_the_mutations_reach_every_kind():
    rng = random.Random(7)
    texts = [mutate(rng)[1] for _ in range(400)]
    assert any("5e-324" in t or "(0/0)" in t for t in texts)
    assert any(t.count("+") > 200 or t.count("-") > 200 or t.count("^") > 40 for t in texts)
    assert any("pipe.isaac" in t or "/dev/zero" in t or "../secret" in t for t in texts)


@pytest.mark.parametrize("text", [
    "scene s { for i in 0 .. 1e400 { } }",
    "scene s { body b sphere { radius 1 m  mass 0/0 kg } }",
    "scene s { body b sphere { radius 1e400 m  mass 1 kg } }",
    "scene s { body b{1e400} sphere { radius 1 m  mass 1 kg } }",
    "scene s { body b{+} sphere { radius 1 m  mass 1 kg } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg  orient quat(0, 0, 0, 0) } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg  at (log(0), 0, 0) } }",
    "scene s { seed 1e400 }",
    "scene s { frames 0/0 }",
    "part p() { use p a()  use p b() }\nscene s { use p top() }",
    "scene s { for i in 0 .. 100000 { for j in 0 .. 100000 { let x = 1 } } }",
    "scene s { body b sphere { radius 1e-300 m  mass 1 kg } }",
    "scene s { body b sphere { radius 5 cm  mass 5e-324 kg } }",
    "scene s { body b sphere { radius 1e200 m  density 1000 kg/m3 } }",
    "scene s { audio { rate 0 Hz } }",
    "scene s { audio { rate 1e-9 Hz  channels 2 } }",
    "scene s { sound a on always { play sine(440 Hz)  gain --1e308 dB } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg  at (1e308, 0, 0) } }",
    "scene s { body b sphere { radius 1 m  mass 1 kg }  constraint n nail(b @ (0, 0, 0), (-1e308, 1, 0)) }",
])
def test_crashes_found_by_the_fuzzer_stay_fixed(text):
    with pytest.raises(SceneError) as caught:
        load_text(text, "s.isaac", limits=Limits(max_items=2000))
    assert all(d.pos is not None for d in caught.value.diagnostics)


# ---- the counts of a fresh fuzz ----------------------------------------------------------------------------------

def fuzz(count: int, seed: int, run: bool, whole: bool = False) -> dict:
    """{verdict: number of mutants}: ok, traceback, hang, unpositioned (or leak), and for runs the outcomes (whole:
    each run to the scene's end under the default budgets, as `isaac run` runs it)."""
    rng, totals = random.Random(seed), {}
    span, budgets = (None, None) if whole else (RUN_SPAN, RUN_BUDGETS)
    for k in range(count):
        path, text = mild_mutant(rng) if run else mutate(rng)
        try:
            verdict = run_outcome(path, text, _WORKSPACE / "out" / str(k % 4), span, budgets) if run else (
                "loads" if load_outcome(path, text) is not None else "positioned error")
        except Hang:
            verdict = "hang"
            print(f"hang: {path.name}: {_difference(SEEDS[path], text)}"[:300])
        except AssertionError as error:
            verdict = "leak" if "may not read" in str(error) else "unpositioned"
            print(f"{verdict}: {path.name}: {error} in {_difference(SEEDS[path], text)}".replace("\n", " ")[:400])
        except Exception as error:  # noqa: BLE001 (a bug: counted and shown)
            verdict = "traceback"
            where = traceback.extract_tb(error.__traceback__)[-1]
            print(f"traceback: {path.name}: {type(error).__name__}: {error} at {where.filename}:{where.lineno} in "
                  f"{_difference(SEEDS[path], text)}".replace("\n", " ")[:400])
        totals[verdict] = totals.get(verdict, 0) + 1
    return totals


def _difference(seed: str, text: str) -> str:
    """Where a mutant first differs from its seed: a few characters either side."""
    at = next((k for k, (a, b) in enumerate(zip(seed, text)) if a != b), min(len(seed), len(text)))
    return repr(text[max(0, at - 40):at + 80])


def main(argv=None) -> int:
    import argparse

    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--check", type=int, default=10_000, help="mutants through the front end")
    parser.add_argument("--run", type=int, default=0, help="mutants run for a few steps")
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--whole", action="store_true", help="run each mutant to its end, under the default budgets")
    args = parser.parse_args(argv)
    bad = 0
    for label, count, run in (("check", args.check, False), ("run", args.run, True)):
        if count:
            totals = fuzz(count, args.seed, run, args.whole)
            print(f"{label}: {count} mutants: " + ", ".join(f"{v} {n}" for v, n in sorted(totals.items())))
            bad += sum(n for v, n in totals.items() if v in ("traceback", "hang", "unpositioned", "leak"))
    return 1 if bad else 0


if __name__ == "__main__":
    raise SystemExit(main())
