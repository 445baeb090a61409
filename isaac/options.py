"""Option values of the command line, read the way the language reads them, and checked where they are given.

    --step 0.5ms   --step "0.5 ms"   --step 0.0005      a time: a unit of time, or a bare number of seconds
    --until 2s     --max-constraint-error "1 cm"         a length (m) or an angle (rad); `off` for no limit

A bad value (zero, negative, not finite, a wrong or unknown unit) is an argparse error: the usage line, one line
that says what is wrong, exit 2, never a traceback.
"""
from __future__ import annotations

import argparse
import math
import os
import re
from contextlib import contextmanager

from isaac_ir import units as U
from isaac_ir.diagnostics import did_you_mean

# a number, then a unit if any: `1`, `-1 ms`, `2.5e-3s`, `nan`, `inf`, `(1/60)` is not taken (use seconds)
_QUANTITY = re.compile(r"\s*([+-]?(?:\d+(?:\.\d*)?|\.\d+)(?:[eE][+-]?\d+)?|[+-]?nan|[+-]?inf(?:inity)?)\s*"
                       r"([A-Za-z][A-Za-z0-9*/^-]*)?\s*", re.IGNORECASE)
# time units a shell user may write as a separate word (`--step 1 ms`): joined back to the number
TIME_UNITS = {name for name, (_, dim) in U.UNITS.items() if dim == U.TIME}


def quantity(text: str, dim, what: str) -> float:
    """The SI value of `NUMBER [UNIT]`; a bare number is already SI. ArgumentTypeError when it cannot be read."""
    match = _QUANTITY.fullmatch(str(text))
    if not match:
        raise argparse.ArgumentTypeError(f"cannot read `{text}` as {what} (e.g. `1 ms`, `0.5 s` or `0.001`)")
    value, unit = float(match.group(1)), match.group(2)
    if unit is None:
        return value
    try:
        factor, unit_dim = U.parse_unit(unit)
    except U.UnitError as error:
        name = str(error).split("`")[1] if "`" in str(error) else unit
        guess = did_you_mean(name, U.UNITS)
        raise argparse.ArgumentTypeError(f"{error}" + (f"; {guess}" if guess else "")) from None
    if unit_dim != dim:
        raise argparse.ArgumentTypeError(f"`{text}` is {U.describe(unit_dim)}, not {what}")
    return value * factor


def _finite(value: float, text: str, what: str) -> float:
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{what} must be a finite number, got `{text}`")
    return value


def step_time(text: str) -> float:
    """--step: a time > 0."""
    value = _finite(quantity(text, U.TIME, "a time"), text, "the step")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"the step must be longer than 0 s, got `{text}`")
    return value


def positive_seconds(text: str) -> float:
    """--expand-seconds: a time > 0 (a bare number is seconds)."""
    value = _finite(quantity(text, U.TIME, "a time"), text, "the time")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"the time must be longer than 0 s, got `{text}`")
    return value


def end_time(text: str) -> float:
    """--until: a finite time, not negative (checked against the scene's start once the scene is read)."""
    value = _finite(quantity(text, U.TIME, "a time"), text, "--until")
    if value < 0:
        raise argparse.ArgumentTypeError(f"--until must not be negative, got `{text}`")
    return value


def constraint_limit(text: str) -> float | None:
    """--max-constraint-error: a length (m) or a bare number (m or rad) > 0; `off` or `none`: no limit."""
    if str(text).strip().lower() in ("off", "none", "no"):
        return None
    match = _QUANTITY.fullmatch(str(text))
    unit = match.group(2) if match else None
    dim = U.ANGLE if unit in ("rad", "deg") else U.LENGTH
    value = _finite(quantity(text, dim, "a length or an angle"), text, "--max-constraint-error")
    if value <= 0:
        raise argparse.ArgumentTypeError(f"--max-constraint-error must be above 0, got `{text}` (`off`: no limit)")
    return value


