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
from isaac.writable import check_output_folder
from isaac_ir.diagnostics import Diagnostic, SceneError

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
    live.add_argument("--out", default=None, type=opt.output_folder, help="output folder (default out/<scene>/)")
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
    out = Path(args.out) if args.out else default_out(args.scene)
    check_output_folder(out, "--out")
    if args.mic:
        check_mic_file(args.mic)
    options = LiveOptions(scene_path=path, out=out,
                          overrides=overrides, solver=args.solver, step=args.step, until=args.until,
                          port=args.port, browser=args.browser, mic=args.mic, sliders=sliders(path, overrides),
                          viewer=args.viewer, verbosity=verbosity, scene_warnings=tuple(loaded.warnings),
                          replan=lambda changed: plan_file(path, changed, solver=args.solver, step=args.step,
                                                           until=args.until))
    return run_live(loaded.scene, options)


# the most samples (frames x channels) of a rehearsal's file: 7.5 minutes of 44.1 kHz stereo, 160 MB as read
MAX_MIC_SAMPLES = 20_000_000
SOUND_SUFFIXES = (".wav", ".flac", ".ogg")


def check_mic_file(option: str) -> None:
    """`--mic FILE`: a regular sound file of bounded size and length, holding samples that are numbers; a
    SceneError naming --mic otherwise, before the page opens. A name that is no file and has no sound suffix is
    a device (left to the live stage)."""
    path = Path(option)
    if path.suffix.lower() not in SOUND_SUFFIXES and not path.is_file():
        return
    problem = _mic_file_problem(path)
    if problem is not None:
        raise SceneError([Diagnostic(f"--mic `{option}`: {problem}", None,
                                     "rehearse with a WAV, FLAC or OGG recording of the breath")])


def _mic_file_problem(path: Path) -> str | None:
    from isaac_ir.files import MAX_ASSET_BYTES, FileRefused, Confinement

    try:
        Confinement.for_scene(path.parent).regular(path, MAX_ASSET_BYTES["recording"], anywhere=True)
    except FileRefused as error:
        return error.message
    try:
        import soundfile

        info = soundfile.info(str(path))
    except ImportError:
        return None  # the live stage says which package is missing
    except Exception as error:  # soundfile's own LibsndfileError, RuntimeError, ...
        return f"cannot read it as sound ({str(error).splitlines()[0][:160] if str(error) else type(error).__name__})"
    return _sound_problem(path, info, soundfile)


def _sound_problem(path: Path, info, soundfile) -> str | None:
    if info.frames <= 0 or info.channels <= 0:
        return "it holds no samples"
    if not info.samplerate >= 1:
        return f"its sample rate is {info.samplerate} Hz"
    if info.frames * info.channels > MAX_MIC_SAMPLES:
        return (f"it holds {info.frames * info.channels} samples, more than the {MAX_MIC_SAMPLES} a rehearsal may "
                "play (cut it shorter)")
    import numpy as np

    samples, rate = soundfile.read(str(path), dtype="float64", always_2d=True)
    bad = np.flatnonzero(~np.all(np.isfinite(samples), axis=1))
    if len(bad):
        return f"sample {bad[0]} (at {bad[0] / rate:.3g} s) is not a number (NaN or infinite)"
    return None


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

