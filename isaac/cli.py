"""The `isaac` command. Exit codes: 0 success, 1 a bug in the tool, 2 a problem in the scene or the command line
(a bad option value, a missing asset or extra, a blow-up), 3 a finished run that broke a stated tolerance
(`run --max-constraint-error`, `golden`).

    isaac parse SCENE [--set NAME=VALUE ...]     canonical IR JSON on stdout
    isaac check SCENE                            diagnostics only
    isaac plan SCENE                             the compiled plan
    isaac run SCENE [--out DIR] [--solver ...] [--step S] [--until S] [--set ...] [--plots] [--no-viewer]
    isaac watch SCENE [--out DIR] [--port N] [--no-serve] [--poll] [--plots] [run options]   live reload
    isaac export SCENE --format rib|gltf|glb [--out DIR] [--trajectory NPZ] [--frames A:B:S] ...
    isaac bench [--quick] [--only NAME] [--out DIR]   the benchmark suite (benchmarks/, a source checkout)
    isaac golden SCENE... [--update] [--set ...]   golden files beside each scene: record, or check (exit 3)
    isaac live SCENE [--mic [DEVICE|FILE]] [--until S] [--port N] [--no-browser] [--out DIR]   real time, a page
    isaac lsp                                    the language server for editors, on stdio (isaac/lsp)
    isaac fit SCENE [--set ...] [--workers N | --scheduler ADDRESS] [--out DIR]   values that meet the goals
    isaac --version; isaac -q|-qq|-v COMMAND ...   no progress bar; errors and warnings only; more verbose
"""
from __future__ import annotations

import argparse
import dataclasses
import os
import sys
from pathlib import Path

from isaac import installed_version
from isaac import options as opt
from isaac_ir.diagnostics import SceneError, SourceCache, counted

EXIT_OK, EXIT_BUG, EXIT_SCENE, EXIT_TOLERANCE = 0, 1, 2, 3


