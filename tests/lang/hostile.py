"""Hand-made hostile inputs: scenes, files and option values that must end in exit 0 or exit 2 with a clean,
positioned diagnostic, within 20 s and 4 GB, and never show a traceback or the contents of a file they may not
read. Each case is a folder of files (one of them the scene) and the command line that runs it.

    python -m tests.lang.hostile            # every case, one line each, and the totals

tests/lang/test_hostile.py runs the cases that only read the scene in its own process by default, and every case
in an `isaac` process of its own (20 s, 4 GB) under `-m slow`. Each case says what it expects: refused (exit 2 with
a positioned diagnostic, the default), accepted (exit 0), or either.
"""
from __future__ import annotations

import os
import re
import resource
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ISAAC = [sys.executable, "-m", "isaac"]
# what a clean scene error looks like: `file:line:col: error: message`
POSITIONED = re.compile(r"^\S.*:\d+:\d+: error: ", re.M)
# a clean command-line error: argparse's (`isaac run: error: argument --step: ...`) or our own `isaac: error:`
USAGE = re.compile(r"^(usage: |isaac[ a-z]*: error: |error: )", re.M)
SECRET = "do-not-print-this-secret"
TIMEOUT = 20.0
MEMORY = 4 << 30

BODY = "body ball sphere { radius 5 cm  mass 1 kg  at (0, 1, 0) }"


def scene(*lines: str) -> str:
    return "scene s {\n  time 0 s .. 0.2 s\n" + "\n".join("  " + line for line in lines) + "\n}\n"


@dataclass
class Case:
    name: str
    files: dict  # relative path -> str | bytes | "<fifo>" | ("<symlink>", target)
    args: list  # after `isaac`; SCENE stands for the scene's path
    scene: str = "s.isaac"
    usage: bool = False  # the error may be a command-line one (no position)
    expect: str = "error"  # error: exit 2 and a clean diagnostic; ok: exit 0; any: either
    outside: dict = field(default_factory=dict)  # files beside the case's folder (outside the scene's tree)


def _obj(vertices, faces) -> str:
    return "".join(f"v {x} {y} {z}\n" for x, y, z in vertices) + "".join(
        "f " + " ".join(str(i) for i in face) + "\n" for face in faces)


