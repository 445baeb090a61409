"""How a scene's goldens are made and checked: run options, sampling and tolerances, with defaults that mean
something, overridden per scene by a small TOML file beside it (`swing.isaac` -> `swing.golden.toml`):

    [run]
    until = "2 s"                 # simulate this long (default: the whole scene)
    every = "0.1 s"               # the trajectory every 0.1 s (or: times = ["0.5 s", "1 s"], or samples = 50)
    set = { length = "2 m" }      # --set overrides, as on the command line
    solver = "dynamics"           # and step = "1 ms", as `isaac run --solver --step`

    [tolerance]
    position = "1 mm"             # each quantity: a value with its unit, or a bare number in SI
    event_time = "2 ms"

A value is read the way the language reads it (`1 mm`, `0.5 deg`, `2 ms`); a mistake in the file is a positioned
error (`swing.golden.toml:7:1: error: unknown tolerance ...`), exit 2.
"""
from __future__ import annotations

import math
import os
import re
from dataclasses import dataclass, field, replace
from pathlib import Path

from isaac_ir import units as U
from isaac_ir.diagnostics import Diagnostic, SceneError, SourceCache, SourcePos, did_you_mean
from isaac_ir.files import BadEncoding, Confinement, FileRefused

# quantity -> (default, dimension, what it bounds). Defaults are far above the rounding differences of a run
# repeated on another machine (1e-12 .. 1e-9 in a scene that is not chaotic) and below what anyone would see
# or hear: a micrometre, a microradian, a millisecond, a fifth of a percent of a pitch, half a decibel.
TOLERANCES = {
    "ir": (1e-9, U.DIMENSIONLESS, "relative difference of a number of the IR"),
    "position": (1e-6, U.LENGTH, "distance between a body's centres, m"),
    "orientation": (1e-6, U.ANGLE, "angle of the rotation between a body's orientations, rad"),
    "linear_velocity": (1e-5, U.VELOCITY, "difference of a body's velocity, m/s"),
    "angular_velocity": (1e-5, U.ANGULAR_VELOCITY, "difference of a body's angular velocity, rad/s"),
    "constraint_error": (1e-6, U.LENGTH, "difference of the largest constraint error, m or rad"),
    "energy": (1e-6, U.DIMENSIONLESS, "difference of the energy, relative to the scene's energy scale"),
    "event_time": (1e-3, U.TIME, "shift of an impact's time, s"),
    "impulse": (1e-3, U.DIMENSIONLESS, "relative difference of an impact's impulse"),
    "onset": (5e-3, U.TIME, "shift of a sound onset, s"),
    "frequency": (2e-3, U.DIMENSIONLESS, "relative shift of a spectral peak (2e-3: 3.5 cents)"),
    "level": (0.5, U.DIMENSIONLESS, "difference of a sound level or a peak's height, dB"),
}
# the trajectory kept by default: about this many samples, every k-th frame (the first and the last kept): a
# 10 s scene at 100 frames per second is kept every 0.1 s
DEFAULT_SAMPLES = 101
# ... and fewer for big scenes, so that a golden stays small: at most this many body-samples
MAX_BODY_SAMPLES = 20_000
# the most trajectory samples a golden may keep (`times`, `samples`, or the scene's span over `every`): far more
# than a review can read, and a few MiB of JSON
MAX_GOLDEN_SAMPLES = 100_000
RUN_KEYS = ("until", "every", "times", "samples", "set", "solver", "step")
_QUANTITY = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?)\s*([A-Za-z][A-Za-z0-9*/^-]*)?\s*")


@dataclass
class Settings:
    """Run options, sampling and tolerances of one scene's goldens."""

    until: float | None = None
    every: float | None = None
    times: tuple | None = None
    samples: int = DEFAULT_SAMPLES
    overrides: dict = field(default_factory=dict)  # --set NAME=VALUE
    solver: str | None = None
    step: float | None = None
    tolerance: dict = field(default_factory=lambda: {k: v[0] for k, v in TOLERANCES.items()})
    file: Path | None = None  # the TOML read, if any
    text: str = ""  # its text (for the position of a value found wrong later, once the scene's span is known)

    def with_overrides(self, overrides: dict) -> "Settings":
        """The command line's --set on top of the file's."""
        return replace(self, overrides={**self.overrides, **overrides})

    def run_record(self) -> dict:
        """What the goldens were made with (meta.json): a check with other options says so."""
        return {"until": self.until, "set": dict(sorted(self.overrides.items())), "solver": self.solver,
                "step": self.step}