def positive_int(text: str) -> int:
    """A whole number >= 1 (--max-items)."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"wants a whole number, got `{text}`") from None
    if value < 1:
        raise argparse.ArgumentTypeError(f"wants a whole number of at least 1, got `{text}`")
    return value


def port(text: str) -> int:
    """--port: 0 (any free one) to 65535."""
    try:
        value = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"a port is a whole number, got `{text}`") from None
    if not 0 <= value <= 65535:
        raise argparse.ArgumentTypeError(f"a port is 0 (any free one) to 65535, got `{text}`")
    return value


def join_time_units(argv: list, options=("--step", "--until")) -> list:
    """`--step 1 ms` as the shell splits it, back to `--step "1 ms"`: a time option, a bare number, then a time
    unit as a word of its own."""
    out, k = [], 0
    while k < len(argv):
        word = argv[k]
        number = _QUANTITY.fullmatch(argv[k + 1]) if word in options and k + 2 < len(argv) else None
        if number is not None and number.group(2) is None and argv[k + 2] in TIME_UNITS:
            out += [word, f"{argv[k + 1]} {argv[k + 2]}"]
            k += 3
        else:
            out.append(word)
            k += 1
    return out


# ---- files and budgets ----------------------------------------------------------------------------------------

# trees of the system where no output folder or include folder belongs
SYSTEM_TREES = ("/proc", "/sys", "/dev")


def output_folder(text: str) -> str:
    """--out: a folder that is (or can be made) a folder of ours: not a file, a device or a system tree, and
    writable where it would be made."""
    real = os.path.realpath(text)
    if any(real == tree or real.startswith(tree + "/") for tree in SYSTEM_TREES):
        raise argparse.ArgumentTypeError(f"`{text}` is in {real.split('/')[1] and '/' + real.split('/')[1]}, "
                                         "not a place for outputs")
    if os.path.exists(real) and not os.path.isdir(real):
        raise argparse.ArgumentTypeError(f"`{text}` is a file, not a folder (the outputs are a folder of files)")
    existing = real
    while not os.path.exists(existing):
        existing = os.path.dirname(existing)
    if not os.path.isdir(existing):
        raise argparse.ArgumentTypeError(f"`{text}` cannot be made: `{existing}` is a file")
    if not os.access(existing, os.W_OK | os.X_OK):
        raise argparse.ArgumentTypeError(f"`{text}`: `{existing}` is not writable")
    return text


def include_folder(text: str) -> str:
    """--include-path: an existing folder whose files a scene may include and name (isaac_ir/files.py)."""
    real = os.path.realpath(text)
    if not os.path.isdir(real):
        raise argparse.ArgumentTypeError(f"`{text}` is not a folder")
    if real == "/" or any(real == tree or real.startswith(tree + "/") for tree in SYSTEM_TREES):
        raise argparse.ArgumentTypeError(f"`{text}` is a system folder: a scene may not read from it")
    return text


def budget(text: str) -> str:
    """--budget NAME=VALUE[,NAME=VALUE...]: checked as runtime/plan/budgets.py reads them (docs/budgets.md)."""
    from isaac_runtime.plan.budgets import parse_budgets

    try:
        parse_budgets(text)
    except ValueError as error:
        raise argparse.ArgumentTypeError(str(error)) from None
    return text


@contextmanager
def budget_environment(values):
    """The --budget values in ISAAC_BUDGET (after any the environment gave) while a command runs, so that every
    plan it makes, in this process or in the processes it starts, holds to them."""
    from isaac_runtime.plan.budgets import ENVIRONMENT

    if not values:
        yield
        return
    before = os.environ.get(ENVIRONMENT)
    os.environ[ENVIRONMENT] = ",".join(([before] if before else []) + list(values))
    try:
        yield
    finally:
        if before is None:
            os.environ.pop(ENVIRONMENT, None)
        else:
            os.environ[ENVIRONMENT] = before