def build_parser() -> argparse.ArgumentParser:
    parser = SuggestingParser(prog="isaac", description="Physically based motion and sound, as text.")
    parser.add_argument("--version", action=_VersionAction)
    verbosity_options(parser, 0)
    commands = parser.add_subparsers(dest="command", required=True, metavar="COMMAND")

    def scene_command(name: str, help: str) -> argparse.ArgumentParser:
        sub = commands.add_parser(name, help=help)
        sub.add_argument("scene", help="the .isaac file")
        sub.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                         help="override a parameter (a top-level `let`), e.g. --set length=2m")
        sub.add_argument("--max-items", type=opt.positive_int, default=None,
                         help="limit on declarations after loops and parts expand (default 200000)")
        sub.add_argument("--expand-seconds", type=opt.positive_seconds, default=None, metavar="S",
                         help="limit on the time includes, loops and parts take to expand (default 3)")
        sub.add_argument("--strict", action="store_true", help="warnings are errors (exit 2)")
        sub.add_argument("--include-path", action="append", default=[], type=opt.include_folder, metavar="DIR",
                         help="a folder besides the scene's own whose files it may include and name (repeatable)")
        sub.add_argument("--budget", action="append", default=[], type=opt.budget, metavar="NAME=VALUE",
                         help="raise (or lower) a limit of the plan, e.g. steps=1e8, memory=8GB, frames=off "
                              "(docs/budgets.md; also ISAAC_BUDGET)")
        verbosity_options(sub, argparse.SUPPRESS)
        return sub

    scene_command("parse", "print the canonical IR as JSON")
    scene_command("check", "report problems in a scene; exit 0 when clean")
    scene_command("plan", "print the compiled plan: stages on/off, solver, sizes")
    run = scene_command("run", "simulate and write trajectory, events, audio and report")
    run_options(run)
    run.add_argument("--max-constraint-error", type=opt.constraint_limit,
                     default=argparse.SUPPRESS, metavar="LIMIT",
                     help="exit 3 when the run keeps a constraint error above this once switched-on constraints "
                          "have settled (m, or rad; e.g. 1cm; default 0.1; `off`: no limit)")
    run.add_argument("--mic", nargs="?", const="", default=None, metavar="DEVICE",
                     help="blow into the microphone: mic() in a wind's speed listens (needs sounddevice)")
    run.add_argument("--viewer", action=argparse.BooleanOptionalAction, default=True,
                     help="write viewer.html beside the outputs (default: yes; it takes milliseconds)")
    run.add_argument("--plots", action="store_true",
                     help="write plots/ (energy, constraint error, trajectories, spectrogram); needs matplotlib")
    watch = scene_command("watch", "re-run the scene on every save; a live viewer on 127.0.0.1")
    run_options(watch)
    watch.add_argument("--port", type=opt.port, default=8765, help="live viewer port on 127.0.0.1 (0: any free one)")
    watch.add_argument("--no-serve", dest="serve", action="store_false", help="no live viewer, files only")
    watch.add_argument("--poll", action="store_true", help="poll the files instead of OS notifications")
    watch.add_argument("--plots", action="store_true", help="write plots/ after every complete run")
    export = scene_command("export", "write the run as RenderMan RIB or glTF 2.0")
    export.add_argument("--format", required=True, choices=("rib", "gltf", "glb"),
                        help="rib: RenderMan frames; gltf: JSON with embedded buffer; glb: binary glTF")
    export.add_argument("--out", default=None, type=opt.output_folder, help="output folder (default out/<scene>/)")
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
    bench.add_argument("--out", default=None, type=opt.output_folder,
                       help="output folder (default benchmarks/results[/quick])")
    bench.add_argument("--docs", action=argparse.BooleanOptionalAction, default=None,
                       help="rewrite the tables of docs/performance.md (default: full runs into benchmarks/results)")
    golden_command(commands)
    from isaac.live_command import add_parser as live_command  # isaac live (isaac/live_command.py)

    live_command(commands, scene_command)
    sweep = commands.add_parser("sweep", help="run many variants of a scene (each a Dask task): one table")
    sweep.add_argument("scene", help="the .isaac file")
    sweep.add_argument("--set", action="append", default=[], metavar="NAME=VALUES",
                       help="the values of a parameter: V1,V2,... or A..B/N (N values, ends included); several "
                            "--set make their product; with --random, A..B is a range to draw from")
    sweep.add_argument("--random", type=opt.positive_int, default=None, metavar="N", help="N random variants instead")
    sweep.add_argument("--seed", type=int, default=0, help="seed of --random (default 0)")
    sweep.add_argument("--solver", choices=("dynamics", "procedural", "auto"), default=None)
    sweep.add_argument("--step", type=opt.step_time, default=None, help="solver step, e.g. 1ms (bare: seconds)")
    sweep.add_argument("--until", type=opt.end_time, default=None, help="stop each run at this time, e.g. 2s")
    sweep.add_argument("--scheduler", default=None, metavar="ADDRESS",
                       help="a Dask scheduler, tcp://HOST:PORT (default: a local cluster, one process per core)")
    sweep.add_argument("--workers", type=opt.positive_int, default=None,
                       help="processes of the local cluster (default: one per core)")
    sweep.add_argument("--out", default=None, help="output folder (default out/<scene>-sweep/)")
    sweep.add_argument("--keep", choices=("outputs", "table"), default="outputs",
                       help="outputs: each variant's files in OUT/variants/<id>/ (default); table: the table only")
    verbosity_options(sweep, argparse.SUPPRESS)
    commands.add_parser("lsp", help="the language server for editors (LSP over stdin/stdout): docs/editors.md")
    from isaac.fit.command import add_parser as fit_command  # isaac fit (isaac/fit/command.py)

    fit_command(commands, scene_command)
    return parser


class SuggestingParser(argparse.ArgumentParser):
    """argparse's parser whose errors end with a hint: the command or option meant (`isaac rnu` -> `run`)."""

    def error(self, message: str):
        self.print_usage(sys.stderr)
        hint = _closest_word(message, self)
        print(f"{self.prog}: error: {message}" + (f"\nhint: {hint}" if hint else ""), file=sys.stderr)
        self.exit(EXIT_SCENE)


def _closest_word(message: str, parser: argparse.ArgumentParser) -> str | None:
    """`did you mean ...` for argparse's "invalid choice: 'rnu'" and "unrecognized arguments: --unti"."""
    import difflib
    import re

    choice = re.search(r"invalid choice: '([^']*)'", message)
    if choice:
        choices = [c for action in parser._actions if action.choices for c in action.choices]
        close = difflib.get_close_matches(choice.group(1), [str(c) for c in choices], n=1, cutoff=0.5)
        return f"did you mean `{close[0]}`?" if close else None
    unknown = re.search(r"unrecognized arguments: (\S+)", message)
    if unknown:
        word = unknown.group(1).split("=")[0]
        options = [o for action in _all_actions(parser) for o in action.option_strings]
        close = difflib.get_close_matches(word, options, n=1, cutoff=0.6)
        return f"did you mean `{close[0]}`?" if close else "see `isaac COMMAND --help` for the options"
    return None