def settings_path(scene: Path) -> Path:
    return Path(scene).with_name(Path(scene).stem + ".golden.toml")


def load_settings(scene: Path, sources: SourceCache | None = None) -> Settings:
    """The defaults, with the scene's TOML on top when there is one. SceneError for a mistake in it."""
    path = settings_path(scene)
    if not os.path.lexists(path):
        return Settings()
    # named like the scene's own files in diagnostics: relative to the scene's folder (the CLI prints it as reached)
    name = Path(path.name)
    text = read_beside_scene(path, Path(scene).parent, name, sources)
    settings = _read(_parse_toml(text, name), text, name)
    settings.file, settings.text = path, text
    return settings


def read_beside_scene(path: Path, folder: Path, name: Path, sources: SourceCache | None) -> str:
    """The text of a file beside a scene, read as the scene's includes are (isaac_ir/files.py: its folder tree,
    a regular file, bounded, UTF-8); a refusal is an error at the file's first line that shows nothing of it."""
    try:
        text = Confinement.for_scene(folder).read_text(path)
    except BadEncoding as error:
        if sources is not None:  # a file inside the scene's tree: its line may be shown
            sources.add(str(name), error.text)
        raise SceneError([Diagnostic(f"cannot read `{name}`: {error.message}", SourcePos(str(name), error.line,
                                                                                        error.col), error.hint)])
    except FileRefused as error:
        raise SceneError([Diagnostic(f"cannot read `{name}`: {error.message}", SourcePos(str(name), 1, 1),
                                     error.hint)])
    if sources is not None:
        sources.add(str(name), text)
    return text


def _parse_toml(text: str, path: Path) -> dict:
    try:
        import tomllib
    except ImportError:  # Python 3.10
        import tomli as tomllib
    try:
        return tomllib.loads(text)
    except tomllib.TOMLDecodeError as error:
        found = re.search(r"\(at line (\d+), column (\d+)\)", str(error))
        pos = SourcePos(str(path), int(found.group(1)), int(found.group(2))) if found else SourcePos(str(path), 1, 1)
        raise SceneError([Diagnostic(f"cannot read the goldens' settings: {str(error).split(' (at line')[0]}", pos,
                                     "the file is TOML: `[run]` and `[tolerance]` tables of `name = value`")])


def _read(data: dict, text: str, path: Path) -> Settings:
    settings, problems = Settings(file=path), []
    for table in data:
        if table not in ("run", "tolerance"):
            problems.append(_problem(f"unknown table `[{table}]`", text, path, f"[{table}]",
                                     did_you_mean(table, ("run", "tolerance")) or "the tables: [run], [tolerance]"))
    for key, value in data.get("run", {}).items():
        _safely(problems, text, path, key, lambda: _run_value(settings, key, value))
    for key, value in data.get("tolerance", {}).items():
        _safely(problems, text, path, key, lambda: _tolerance_value(settings, key, value))
    if problems:
        raise SceneError(problems)
    return settings


def _safely(problems: list, text: str, path: Path, key: str, read) -> None:
    try:
        read()
    except ValueError as error:
        message, _, hint = str(error).partition("\n")
        problems.append(_problem(message, text, path, key, hint or None))


def _run_value(settings: Settings, key: str, value) -> None:
    if key == "until":
        settings.until = _positive(key, quantity(value, U.TIME, key))
    elif key == "every":
        settings.every = _positive(key, quantity(value, U.TIME, key))
    elif key == "times":
        if not isinstance(value, list) or not value:
            raise ValueError("`times` is a list of times, e.g. times = [\"0.5 s\", \"1 s\"]")
        if len(value) > MAX_GOLDEN_SAMPLES:
            raise ValueError(f"`times` lists {len(value)} times, more than the {MAX_GOLDEN_SAMPLES} a golden keeps")
        settings.times = tuple(sorted(quantity(v, U.TIME, key) for v in value))
    elif key == "samples":
        if not isinstance(value, int) or isinstance(value, bool) or not 2 <= value <= MAX_GOLDEN_SAMPLES:
            raise ValueError(f"`samples` is a whole number from 2 to {MAX_GOLDEN_SAMPLES}")
        settings.samples = value
    elif key == "set":
        if not isinstance(value, dict):
            raise ValueError("`set` is a table of parameters, e.g. set = { length = \"2 m\" }")
        settings.overrides = {str(k): str(v) for k, v in value.items()}
    elif key == "solver":
        if value not in ("dynamics", "procedural", "auto"):
            raise ValueError("`solver` is dynamics, procedural or auto")
        settings.solver = value
    elif key == "step":
        settings.step = _positive(key, quantity(value, U.TIME, key))
    else:
        raise ValueError(f"unknown run option `{key}`\n" + (did_you_mean(key, RUN_KEYS) or
                                                           "the run options: " + ", ".join(RUN_KEYS)))


