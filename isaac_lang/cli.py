"""The `isaac` command. Exit codes: 0 success, 2 a problem in the scene, 1 a bug in the tool.

    isaac parse SCENE [--set NAME=VALUE ...]     canonical IR JSON on stdout
    isaac check SCENE                            diagnostics only
    isaac plan SCENE                             the compiled plan
    isaac run SCENE [--out DIR] [--solver ...] [--step S] [--until S] [--set ...] [--plots] [--no-viewer]
    isaac watch SCENE [--out DIR] [--port N] [--no-serve] [--poll] [--plots] [run options]   live reload
    isaac export SCENE --format rib|gltf|glb [--out DIR] [--trajectory NPZ] [--frames A:B:S] ...
    isaac bench [--quick] [--only NAME] [--out DIR]   the benchmark suite (benchmarks/, a source checkout)
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
import tempfile
import time
import traceback
from pathlib import Path

from .diagnostics import SceneError, SourceCache

EXIT_OK, EXIT_BUG, EXIT_SCENE = 0, 1, 2


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(prog="isaac", description="Physically based motion and sound, as text.")
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def scene_command(name: str, help: str) -> argparse.ArgumentParser:
        sub = commands.add_parser(name, help=help)
        sub.add_argument("scene", help="the .isaac file")
        sub.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                         help="override a parameter (a top-level `let`), e.g. --set length=2m")
        sub.add_argument("--max-items", type=int, default=None,
                         help="limit on declarations after loops and parts expand (default 200000)")
        return sub

    scene_command("parse", "print the canonical IR as JSON")
    scene_command("check", "report problems in a scene; exit 0 when clean")
    scene_command("plan", "print the compiled plan: stages on/off, solver, sizes")
    run = scene_command("run", "simulate and write trajectory, events, audio and report")
    run_options(run)
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    run.add_argument("--mic", nargs="?", const="", default=None, metavar="DEVICE",
                     help="blow into the microphone: mic() in a wind's speed listens (needs sounddevice)")
    run.add_argument("--viewer", action=argparse.BooleanOptionalAction, default=True,
                     help="write viewer.html beside the outputs (default: yes; it takes milliseconds)")
    run.add_argument("--plots", action="store_true",
                     help="write plots/ (energy, constraint error, trajectories, spectrogram); needs matplotlib")
    watch = scene_command("watch", "re-run the scene on every save; a live viewer on 127.0.0.1")
    run_options(watch)
    watch.add_argument("--port", type=int, default=8765, help="live viewer port on 127.0.0.1 (0: any free one)")
    watch.add_argument("--no-serve", dest="serve", action="store_false", help="no live viewer, files only")
    watch.add_argument("--poll", action="store_true", help="poll the files instead of OS notifications")
    watch.add_argument("--plots", action="store_true", help="write plots/ after every complete run")
    export = scene_command("export", "write the run as RenderMan RIB or glTF 2.0")
    export.add_argument("--format", required=True, choices=("rib", "gltf", "glb"),
                        help="rib: RenderMan frames; gltf: JSON with embedded buffer; glb: binary glTF")
    export.add_argument("--out", default=None, help="output folder (default out/<scene>/)")
    export.add_argument("--trajectory", default=None,
                        help="the trajectory.npz to export (default: the one in the output folder when it was "
                             "run from this very scene, else a new run)")
    export.add_argument("--frames", default=None, metavar="A:B[:STEP]",
                        help="RIB: which frames (indices, Python slice), e.g. 0:100:10 or 42 (default all)")
    export.add_argument("--sequence", action="store_true", help="RIB: every frame in one file, not one per frame")
    export.add_argument("--motion-blur", action="store_true", help="RIB: blur over half a frame")
    export.add_argument("--size", default="960x540", metavar="WxH", help="RIB: image size in pixels")
    export.add_argument("--camera", default=None, help="RIB: the camera to render (default the scene's first)")
    bench = commands.add_parser("bench", help="run the benchmark suite: CSVs and plots in benchmarks/results/")
    bench.add_argument("--quick", action="store_true",
                       help="a few minutes: fewer steps, sizes and repeats, into benchmarks/results/quick/")
    bench.add_argument("--only", action="append", metavar="NAME", choices=BENCH_SECTIONS,
                       help=f"one section (repeatable): {', '.join(BENCH_SECTIONS)}")
    bench.add_argument("--out", default=None, help="output folder (default benchmarks/results[/quick])")
    bench.add_argument("--docs", action=argparse.BooleanOptionalAction, default=None,
                       help="rewrite the tables of docs/performance.md (default: full runs into benchmarks/results)")
    return parser


# benchmarks/suite.py SECTIONS, repeated here so that building the parser imports nothing
BENCH_SECTIONS = ("work_precision", "scaling", "stress", "specialization", "audio", "profile")


def run_options(sub: argparse.ArgumentParser) -> None:
    """The options that say how to simulate, shared by run and watch."""
    sub.add_argument("--out", default=None, help="output folder (default out/<scene>/)")
    sub.add_argument("--solver", choices=("dynamics", "procedural", "auto"), default=None)
    sub.add_argument("--step", type=float, default=None, help="solver step in seconds")
    sub.add_argument("--until", type=float, default=None, help="stop at this time (seconds)")


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    sources = SourceCache()
    try:
        code = COMMANDS[args.command](args, sources)
    except SceneError as error:
        print(_as_written(error, args.scene, sources).format(sources), file=sys.stderr)
        code = EXIT_SCENE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        code = 130
    except BrokenPipeError:
        code = EXIT_OK
    except Exception:  # a bug in the tool, not in the scene
        code = _report_bug()
    return code


def _as_written(error: SceneError, scene: str, sources: SourceCache) -> SceneError:
    """Files in diagnostics are named relative to the scene's folder (as in the IR); print them as the user
    reaches them from here (`scenes/pendulum.isaac:12:3`), so that an editor can jump to them."""
    folder = Path(scene).parent
    if folder == Path("."):
        return error
    located = []
    for diagnostic in error.diagnostics:
        pos = diagnostic.pos
        if pos is not None and not pos.file.startswith("--set") and not Path(pos.file).is_absolute():
            written = (folder / pos.file).as_posix()
            sources.alias(pos.file, written)
            diagnostic = dataclasses.replace(diagnostic, pos=dataclasses.replace(pos, file=written))
        located.append(diagnostic)
    return SceneError(located)


def _report_bug() -> int:
    """Say it is our fault, and where the traceback went, instead of a wall of text."""
    fd, path = tempfile.mkstemp(prefix="isaac-crash-", suffix=".txt")
    with os.fdopen(fd, "w") as handle:
        traceback.print_exc(file=handle)
    kind, value, _ = sys.exc_info()
    print(f"isaac: internal error ({kind.__name__}: {value}); this is a bug in isaac, not in your scene.\n"
          f"The traceback is in {path}", file=sys.stderr)
    return EXIT_BUG


def _overrides(args) -> dict:
    out = {}
    for item in args.set:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise SceneError([_usage_diagnostic(f"--set wants NAME=VALUE, got `{item}`")])
        out[name.strip()] = value.strip()
    return out


def _usage_diagnostic(message: str):
    from .diagnostics import Diagnostic

    return Diagnostic(message, None)


def _load(args, sources):
    from .expand import Limits
    from .load import load_scene

    path = Path(args.scene)
    if not path.is_file():
        raise SceneError([_usage_diagnostic(f"no such scene file: {path}")])
    limits = Limits(max_items=args.max_items) if args.max_items else Limits()
    loaded = load_scene(path, _overrides(args), limits, sources)
    for warning in loaded.warnings:
        print(f"warning: {warning}", file=sys.stderr)
    return loaded


def cmd_parse(args, sources) -> int:
    from . import ir

    loaded = _load(args, sources)
    sys.stdout.write(ir.to_json(loaded.scene) + "\n")
    return EXIT_OK


def cmd_check(args, sources) -> int:
    loaded = _load(args, sources)
    scene = loaded.scene
    print(f"{args.scene}: ok ({len(scene.bodies)} bodies, {len(scene.constraints)} constraints)")
    return EXIT_OK


def cmd_plan(args, sources) -> int:
    from isaac_runtime.plan import PlanOptions, compile_plan

    loaded = _load(args, sources)
    plan = compile_plan(loaded.scene, PlanOptions(folder=Path(args.scene).parent))
    print(plan.describe())
    return EXIT_OK


def cmd_run(args, sources) -> int:
    from isaac_runtime.run import RunOptions, run_scene

    loaded = _load(args, sources)
    if args.mic is not None:  # a SignalError (no sounddevice, no device) is a SceneError: exit 2, with a hint
        from isaac_runtime.signals import open_microphone
        open_microphone(args.mic or None)
    out = Path(args.out) if args.out else Path("out") / loaded.scene.name
    options = RunOptions(solver=args.solver, step=args.step, until=args.until,
                         progress=not args.quiet and sys.stderr.isatty(), folder=Path(args.scene).parent)
    code = run_scene(loaded.scene, out, options, scene_path=Path(args.scene))
    if args.viewer:
        _write_viewer(loaded.scene, out, Path(args.scene).parent)
    if args.plots:
        return _write_plots(loaded.scene, out) or code
    return code


def _write_viewer(scene, out: Path, folder: Path) -> None:
    import numpy as np

    from isaac_runtime.viewer import write_viewer

    with np.load(out / "trajectory.npz", allow_pickle=False) as data:
        arrays = dict(data)
    write_viewer(out / "viewer.html", scene, arrays, folder, audio=out / "audio.wav" if scene.sounds else None)


def _write_plots(scene, out: Path) -> int:
    """Plots of the run in out/plots/; 0, or 1 (with a message, not a traceback) without matplotlib."""
    import numpy as np

    try:
        from isaac_runtime.plots import write_plots

        import matplotlib  # noqa: F401 (the optional `plots` extra)
    except ImportError:
        print("isaac: --plots needs matplotlib: pip install 'isaac[plots]'", file=sys.stderr)
        return EXIT_BUG
    with np.load(out / "trajectory.npz", allow_pickle=False) as data:
        arrays = dict(data)
    paths = write_plots(out / "plots", arrays, out / "audio.wav" if scene.sounds else None, title=scene.name)
    print(f"plots: {', '.join(p.name for p in paths)} in {out / 'plots'}/")
    return EXIT_OK


def cmd_watch(args, sources) -> int:
    from .expand import Limits
    from .watch import Watch, WatchOptions

    path = Path(args.scene)
    if not path.is_file():
        raise SceneError([_usage_diagnostic(f"no such scene file: {path}")])
    options = WatchOptions(out=Path(args.out) if args.out else None, overrides=_overrides(args), solver=args.solver,
                           step=args.step, until=args.until,
                           limits=Limits(max_items=args.max_items) if args.max_items else Limits(),
                           serve=args.serve, port=args.port, poll=args.poll, plots=args.plots)

    def format_error(error, loaded_sources):
        return _as_written(error, args.scene, loaded_sources).format(loaded_sources)

    return Watch(path, options, format_error).run()


def cmd_export(args, sources) -> int:
    from isaac_runtime.export.command import export
    from isaac_runtime.export.geometry import MeshFileError
    from isaac_runtime.export.rib import RibOptions

    loaded = _load(args, sources)
    out = Path(args.out) if args.out else Path("out") / loaded.scene.name
    width, sep, height = args.size.lower().partition("x")
    if not (sep and width.isdigit() and height.isdigit() and int(width) > 0 and int(height) > 0):
        raise SceneError([_usage_diagnostic(f"--size wants WIDTHxHEIGHT in pixels, e.g. 960x540, got `{args.size}`")])
    if args.camera is not None and args.camera not in {c.name for c in loaded.scene.cameras}:
        names = ", ".join(c.name for c in loaded.scene.cameras) or "none"
        raise SceneError([_usage_diagnostic(f"--camera: the scene has no camera `{args.camera}` (it has: {names})")])
    rib = RibOptions(width=int(width), height=int(height), frames=_frames(args.frames), sequence=args.sequence,
                     motion_blur=args.motion_blur, camera=args.camera)
    trajectory = Path(args.trajectory) if args.trajectory else None
    if trajectory is not None and not trajectory.is_file():
        raise SceneError([_usage_diagnostic(f"--trajectory: no such file: {trajectory}")])
    try:
        export(loaded.scene, Path(args.scene), out, args.format, trajectory, rib)
    except MeshFileError as error:
        raise SceneError([_usage_diagnostic(str(error))]) from None
    return EXIT_OK


def _frames(spec: str | None) -> slice:
    """--frames: `42` (one frame), `0:100` or `0:100:10` (a Python slice of frame indices)."""
    if spec is None:
        return slice(None)
    try:
        parts = [int(p) if p.strip() else None for p in spec.split(":")]
        if len(parts) == 1:
            return slice(parts[0], None if parts[0] == -1 else parts[0] + 1)
        if len(parts) in (2, 3) and parts[-1] != 0:
            return slice(*parts)
    except ValueError:
        pass
    raise SceneError([_usage_diagnostic(f"--frames wants A, A:B or A:B:STEP (frame numbers), got `{spec}`")])


def cmd_bench(args, sources) -> int:
    """The suite lives in the source tree's benchmarks/ (not installed): found beside this package."""
    root = Path(__file__).resolve().parents[1]
    if not (root / "benchmarks" / "suite.py").is_file():
        print("isaac bench: needs a source checkout (benchmarks/ beside isaac_lang/); "
              "install with `pip install -e '.[bench]'`", file=sys.stderr)
        return EXIT_BUG
    sys.path.insert(0, str(root))
    from benchmarks.suite import run

    return run(quick=args.quick, only=args.only, out=args.out, docs=args.docs)


COMMANDS = {"parse": cmd_parse, "check": cmd_check, "plan": cmd_plan, "run": cmd_run, "watch": cmd_watch,
            "export": cmd_export, "bench": cmd_bench}

def entry() -> None:  # pragma: no cover (the `isaac` command; tests call main)
    """`isaac ...`: main(), then leave without the interpreter's teardown. Every output is written and closed by
    then; what the teardown would do is unload numba's and LLVM's machine code, a tenth of a second of a cached
    `isaac run`."""
    code = main()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


if __name__ == "__main__":  # pragma: no cover
    entry()