def _all_actions(parser: argparse.ArgumentParser) -> list:
    """The parser's actions and those of its commands' parsers."""
    actions = list(parser._actions)
    for action in parser._actions:
        if isinstance(action, argparse._SubParsersAction):
            for sub in action.choices.values():
                actions += sub._actions
    return actions


def complete_scene_names(args) -> None:
    """A scene named without its extension is found: `isaac run swing` runs swing.isaac when swing does not
    exist."""
    if isinstance(getattr(args, "scene", None), str):
        args.scene = _with_extension(args.scene)
    if isinstance(getattr(args, "scenes", None), list):
        args.scenes = [_with_extension(s) for s in args.scenes]


def _with_extension(name: str) -> str:
    path = Path(name)
    if not path.exists() and path.suffix != ".isaac" and path.with_name(path.name + ".isaac").is_file():
        return name + ".isaac"
    return name


# benchmarks/suite.py SECTIONS, repeated here so that building the parser imports nothing
# the sections of benchmarks/suite.py (not installed with the package: tests/test_bench_smoke.py holds them equal)
BENCH_SECTIONS = ("work_precision", "scaling", "stress", "specialization", "audio", "profile", "contact", "commands")


def run_options(sub: argparse.ArgumentParser) -> None:
    """The options that say how to simulate, shared by run and watch."""
    sub.add_argument("--out", default=None, type=opt.output_folder, help="output folder (default out/<scene>/)")
    sub.add_argument("--solver", choices=("dynamics", "procedural", "auto"), default=None)
    sub.add_argument("--step", type=opt.step_time, default=None, help="solver step, e.g. 1ms (bare: seconds)")
    sub.add_argument("--until", type=opt.end_time, default=None, help="stop at this time, e.g. 2s (bare: seconds)")


def golden_command(commands) -> None:
    """`isaac golden SCENE... [--update] [--set ...]` (isaac/golden)."""
    golden = commands.add_parser("golden", help="check each scene against its golden files (exit 3 on a mismatch), "
                                                "or record them with --update")
    golden.add_argument("scenes", nargs="+", metavar="SCENE", help=".isaac files; goldens in SCENE_STEM.golden/")
    golden.add_argument("--update", action="store_true", help="(re)write the golden files from this run")
    golden.add_argument("--set", action="append", default=[], metavar="NAME=VALUE",
                        help="override a parameter, as for run (also `[run] set` in SCENE_STEM.golden.toml)")
    verbosity_options(golden, argparse.SUPPRESS)


def cmd_golden(args, sources) -> int:
    from isaac.golden.command import run_golden

    def format_error(error, scene, loaded_sources):
        return _as_written(error, scene, loaded_sources).format(loaded_sources)

    return run_golden(args.scenes, args.update, _overrides(args), _verbosity(args), format_error)


def verbosity_options(parser: argparse.ArgumentParser, default) -> None:
    """-q and -v, before the command or after it (a subcommand's default is SUPPRESS: it keeps the main one's)."""
    parser.add_argument("-q", "--quiet", action="count", default=default,
                        help="say less: no progress bar; twice (-qq): errors and warnings only")
    parser.add_argument("-v", "--verbose", action="count", default=default,
                        help="say more: the plan before a run, every file written")


class _VersionAction(argparse.Action):
    """--version: the installed version, looked up only when asked (importlib.metadata costs 19 ms of every
    command's start)."""

    def __init__(self, option_strings, dest, **kwargs):
        super().__init__(option_strings, dest, nargs=0, default=argparse.SUPPRESS, help="show the version and exit")

    def __call__(self, parser, namespace, values, option_string=None):
        print(f"isaac {installed_version()}")  # (on stdout, as argparse's own version action prints it)
        parser.exit()


def _verbosity(args) -> int:
    """-2 errors and warnings only (-qq), -1 no progress bar (-q), 0 normal, 1 verbose (-v)."""
    return max(-2, min(1, int(getattr(args, "verbose", 0) or 0) - int(getattr(args, "quiet", 0) or 0)))