TETRA = _obj([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [(1, 3, 2), (1, 2, 4), (1, 4, 3), (2, 3, 4)])


def _mesh_case(name: str, content, extra: str = "", file: str = "m.obj") -> Case:
    text = scene("body floor plane { }", f'body rock mesh {{ file "{file}"  mass 1 kg  inertia (1, 1, 1) kg*m2  at (0, 1, 0) {extra} }}')
    return Case(name, {"s.isaac": text, file: content}, ["check", "SCENE"])


def _include(target: str) -> str:
    return f'include "{target}"\n' + scene(BODY)


def cases() -> list:
    big_sum = " + ".join(["t"] * 10_000)
    out = [
        # -- includes: confined to the scene's folder tree, regular files, bounded, UTF-8, read once
        Case("include /etc/passwd", {"s.isaac": _include("/etc/passwd")}, ["check", "SCENE"]),
        Case("include /proc/self/environ", {"s.isaac": _include("/proc/self/environ")}, ["check", "SCENE"]),
        Case("include /dev/zero", {"s.isaac": _include("/dev/zero")}, ["check", "SCENE"]),
        Case("include /dev/urandom", {"s.isaac": _include("/dev/urandom")}, ["check", "SCENE"]),
        Case("include a fifo", {"s.isaac": _include("pipe.isaac"), "pipe.isaac": "<fifo>"}, ["check", "SCENE"]),
        Case("include outside the folder", {"s.isaac": _include("../secret.isaac")}, ["check", "SCENE"],
             outside={"secret.isaac": f"let {SECRET} = 1\n"}),
        Case("include a symlink to outside", {"s.isaac": _include("link.isaac"),
                                              "link.isaac": ("<symlink>", "../secret.isaac")},
             ["check", "SCENE"], outside={"secret.isaac": f"garbage {SECRET}\n"}),
        Case("include a folder", {"s.isaac": _include("lib"), "lib/a.isaac": "let a = 1\n"}, ["check", "SCENE"]),
        Case("include a huge file", {"s.isaac": _include("big.isaac"), "big.isaac": "# x\n" * 5_000_000},
             ["check", "SCENE"]),
        Case("include invalid UTF-8", {"s.isaac": _include("bin.isaac"), "bin.isaac": b"let a = 1\nlet \xff\xfe = 2\n"},
             ["check", "SCENE"]),
        Case("include in a loop", {"s.isaac": "scene s {\n  for i in 0 .. 5000 { include \"x.isaac\" }\n}\n",
                                   "x.isaac": "let y = 1\n"}, ["check", "SCENE"], expect="ok"),
        Case("include itself", {"s.isaac": _include("s.isaac")}, ["check", "SCENE"]),
        # -- assets: meshes, recordings, textures
        _mesh_case("mesh /dev/zero", "", file="/dev/zero"),
        _mesh_case("mesh /etc/passwd", "", file="/etc/passwd"),
        _mesh_case("mesh outside", "", file="../secret.obj"),
        _mesh_case("mesh empty", ""),
        _mesh_case("mesh flat", _obj([(0, 0, 0), (1, 0, 0), (0, 1, 0), (1, 1, 0)], [(1, 2, 3), (2, 4, 3)])),
        _mesh_case("mesh nan vertex", TETRA.replace("v 1 0 0", "v nan 0 0")),
        _mesh_case("mesh inf vertex", TETRA.replace("v 1 0 0", "v 1e999 0 0")),
        _mesh_case("mesh non-numeric vertex", TETRA.replace("v 1 0 0", "v one 0 0")),
        _mesh_case("mesh face index out of range", TETRA.replace("f 2 3 4", "f 2 3 99")),
        _mesh_case("mesh face index zero", TETRA.replace("f 2 3 4", "f 0 3 4")),
        _mesh_case("mesh scale 0", TETRA, extra="scale 0"),
        _mesh_case("mesh scale -1", TETRA, extra="scale -1"),
        _mesh_case("mesh a text file", "This is a letter, not a mesh.\nDear reader,\n"),
        _mesh_case("mesh missing", None),
        _mesh_case("mesh fifo", "<fifo>"),
        _mesh_case("mesh binary stl truncated", b"\0" * 80 + (1000).to_bytes(4, "little") + b"\0" * 10, file="m.stl"),
        _mesh_case("mesh ascii stl garbage", "solid x\nfacet normal 0 0 1\nvertex a b c\nendsolid\n", file="m.stl"),
        _mesh_case("mesh too many vertices", "v 0 0 0\n" * 3_000_000),
        Case("envelope of /dev/zero", {"s.isaac": scene(BODY, 'wind w { direction (1, 0, 0) '
                                                               'speed envelope("/dev/zero") * 1 m/s }')},
             ["check", "SCENE"]),
        Case("texture /dev/urandom", {"s.isaac": scene('material m { texture "/dev/urandom" }',
                                                       BODY.replace("}", " material m }"))}, ["check", "SCENE"]),
        # -- numbers: finite, in range, where given
        Case("mass subnormal", {"s.isaac": scene(BODY.replace("1 kg", "5e-324 kg"))}, ["run", "SCENE"]),
        Case("radius 1e-300", {"s.isaac": scene(BODY.replace("5 cm", "1e-300 m"))}, ["run", "SCENE"]),
        Case("radius 1e200 (overflow)", {"s.isaac": scene(BODY.replace("5 cm", "1e200 m").replace("mass 1 kg",
                                                                                                  "density 1000 kg/m3"))},
             ["check", "SCENE"]),
        Case("mass 1e308", {"s.isaac": scene(BODY.replace("1 kg", "1e308 kg"))}, ["run", "SCENE"]),
        Case("restitution 2", {"s.isaac": scene("material m { restitution 2 }", "body f plane { material m }",
                                                BODY.replace("}", " material m }"))}, ["check", "SCENE"]),
        Case("friction -1", {"s.isaac": scene("material m { friction -1 }", BODY.replace("}", " material m }"))},
             ["check", "SCENE"]),
        Case("velocity 1e300", {"s.isaac": scene(BODY.replace("}", " velocity (1e300, 0, 0) m/s }"))},
             ["run", "SCENE"]),
        Case("gravity 1e300", {"s.isaac": scene("gravity (0, -1e300, 0) m/s2", BODY)}, ["run", "SCENE"]),
        Case("position 1e300 two spheres", {"s.isaac": scene(BODY.replace("(0, 1, 0)", "(1e300, 0, 0)"),
                                                             BODY.replace("ball", "b2"))}, ["run", "SCENE"]),
        Case("seed 1e300", {"s.isaac": scene("seed 1e300", BODY)}, ["check", "SCENE"], expect="any"),
        Case("time reversed", {"s.isaac": "scene s { time 5 s .. 1 s\n" + BODY + " }"}, ["check", "SCENE"]),
        Case("inertia negative", {"s.isaac": scene(BODY.replace("}", " inertia (1, -1, 1) kg*m2 }"))},
             ["check", "SCENE"]),
        # -- budgets: refused when the plan is made, before anything is allocated
        Case("frames 1e9 Hz", {"s.isaac": scene("frames 1e9 Hz", BODY)}, ["run", "SCENE"]),
        Case("time span 1e9 s", {"s.isaac": "scene s { time 0 s .. 1e9 s\n" + BODY + " }"}, ["run", "SCENE"]),
        Case("audio rate 1e12", {"s.isaac": scene("audio { rate 1e12 Hz }", BODY,
                                                  "sound ding on always { play sine(440) }")}, ["run", "SCENE"]),
        Case("step 1e-12 s", {"s.isaac": scene("solver dynamics { step 1e-12 s }", BODY)}, ["run", "SCENE"]),
        Case("substeps 1e9", {"s.isaac": scene("solver procedural { substeps 1e9 }", BODY)}, ["run", "SCENE"]),
        Case("iterations 1e9", {"s.isaac": scene("solver procedural { iterations 1e9 }", BODY)}, ["run", "SCENE"]),
        Case("100 overlapping spheres", {"s.isaac": scene("for i in 0 .. 100 { body b{i} sphere { radius 1 m  "
                                                          "mass 1 kg  at (0, 0, 0) } }")}, ["run", "SCENE"]),
        Case("late time, tiny step", {"s.isaac": "scene s { time 1e9 s .. 1e9 s + 1 s\n solver dynamics "
                                                 "{ step 1e-9 s }\n" + BODY + " }"}, ["run", "SCENE"]),
        # -- expressions: long, deep, overflowing, dividing by zero
        Case("10000-term sum of constants", {"s.isaac": scene(BODY.replace("(0, 1, 0)", "(0, " + " + ".join(
            ["0.0001"] * 10_000) + ", 0)"))}, ["check", "SCENE"], expect="ok"),
        Case("10000-term sum of t", {"s.isaac": scene("body k box kinematic { size (1, 1, 1) m  at (0, (" + big_sum
                                                      + ") * 1e-6 m/s, 0) }")}, ["run", "SCENE"], expect="ok"),
        Case("500 unary minuses", {"s.isaac": scene(BODY.replace("(0, 1, 0)", "(0, " + "-" * 500 + "1, 0)"))},
             ["check", "SCENE"], expect="ok"),
        Case("power tower", {"s.isaac": scene("let a = " + "^".join(["1.0001"] * 500), BODY)}, ["check", "SCENE"],
             expect="ok"),
        Case("power tower of t", {"s.isaac": scene("let u = t / 1 s", "body k box kinematic { size (1, 1, 1) m  "
                                                   "at (0, (" + "^".join(["u"] * 300) + ") * 1 m, 0) }")},
             ["check", "SCENE"]),
        Case("deep parentheses", {"s.isaac": scene("let a = " + "(1 + " * 3000 + "1" + ")" * 3000, BODY)},
             ["check", "SCENE"]),
        Case("deep calls", {"s.isaac": scene("let a = " + "sin(" * 2000 + "1" + ")" * 2000, BODY)},
             ["check", "SCENE"]),
        Case("exponential lets", {"s.isaac": scene("let a0 = t / 1 s", *[f"let a{k + 1} = a{k} * a{k} + a0"
                                                                         for k in range(60)],
                                                   "body k box kinematic { size (1, 1, 1) m  at (0, a60 * 1 m, 0) }")},
             ["check", "SCENE"]),
        Case("overflow at lowering", {"s.isaac": scene("let a = 1e300 * 1e300", BODY)}, ["check", "SCENE"]),
        Case("division by zero at lowering", {"s.isaac": scene("let a = 1 / (1 - 1)", BODY)}, ["check", "SCENE"]),
        Case("path divides by zero at run time", {"s.isaac": scene("body k box kinematic { size (1, 1, 1) m  "
                                                                   "at (1 / (t - 0.1 s) * 1 m*s, 0, 0) }", BODY)},
             ["run", "SCENE"]),
        Case("path overflows at run time", {"s.isaac": scene("body k box kinematic { size (1, 1, 1) m  "
                                                             "at (exp(t * 1e4 / 1 s) * 1 m, 0, 0) }", BODY)},
             ["run", "SCENE"]),
        Case("log of a negative at run time", {"s.isaac": scene("body k box kinematic { size (1, 1, 1) m  "
                                                                "at (log(0.1 - t / 1 s) * 1 m, 0, 0) }", BODY)},
             ["run", "SCENE"]),
        Case("a 2 MB line", {"s.isaac": scene("let a = 1 " + "+ 1 " * 500_000, BODY)}, ["check", "SCENE"],
             expect="ok"),
        Case("nested loops", {"s.isaac": scene("for i in 0 .. 1000 { for j in 0 .. 1000 { for k in 0 .. 1000 "
                                               "{ let x = 1 } } }", BODY)}, ["check", "SCENE"]),
        # -- encodings and line separators
        Case("invalid UTF-8 in the scene", {"s.isaac": scene(BODY).encode() + b"# \xc3\x28 broken\n"},
             ["check", "SCENE"]),
        Case("form feed before an error", {"s.isaac": "scene s {\f\n  " + BODY + "\f  bodyy\n}\n"},
             ["check", "SCENE"]),
        Case("old Mac line ends", {"s.isaac": scene(BODY, "bodyy x").replace("\n", "\r")}, ["check", "SCENE"]),
        Case("unicode line separator", {"s.isaac": scene(BODY) + "\u2028\u2029\x85\x0b\x1c\n"}, ["check", "SCENE"]),
        Case("NUL bytes", {"s.isaac": scene(BODY) + "\x00\x00"}, ["check", "SCENE"]),
        Case("byte order mark", {"s.isaac": "\ufeff" + scene(BODY)}, ["check", "SCENE"], expect="ok"),
        Case("empty scene file", {"s.isaac": ""}, ["check", "SCENE"]),
        Case("scene file is a fifo", {"s.isaac": "<fifo>"}, ["check", "SCENE"], usage=True),
        Case("scene file is /dev/zero", {}, ["check", "/dev/zero"], usage=True),
    ]
    out += more_cases()
    ok = {"s.isaac": scene(BODY)}
    for value in ("0", "nan", "1e-300", "-1", "inf", "-0", "1 parsec", "1e400", "0x10"):
        out.append(Case(f"--step {value}", ok, ["run", "SCENE", "--step", value], usage=True))
    for value in ("-1", "nan", "inf", "0", "1e300"):
        out.append(Case(f"--until {value}", ok, ["run", "SCENE", "--until", value], usage=True,
                        expect="any" if value == "1e300" else "error"))
    for args in (["--out", "/dev/null"], ["--out", "/proc/self"], ["--out", "s.isaac"], ["--max-items", "0"],
                 ["--max-items", "1e99"], ["--set", "x=1e400"], ["--set", "x=((((("], ["--set", "=1"],
                 ["--max-constraint-error", "nan"], ["--max-constraint-error", "-1 cm"], ["--budget", "steps=-1"],
                 ["--budget", "nonsense"], ["--budget", "steps=nan"], ["--include-path", "/nonexistent"]):
        out.append(Case(f"run {' '.join(args)}", ok, ["run", "SCENE", *args], usage=True))
    return out


def more_cases() -> list:
    """Numbers out of range at their position, long expressions through every command that prints the IR."""
    deep_t = "(" + " + ".join(["t"] * 5_000) + ") * 1e-6 m/s"
    minus_t = "-" * 500 + "t * 1 m/s"
    path_body = "body k box kinematic {{ size (1, 1, 1) m  at (0, {0}, 0) }}"
    out = [Case("include /proc with --include-path /", {"s.isaac": _include("/proc/self/environ")},
                ["check", "SCENE", "--include-path", "/"], usage=True)]
    for name, text in [("radius 0", BODY.replace("5 cm", "0 m")), ("mass nan", BODY.replace("1 kg", "(0/0) kg")),
                       ("mass -1", BODY.replace("1 kg", "-1 kg")), ("density subnormal", BODY.replace(
                           "mass 1 kg", "density 1e-320 kg/m3")),
                       ("box size subnormal", "body b box { size (1, 1e-320, 1) m  mass 1 kg }"),
                       ("inertia subnormal", BODY.replace("}", " inertia (1, 1e-320, 1) kg*m2 }")),
                       ("frames 0", "frames 0 Hz"), ("frames nan", "frames (0/0) Hz"), ("step 0", "solver dynamics "
                                                                                        "{ step 0 s }"),
                       ("step -1 ms", "solver dynamics { step -1 ms }"), ("audio rate 0", "audio { rate 0 Hz }"),
                       ("substeps 0", "solver procedural { substeps 0 }"), ("iterations -1", "solver procedural "
                                                                                             "{ iterations -1 }")]:
        out.append(Case(name, {"s.isaac": scene(text, BODY)}, ["check", "SCENE"]))
    out.append(Case("time 0 s .. nan s", {"s.isaac": "scene s { time 0 s .. (0/0) s\n" + BODY + " }"},
                    ["check", "SCENE"]))
    for command in (["parse", "SCENE"], ["plan", "SCENE"], ["golden", "SCENE", "--update"], ["run", "SCENE"]):
        for label, value in (("a 5000-term sum of t", deep_t), ("500 unary minuses of t", minus_t)):
            out.append(Case(f"{label}, isaac {command[0]}", {"s.isaac": scene(path_body.format(value))}, command,
                            expect="ok"))
    return out


def materialize(case: Case, root: Path) -> Path:
    """Write the case's files under root/case/ (and its outside files beside that); returns the scene's path."""
    folder = root / "case"
    folder.mkdir(parents=True)
    for name, content in case.outside.items():
        (root / name).write_text(content)
    for name, content in case.files.items():
        path = folder / name
        if content is None or name.startswith("/") or name.startswith(".."):
            continue
        path.parent.mkdir(parents=True, exist_ok=True)
        if content == "<fifo>":
            os.mkfifo(path)
        elif isinstance(content, tuple):
            os.symlink(content[1], path)
        elif isinstance(content, bytes):
            path.write_bytes(content)
        else:
            path.write_text(content, encoding="utf-8")
    return folder / case.scene


def _limit_memory() -> None:
    resource.setrlimit(resource.RLIMIT_AS, (MEMORY, MEMORY))


@dataclass
class Outcome:
    verdict: str  # ok | traceback | hang | unpositioned | leak | exit N
    code: int | None
    stderr: str
    seconds: float


def run_case(case: Case, root: Path, timeout: float = TIMEOUT) -> Outcome:
    path = materialize(case, root)
    args = [str(path) if a == "SCENE" else a for a in case.args]
    if args[0] == "run" and "--out" not in args:
        args += ["--out", str(root / "out")]
    if args[0] == "run" and "--viewer" not in args:
        args += ["--no-viewer"]
    # the secret in the environment too: a leak of /proc/self/environ shows it
    env = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[2]), "ISAAC_HOSTILE_SECRET": SECRET}
    started = time.monotonic()
    try:
        done = subprocess.run(ISAAC + args, cwd=path.parent, capture_output=True, text=True, errors="replace",
                              timeout=timeout, preexec_fn=_limit_memory, env=env)
    except subprocess.TimeoutExpired as expired:
        return Outcome("hang", None, str(expired.stderr or ""), time.monotonic() - started)
    return Outcome(verdict(case, done.returncode, done.stdout + done.stderr), done.returncode, done.stderr,
                   time.monotonic() - started)


def verdict(case: Case, code: int, output: str) -> str:
    """ok, or what is wrong: leak, traceback, accepted (exit 0 for what must be refused), refused (exit 2 for what
    must work), unpositioned, exit N."""
    if SECRET in output:
        return "leak"
    if code == 1 or "Traceback" in output:
        return "traceback"
    if code == 0:
        return "accepted" if case.expect == "error" else "ok"
    if code != 2:
        return f"exit {code}"
    if case.expect == "ok":
        return "refused"
    if POSITIONED.search(output) or (case.usage and USAGE.search(output)):
        return "ok"
    return "unpositioned"


def main() -> int:
    import tempfile

    selected = sys.argv[1:]
    bad = 0
    for case in cases():
        if selected and not any(s in case.name for s in selected):
            continue
        with tempfile.TemporaryDirectory() as tmp:
            outcome = run_case(case, Path(tmp))
        first = next((line for line in outcome.stderr.splitlines() if "error" in line), outcome.stderr[:100])
        print(f"{outcome.verdict:12} {outcome.code!s:5} {outcome.seconds:5.1f}s  {case.name}: {first[:150]}")
        bad += outcome.verdict != "ok"
    print(f"{bad} not ok")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main())
