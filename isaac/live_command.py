"""`isaac live SCENE [--mic [DEVICE|FILE.wav]] [--until S] [--port N] [--no-browser] [--out DIR]`: the front
end's part (the options, the scene loaded and checked, the parameters the page offers as sliders); the run itself
is isaac_runtime.live.

A slider is offered for each declared parameter: a `let` at the top of the file or of the scene whose value is one
number with its unit as written (`let breath = 3 m/s`, `let d1 = 30 g`), not one computed from others (a
balance point, a hook's position: changing those alone would undo what they were computed for). It moves
between 0 and three times the declared value (a negative one: the mirror), in the unit it was written in.
"""
from __future__ import annotations

from pathlib import Path

from isaac import options as opt

# the slider of a parameter spans [0, SLIDER_SPAN * value] (or [SLIDER_SPAN * value, 0] for a negative value)
SLIDER_SPAN = 3.0
# steps along a slider
SLIDER_STEPS = 200


def add_parser(commands, scene_command) -> None:
    """The `live` subcommand (scene_command: the CLI's maker of a scene command with --set and -q/-v)."""
    live = scene_command("live", "run the scene in real time: a live page on 127.0.0.1, breath from a microphone")
    live.add_argument("--mic", nargs="?", const="", default=None, metavar="DEVICE|FILE",
                      help="the breath: the default input device, a named one, or a WAV file played in real time "
                           "(it stands in for the recordings the winds follow, and mic()); a device needs "
                           "sounddevice (pip install 'isaac[live]')")
    live.add_argument("--until", type=opt.end_time, default=None, help="stop at this time, e.g. 4s (bare: seconds)")
    live.add_argument("--port", type=opt.port, default=None,
                      help="the page's port on 127.0.0.1 (default 8766, or a free one if taken; 0: any free one)")
    live.add_argument("--no-browser", dest="browser", action="store_false", help="do not open the page in a browser")
    live.add_argument("--out", default=None, help="output folder (default out/<scene>/)")
    live.add_argument("--solver", choices=("dynamics", "procedural", "auto"), default=None)
    live.add_argument("--step", type=opt.step_time, default=None, help="solver step, e.g. 1ms (bare: seconds)")
    live.add_argument("--no-viewer", dest="viewer", action="store_false", help="no viewer.html in the outputs")


def cmd_live(args, load, verbosity: int, default_out, check_until, overrides) -> int:
    """Load the scene (diagnostics as for every command), find its sliders, and run it live."""
    from isaac.api import plan_file
    from isaac_runtime.live import LiveOptions, run_live
    from isaac_runtime.run import load_core_in_background

    load_core_in_background()  # (while the scene is parsed and planned: the clock starts after the first frames)
    loaded = load(args)
    check_until(args, loaded.scene)
    path = Path(args.scene)
    options = LiveOptions(scene_path=path, out=Path(args.out) if args.out else default_out(args.scene),
                          overrides=overrides, solver=args.solver, step=args.step, until=args.until,
                          port=args.port, browser=args.browser, mic=args.mic, sliders=sliders(path, overrides),
                          viewer=args.viewer, verbosity=verbosity, scene_warnings=tuple(loaded.warnings),
                          replan=lambda changed: plan_file(path, changed, solver=args.solver, step=args.step,
                                                           until=args.until))
    return run_live(loaded.scene, options)


def sliders(path: Path, overrides: dict | None = None) -> list:
    """[{name, value, unit, text, min, max, step}] of the scene file's declared parameters (module docstring),
    `value` in the written unit (an override given with --set in place of the declared value, when it reads so)."""
    from isaac_ir.diagnostics import Reporter
    from isaac_lang.syntax import parse_text

    tree = parse_text(path.read_text(encoding="utf-8"), path.name, Reporter())
    if tree is None:
        return []
    out = []
    for item in _lets(tree):
        name, value = str(item.children[0]), item.children[1]
        tokens = list(value.scan_values(lambda v: True))
        kinds = [getattr(t, "type", "") for t in tokens]
        if kinds not in (["NUMBER"], ["NUMBER", "UNIT"]):
            continue
        number, unit = float(tokens[0]), (str(tokens[1]) if len(tokens) > 1 else "")
        if value.data == "neg":
            number = -number
        elif value.data not in ("number", "quantity"):
            continue
        given = (overrides or {}).get(name)
        if given is not None:
            number = _read(given, unit, number)
        out.append(_slider(name, number, unit))
    return out


def _lets(tree):
    """The `let` statements at the top of the file and directly in a scene block."""
    for item in tree.children:
        data = getattr(item, "data", None)
        if data == "let_stmt":
            yield item
        elif data == "scene":
            for inner in item.children:
                if getattr(inner, "data", None) == "let_stmt":
                    yield inner


def _read(text: str, unit: str, default: float) -> float:
    """An override `45 g` read as a number in `unit` (the slider's), or the default when it does not read so."""
    parts = str(text).split()
    try:
        number = float(parts[0])
    except (ValueError, IndexError):
        return default
    return number if (parts[1:] == [unit] or (not unit and len(parts) == 1)) else default


def _slider(name: str, value: float, unit: str) -> dict:
    lo, hi = sorted((0.0, SLIDER_SPAN * value)) if value != 0 else (-1.0, 1.0)
    return {"name": name, "value": value, "unit": unit, "text": _text(value, unit), "min": lo, "max": hi,
            "step": (hi - lo) / SLIDER_STEPS}


def _text(value: float, unit: str) -> str:
    number = f"{value:.6g}"
    return f"{number} {unit}" if unit else number