def main(argv=None) -> int:
    try:
        args = build_parser().parse_args(opt.join_time_units(list(sys.argv[1:] if argv is None else argv)))
    except SystemExit as done:  # --help, --version (0), a bad option value (2): argparse has said why
        return done.code if isinstance(done.code, int) else (0 if done.code is None else EXIT_SCENE)
    complete_scene_names(args)
    sources = SourceCache()
    try:
        with opt.budget_environment(getattr(args, "budget", None)):
            code = COMMANDS[args.command](args, sources)
    except SceneError as error:
        print(_as_written(error, getattr(args, "scene", ""), sources).format(sources), file=sys.stderr)
        code = EXIT_SCENE
    except KeyboardInterrupt:
        print(interrupted_message(args), file=sys.stderr)
        code = 130
    except BrokenPipeError:
        code = EXIT_OK
    except Exception:  # a bug in the tool, not in the scene
        code = _report_bug()
    return code


def interrupted_message(args) -> str:
    """What Ctrl-C leaves: a command writes its outputs into a staging folder swapped in only when complete."""
    if args.command in ("run", "watch", "export", "live"):
        out = getattr(args, "out", None) or default_out(args.scene)
        return (f"interrupted: nothing of this run was written; the previous outputs in {out}/ were kept whole "
                "(a run replaces them only once it has finished)")
    return "interrupted"


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
    """Say it is our fault, and where the traceback went, instead of a wall of text (isaac/crash.py, as
    `isaac watch` says it)."""
    from isaac.crash import internal_error

    print(f"isaac: {internal_error(sys.exc_info()[1])}", file=sys.stderr)
    return EXIT_BUG


def _overrides(args) -> dict:
    from isaac_lang.overrides import clipped

    out = {}
    for item in args.set:
        name, sep, value = item.partition("=")
        if not sep or not name.strip():
            raise SceneError([_usage_diagnostic(f"--set wants NAME=VALUE, got `{clipped(item)}`")])
        out[name.strip()] = value.strip()
    return out


def _usage_diagnostic(message: str):
    from isaac_ir.diagnostics import Diagnostic

    return Diagnostic(message, None)


def _load(args, sources):
    from isaac_ir.diagnostics import warning_diagnostic
    from isaac_lang.load import load_scene

    path = Path(args.scene)
    _check_scene_file(path)
    loaded = load_scene(path, _overrides(args), _limits(args), sources)
    strict = getattr(args, "strict", False)
    warnings = [warning_diagnostic(text, "error" if strict else "warning") for text in loaded.warnings]
    if warnings and strict:
        raise SceneError(warnings)
    if warnings:
        print(_as_written(SceneError(warnings), args.scene, sources).format(sources), file=sys.stderr)
    return loaded


def _check_scene_file(path: Path) -> None:
    """The scene named on the command line is a text file: not missing, not a folder, a FIFO or a device."""
    if not path.exists():
        raise SceneError([_usage_diagnostic(f"no such scene file: {path}")])
    if not path.is_file():
        raise SceneError([_usage_diagnostic(f"{path} is not a regular file (a folder, a FIFO or a device): a scene "
                                            "is a text file")])


def _limits(args):
    """--max-items, --expand-seconds and --include-path as the front end's Limits."""
    from isaac_lang.expand import Limits

    return Limits(max_items=args.max_items or Limits.max_items, include_path=tuple(args.include_path or ()),
                  max_seconds=getattr(args, "expand_seconds", None) or Limits.max_seconds)


def cmd_parse(args, sources) -> int:
    from isaac_ir import ir

    loaded = _load(args, sources)
    sys.stdout.write(ir.to_json(loaded.scene) + "\n")
    return EXIT_OK


def cmd_check(args, sources) -> int:
    loaded = _load(args, sources)
    scene = loaded.scene
    print(f"{args.scene}: ok ({counted(len(scene.bodies), 'body')}, {counted(len(scene.constraints), 'constraint')})")
    return EXIT_OK


def cmd_plan(args, sources) -> int:
    from isaac_runtime.plan.extras import check_extras
    from isaac_runtime.plan import PlanOptions, compile_plan

    loaded = _load(args, sources)
    plan = compile_plan(loaded.scene, PlanOptions(folder=Path(args.scene).parent))
    print(plan.describe())
    check_extras(plan)  # a plan this machine cannot run says so now (exit 2), naming the extra to install
    return EXIT_OK