def check_sample_count(settings: Settings, start: float, end: float) -> None:
    """`every` against the span the run covers (the scene's, or up to `until`): at most MAX_GOLDEN_SAMPLES
    samples, refused at the line that writes it before anything runs."""
    if settings.every is None:
        return
    span = max(0.0, (min(end, settings.until) if settings.until is not None else end) - start)
    count = span / settings.every + 1
    if count > MAX_GOLDEN_SAMPLES:
        name = Path(settings.file.name) if settings.file else Path("golden.toml")
        raise SceneError([_problem(f"`every = {settings.every:g} s` keeps {count:.3g} samples of a {span:g} s run, "
                                   f"more than the {MAX_GOLDEN_SAMPLES} a golden may keep", settings.text, name,
                                   "every", f"every = \"{span / (MAX_GOLDEN_SAMPLES - 1):.3g} s\" or more")])


def _tolerance_value(settings: Settings, key: str, value) -> None:
    if key not in TOLERANCES:
        raise ValueError(f"unknown tolerance `{key}`\n" + (did_you_mean(key, TOLERANCES) or
                                                          "the tolerances: " + ", ".join(TOLERANCES)))
    settings.tolerance[key] = _not_negative(key, quantity(value, TOLERANCES[key][1], key))


def quantity(value, dim, name: str) -> float:
    """A TOML value as SI: a number (already SI), or a string `NUMBER UNIT` in the language's units."""
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise ValueError(f"`{name}` wants a number or a quantity such as \"1 mm\", got {value!r}")
    if not isinstance(value, str):
        return float(value)
    match = _QUANTITY.fullmatch(value)
    if not match:
        raise ValueError(f"cannot read `{name} = \"{value}\"` as a quantity\nwrite it as \"1 mm\", \"2 ms\" or 1e-6")
    number, unit = float(match.group(1)), match.group(2)
    if unit is None:
        return number
    try:
        factor, found = U.parse_unit(unit)
    except U.UnitError as error:
        raise ValueError(f"`{name}`: {error}\n" + (did_you_mean(unit, U.UNITS) or "the units of docs/language.md"))
    if found != dim and not (dim == U.DIMENSIONLESS and found == U.DIMENSIONLESS):
        raise ValueError(f"`{name}` wants {U.describe(dim)}, not {U.describe(found)}")
    return number * factor


def _positive(name: str, value: float) -> float:
    if not (math.isfinite(value) and value > 0):
        raise ValueError(f"`{name}` must be a finite value above 0")
    return value


def _not_negative(name: str, value: float) -> float:
    if not (math.isfinite(value) and value >= 0):
        raise ValueError(f"the tolerance `{name}` must be a finite value, 0 or more")
    return value


def _problem(message: str, text: str, path: Path, key: str, hint: str | None) -> Diagnostic:
    """A diagnostic at the line that writes `key` (TOML's parser keeps no positions)."""
    for number, line in enumerate(text.splitlines(), start=1):
        col = _key_column(line, key)
        if col:
            return Diagnostic(message, SourcePos(str(path), number, col, len(key)), hint)
    return Diagnostic(message, SourcePos(str(path), 1, 1), hint)


def _key_column(line: str, key: str) -> int:
    stripped = line.split("#")[0]
    if key.startswith("["):
        return stripped.find(key) + 1 if stripped.strip().startswith(key) else 0
    found = re.match(rf"\s*({re.escape(key)})\s*=", stripped)
    return found.start(1) + 1 if found else 0
