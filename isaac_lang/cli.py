"""The `isaac` command. Exit codes: 0 success, 2 a problem in the scene, 1 a bug in the tool.

    isaac parse SCENE [--set NAME=VALUE ...]     canonical IR JSON on stdout
    isaac check SCENE                            diagnostics only
    isaac plan SCENE                             the compiled plan
    isaac run SCENE [--out DIR] [--solver ...] [--step S] [--until S] [--set ...]
"""
from __future__ import annotations

import argparse
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
    run.add_argument("--out", default=None, help="output folder (default out/<scene>/)")
    run.add_argument("--solver", choices=("dynamics", "procedural", "auto"), default=None)
    run.add_argument("--step", type=float, default=None, help="solver step in seconds")
    run.add_argument("--until", type=float, default=None, help="stop at this time (seconds)")
    run.add_argument("--quiet", action="store_true", help="no progress bar")
    return parser


def main(argv=None) -> int:
    args = build_parser().parse_args(argv)
    sources = SourceCache()
    try:
        code = COMMANDS[args.command](args, sources)
    except SceneError as error:
        print(error.format(sources), file=sys.stderr)
        code = EXIT_SCENE
    except KeyboardInterrupt:
        print("interrupted", file=sys.stderr)
        code = 130
    except BrokenPipeError:
        code = EXIT_OK
    except Exception:  # a bug in the tool, not in the scene
        code = _report_bug()
    return code


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
    from isaac_runtime.plan import compile_plan

    loaded = _load(args, sources)
    plan = compile_plan(loaded.scene)
    print(plan.describe())
    return EXIT_OK


def cmd_run(args, sources) -> int:
    from isaac_runtime.run import RunOptions, run_scene

    loaded = _load(args, sources)
    out = Path(args.out) if args.out else Path("out") / loaded.scene.name
    options = RunOptions(solver=args.solver, step=args.step, until=args.until,
                         progress=not args.quiet and sys.stderr.isatty())
    return run_scene(loaded.scene, out, options, scene_path=Path(args.scene))


COMMANDS = {"parse": cmd_parse, "check": cmd_check, "plan": cmd_plan, "run": cmd_run}

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