def cmd_run(args, sources) -> int:
    from isaac_runtime.run import RunOptions, load_core_in_background, run_scene

    load_core_in_background()  # (while the scene is parsed and planned)
    loaded = _load(args, sources)
    _check_until(args, loaded.scene)
    if args.mic is not None:  # a SignalError (no sounddevice, no device) is a SceneError: exit 2, with a hint
        from isaac_runtime.signals import open_microphone
        open_microphone(args.mic or None)
    out = Path(args.out) if args.out else default_out(args.scene)
    verbosity = _verbosity(args)
    # the limit when given (`off`: None); otherwise RunOptions' own default, the runtime's one definition of it (read
    # here, not when the parser is built: the command's start does not wait for numpy)
    limit = {"max_constraint_error": args.max_constraint_error} if hasattr(args, "max_constraint_error") else {}
    options = RunOptions(solver=args.solver, step=args.step, until=args.until,
                         progress=verbosity >= 0 and sys.stderr.isatty(), folder=Path(args.scene).parent,
                         viewer=args.viewer, plots=args.plots, strict=args.strict, verbosity=verbosity,
                         scene_warnings=tuple(loaded.warnings), **limit)
    return run_scene(loaded.scene, out, options, scene_path=Path(args.scene))


def default_out(scene_path) -> Path:
    """out/<file stem>/: named after the scene's file (two files that declare the same scene name never share
    a folder)."""
    return Path("out") / Path(scene_path).stem


def _check_until(args, scene) -> None:
    """--until must leave something to simulate: after the scene's start. Past the scene's end, the run goes to
    the end and says so."""
    until = getattr(args, "until", None)
    if until is not None and until > scene.time.end:
        print(f"isaac: warning: --until {until:g} s is past the scene's end ({scene.time.end:g} s): running to the "
              f"end, {scene.time.end:g} s\nhint: to simulate longer, change the scene's `time` "
              f"(e.g. `time {scene.time.start:g} s .. {until:g} s`)", file=sys.stderr)
        args.until = None
        return
    if until is not None and until <= scene.time.start:
        raise SceneError([_usage_diagnostic(f"--until {until:g} s is not after the scene's start "
                                            f"({scene.time.start:g} s): nothing to simulate")])


def cmd_watch(args, sources) -> int:
    from isaac.watch import Watch, WatchOptions

    path = Path(args.scene)
    _check_scene_file(path)
    if args.plots:  # every extra is checked before the first run, never after it
        from isaac_runtime.plan.extras import check_modules

        check_modules([("matplotlib", "--plots")])
    options = WatchOptions(out=Path(args.out) if args.out else None, overrides=_overrides(args), solver=args.solver,
                           step=args.step, until=args.until,
                           limits=_limits(args),
                           serve=args.serve, port=args.port, poll=args.poll, plots=args.plots)

    def format_error(error, loaded_sources):
        return _as_written(error, args.scene, loaded_sources).format(loaded_sources)

    return Watch(path, options, format_error).run()


def cmd_export(args, sources) -> int:
    from isaac.export_command import export
    from isaac_runtime.export.geometry import MeshFileError
    from isaac_runtime.export.rib import RibOptions

    loaded = _load(args, sources)
    out = Path(args.out) if args.out else default_out(args.scene)
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
        # not a bug in the tool: the command asks for what this install does not have (exit 2, as a missing extra)
        print("error: isaac bench needs a source checkout (benchmarks/ beside isaac/)\n"
              "hint: clone the repository and install it with `pip install -e '.[bench]'`", file=sys.stderr)
        return EXIT_SCENE
    sys.path.insert(0, str(root))
    from benchmarks.suite import run

    return run(quick=args.quick, only=args.only, out=args.out, docs=args.docs)


def cmd_sweep(args, sources) -> int:
    """Variants on Dask, one table (isaac/sweep/command.py; dask and pandas are imported from here on)."""
    from isaac.sweep.command import run_command

    return run_command(args, _verbosity(args))


def cmd_live(args, sources) -> int:
    """Real time, a live page (isaac/live_command.py; the run: isaac_runtime.live)."""
    from isaac.live_command import cmd_live as live

    return live(args, lambda a: _load(a, sources), _verbosity(args), default_out, _check_until, _overrides(args))


def cmd_lsp(args, sources) -> int:
    """The language server (isaac/lsp), imported only here."""
    from isaac.lsp import serve_stdio

    return serve_stdio()


def cmd_fit(args, sources) -> int:
    """Values of the `vary`s that meet the goals (isaac/fit; scipy and, with workers, dask from here on)."""
    from isaac.fit.command import cmd_fit as fit

    return fit(args, lambda a: _load(a, sources), default_out, _overrides(args), _limits(args), _verbosity(args))


COMMANDS = {"parse": cmd_parse, "check": cmd_check, "plan": cmd_plan, "run": cmd_run, "watch": cmd_watch,
            "export": cmd_export, "bench": cmd_bench, "sweep": cmd_sweep, "golden": cmd_golden, "live": cmd_live,
            "lsp": cmd_lsp, "fit": cmd_fit}

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
