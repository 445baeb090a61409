"""A record against its golden: each quantity within its tolerance, or a Finding that says what moved and by
how much. Findings are ordered worst first (by how many tolerances they are off; a change of structure, such as
a body that is not there, counts as infinitely many).

    findings = compare(golden, record, tolerance)     # [] when everything is within tolerance
"""
from __future__ import annotations

import math
from contextlib import contextmanager
from dataclasses import dataclass

import numpy as np

from isaac.golden.canonical import item_name
from isaac.golden.record import QUANTITIES

# differences of the IR shown for one scene (the rest are counted)
MAX_IR_DIFFERENCES = 12
UNITS = {"position": "m", "orientation": "rad", "linear_velocity": "m/s", "angular_velocity": "rad/s"}


@dataclass(frozen=True)
class Finding:
    section: str  # ir | trajectory | events | report | audio
    what: str  # the quantity, e.g. `bodies[bob].shape.radius`, `position of bob`
    detail: str  # how it moved, e.g. "0.06, the golden has 0.05 (+20%)"
    excess: float  # how many tolerances off (math.inf: a change of structure)

    def __str__(self) -> str:
        return f"{self.section}: {self.what}: {self.detail}"


class GoldenShapeError(ValueError):
    """Golden data whose JSON is valid but not of the shape `isaac golden --update` writes (a list where an object
    belongs, a key missing, a string for a number): which section, and what was found wrong."""

    def __init__(self, section: str, detail: str):
        super().__init__(f"{section}.json: {detail}")
        self.section, self.detail = section, detail


@contextmanager
def golden_section(section: str):
    """Read a section of the golden within this block: what its shape breaks is a GoldenShapeError of it."""
    try:
        yield
    except GoldenShapeError:
        raise
    except KeyError as error:
        raise GoldenShapeError(section, f"it has no {error} where one belongs") from None
    except (TypeError, AttributeError, IndexError, ValueError, OverflowError, RecursionError) as error:
        raise GoldenShapeError(section, f"a value is not of the kind written there ({_first_line(error)})") from None


def _first_line(error: Exception) -> str:
    return (str(error).splitlines() or [type(error).__name__])[0][:160]


def golden_times(golden: dict, most: int) -> list | None:
    """The times of the golden trajectory, that the record is sampled at: finite numbers in order, at most
    `most` of them (a GoldenShapeError otherwise); None when the golden has no trajectory."""
    if "trajectory" not in golden:
        return None
    with golden_section("trajectory"):
        times = np.asarray(golden["trajectory"]["time"], float)
    if times.ndim != 1 or len(times) > most or not np.all(np.isfinite(times)) or np.any(np.diff(times) < 0):
        raise GoldenShapeError("trajectory", f"`time` is not a list of at most {most} finite times in order")
    return times.tolist()


def compare(golden: dict, record: dict, tolerance: dict, energy_scale: float = 1.0) -> list:
    """Every finding of the record's sections against the golden's (sections missing on one side included); a
    GoldenShapeError naming the section whose shape is not a golden's."""
    if not isinstance(golden, dict):
        raise GoldenShapeError("meta", "the goldens are not sections of a record")
    with golden_section("ir"):
        findings = compare_ir(golden.get("ir"), record.get("ir"), tolerance["ir"])
    with golden_section("trajectory"):
        energy_scale = _energy_scale(golden.get("trajectory"), energy_scale)
    if "trajectory" in golden or "trajectory" in record:
        with golden_section("trajectory"):
            findings += compare_trajectory(golden.get("trajectory"), record.get("trajectory"), tolerance,
                                           energy_scale)
        with golden_section("events"):
            findings += compare_events(golden.get("events") or {}, record.get("events") or {}, tolerance)
        with golden_section("report"):
            findings += compare_report(golden.get("report") or {}, record.get("report") or {}, tolerance,
                                       energy_scale)
        with golden_section("audio"):
            findings += compare_audio(golden.get("audio"), record.get("audio"), tolerance)
    return sorted(findings, key=lambda f: -f.excess)


def _energy_scale(trajectory, report_scale: float) -> float:
    """The yardstick of energy differences: the report's (m |g| size of the scene, or the kinetic energy at the
    start), or the largest energy the golden holds when that is larger (a scene without gravity that starts at
    rest has a yardstick of zero)."""
    energies = np.abs(np.asarray((trajectory or {}).get("energy", []), float))
    largest = float(np.nanmax(energies)) if energies.size and np.isfinite(energies).any() else 0.0
    return max(report_scale, largest, 1e-12)


# ---- the IR -------------------------------------------------------------------------------------------------

def compare_ir(golden, actual, rel_tol: float) -> list:
    found = []
    _walk(golden, actual, "", rel_tol, found)
    if len(found) > MAX_IR_DIFFERENCES:
        more = len(found) - MAX_IR_DIFFERENCES
        found = found[:MAX_IR_DIFFERENCES] + [Finding("ir", "...", f"and {more} more differences", math.inf)]
    return found


def _walk(expected, actual, path: str, rel_tol: float, found: list) -> None:
    """Depth first, in key order; lists of named items matched by name (a body added does not shift the rest)."""
    if isinstance(expected, dict) and isinstance(actual, dict):
        for key in sorted(set(expected) | set(actual)):
            where = f"{path}.{key}" if path else key
            if key not in actual:
                found.append(Finding("ir", where, f"gone (the golden has {_short(expected[key])})", math.inf))
            elif key not in expected:
                found.append(Finding("ir", where, f"new: {_short(actual[key])}", math.inf))
            else:
                _walk(expected[key], actual[key], where, rel_tol, found)
    elif isinstance(expected, list) and isinstance(actual, list):
        _walk_list(expected, actual, path, rel_tol, found)
    elif _is_number(expected) and _is_number(actual):
        if not math.isclose(expected, actual, rel_tol=rel_tol, abs_tol=1e-300):
            found.append(Finding("ir", path, f"{_number(actual)}, the golden has {_number(expected)}"
                                             f"{_percent(expected, actual)}",
                                 _excess(abs(actual - expected), rel_tol * max(abs(expected), abs(actual)))))
    elif expected != actual or type(expected) is not type(actual):
        found.append(Finding("ir", path, f"{_short(actual)}, the golden has {_short(expected)}", math.inf))


def _walk_list(expected: list, actual: list, path: str, rel_tol: float, found: list) -> None:
    named = all(isinstance(x, dict) and isinstance(x.get("name"), str) for x in expected + actual)
    if named and expected + actual:
        mine, theirs = {x["name"]: x for x in actual}, {x["name"]: x for x in expected}
        for name in theirs:
            if name not in mine:
                found.append(Finding("ir", f"{path}[{name}]", "gone (the golden has it)", math.inf))
            else:
                _walk(theirs[name], mine[name], f"{path}[{name}]", rel_tol, found)
        for name in mine:
            if name not in theirs:
                found.append(Finding("ir", f"{path}[{name}]", "new (not in the golden)", math.inf))
        if [x["name"] for x in expected if x["name"] in mine] != [x["name"] for x in actual if x["name"] in theirs]:
            found.append(Finding("ir", path, "the same items in another order", math.inf))
        return
    if len(expected) != len(actual):
        found.append(Finding("ir", path, f"{len(actual)} items, the golden has {len(expected)}", math.inf))
        return
    for k, (e, a) in enumerate(zip(expected, actual)):
        _walk(e, a, f"{path}[{item_name(e, k)}]", rel_tol, found)


def _is_number(value) -> bool:
    return isinstance(value, (int, float)) and not isinstance(value, bool)


def _number(value) -> str:
    """A number of the IR as a reader writes it: 12 significant digits (0.00196, not 0.0019600000000000004)."""
    return repr(float(f"{value:.12g}")) if isinstance(value, float) else repr(value)


def _percent(expected, actual) -> str:
    return f" ({100 * (actual - expected) / abs(expected):+.3g}%)" if expected else ""


def _short(value) -> str:
    text = repr(value)
    return text if len(text) <= 60 else text[:57] + "..."


def _excess(deviation: float, tol: float) -> float:
    return deviation / tol if tol > 0 else (math.inf if deviation > 0 else 0.0)


# ---- the trajectory -----------------------------------------------------------------------------------------

def compare_trajectory(golden, actual, tolerance: dict, energy_scale: float) -> list:
    if golden is None or actual is None:
        which = "the golden has no trajectory (record it: --update)" if golden is None else "no trajectory"
        return [Finding("trajectory", "trajectory", which, math.inf)]
    found = []
    times = np.asarray(golden["time"], float)
    got = np.asarray(actual["time"], float)
    if len(got) < len(times):
        end = f"{got[-1]:.6g} s" if len(got) else "its start"
        found.append(Finding("trajectory", "run", f"ended at {end}; the golden goes on to {times[-1]:.6g} s",
                             math.inf))
    n = min(len(times), len(got))
    if not np.allclose(times[:n], got[:n], rtol=0, atol=1e-9):
        return found + [Finding("trajectory", "sampling", "samples at other times than the golden's", math.inf)]
    for name in golden["bodies"]:
        if name not in actual["bodies"]:
            found.append(Finding("trajectory", f"body `{name}`", "gone (the golden has it)", math.inf))
            continue
        for key in QUANTITIES:
            g = np.asarray(golden["bodies"][name][key], float)[:n]
            a = np.asarray(actual["bodies"][name][key], float)[:n]
            deviation = _rotation_angle(g, a) if key == "orientation" else np.linalg.norm(a - g, axis=-1)
            found += _series("trajectory", f"{key} of `{name}`", times[:n], deviation, tolerance[key], UNITS[key])
    for name in actual["bodies"]:
        if name not in golden["bodies"]:
            found.append(Finding("trajectory", f"body `{name}`", "new (not in the golden)", math.inf))
    for key, tol, unit, scale in (("constraint_error", tolerance["constraint_error"], "m", 1.0),
                                  ("energy", tolerance["energy"], "of the energy scale", energy_scale)):
        deviation = np.abs(np.asarray(actual[key], float)[:n] - np.asarray(golden[key], float)[:n]) / scale
        found += _series("trajectory", key, times[:n], deviation, tol, unit)
    return found


def _rotation_angle(q1: np.ndarray, q2: np.ndarray) -> np.ndarray:
    """The angle of the rotation taking q1 to q2, (T,) rad: 2 atan2(|v|, |w|) of q1* q2 (q and -q alike)."""
    w1, v1, w2, v2 = q1[..., 0], q1[..., 1:], q2[..., 0], q2[..., 1:]
    # q1* q2 = (w1 w2 + v1.v2, w1 v2 - w2 v1 - v1 x v2)
    w = w1 * w2 + np.sum(v1 * v2, axis=-1)
    v = w1[..., None] * v2 - w2[..., None] * v1 - np.cross(v1, v2)
    return 2.0 * np.arctan2(np.linalg.norm(v, axis=-1), np.abs(w))


def _series(section: str, what: str, times, deviation, tol: float, unit: str) -> list:
    """One finding for a quantity sampled over time: its largest deviation, when and since when it is off."""
    deviation = np.where(np.isfinite(deviation), deviation, np.inf)
    over = np.flatnonzero(deviation > tol)
    if len(over) == 0:
        return []
    worst = int(np.argmax(deviation))
    return [Finding(section, what, f"off by up to {deviation[worst]:.3g} {unit} (at t = {times[worst]:.6g} s; "
                                   f"beyond {tol:.3g} from t = {times[over[0]]:.6g} s)",
                    _excess(float(deviation[worst]), tol))]


# ---- events, report, audio ----------------------------------------------------------------------------------

def compare_events(golden: dict, actual: dict, tolerance: dict) -> list:
    found = []
    if golden.get("impact_count", 0) != actual.get("impact_count", 0):
        found.append(Finding("events", "impacts", f"{actual.get('impact_count', 0)}, the golden has "
                                                  f"{golden.get('impact_count', 0)}", math.inf))
    for k, (g, a) in enumerate(zip(golden.get("impacts", []), actual.get("impacts", []))):
        what = f"impact #{k + 1} ({' and '.join(g['bodies'])} at {g['time']:.6g} s)"
        if g["bodies"] != a["bodies"]:
            found.append(Finding("events", what, f"between {' and '.join(a['bodies'])} now", math.inf))
            break  # the rest are shifted: one finding says it
        found += _scalar("events", f"{what} time", g["time"], a["time"], tolerance["event_time"], "s")
        found += _relative("events", f"{what} impulse", g["impulse"], a["impulse"], tolerance["impulse"], "N s")
    theirs = {" ".join(c["bodies"]): c for c in golden.get("contacts", [])}
    mine = {" ".join(c["bodies"]): c for c in actual.get("contacts", [])}
    for pair in sorted(set(theirs) | set(mine)):
        if pair not in mine or pair not in theirs:
            found.append(Finding("events", f"contact of {pair.replace(' ', ' and ')}",
                                 "gone" if pair not in mine else "new", math.inf))
            continue
        g, a = theirs[pair], mine[pair]
        what = f"contact of {pair.replace(' ', ' and ')}"
        if g["frames"] != a["frames"]:
            found.append(Finding("events", what, f"{a['frames']} frames, the golden has {g['frames']}", math.inf))
        for key in ("first", "last"):
            found += _scalar("events", f"{what} {key} frame", g[key], a[key], tolerance["event_time"], "s")
        found += _relative("events", f"{what} total impulse", g["impulse"], a["impulse"], tolerance["impulse"], "N s")
    return found


def compare_report(golden: dict, actual: dict, tolerance: dict, energy_scale: float) -> list:
    found = []
    numeric = {"max_constraint_error": (tolerance["constraint_error"], "m"),
               "constraint_error_settled": (tolerance["constraint_error"], "m"),
               "simulated_time": (1e-9, "s")}
    for key in sorted(set(golden) | set(actual)):
        g, a = golden.get(key), actual.get(key)
        if key == "energy_start" and _is_number(g) and _is_number(a):
            found += _scalar("report", key, g / energy_scale, a / energy_scale, tolerance["energy"],
                             "of the energy scale")
        elif key == "energy_drift_relative" and _is_number(g) and _is_number(a):
            # relative to the report's yardstick already: compared as is, or relative to itself when above 1
            found += _scalar("report", key, g / max(1.0, abs(g)), a / max(1.0, abs(g)), tolerance["energy"], "")
        elif key == "step" and _is_number(g) and _is_number(a):
            found += _relative("report", key, g, a, 1e-12, "s")
        elif key in numeric and _is_number(g) and _is_number(a):
            found += _scalar("report", key, g, a, *numeric[key])
        elif g != a:
            found.append(Finding("report", key, f"{_short(a)}, the golden has {_short(g)}", math.inf))
    return found


def compare_audio(golden, actual, tolerance: dict) -> list:
    if golden is None and actual is None:
        return []
    if golden is None or actual is None:
        return [Finding("audio", "sound", "new (the golden is silent)" if golden is None else "gone", math.inf)]
    found = []
    for key in ("rate", "channels"):
        if golden[key] != actual[key]:
            found.append(Finding("audio", key, f"{actual[key]}, the golden has {golden[key]}", math.inf))
    found += _scalar("audio", "length", golden["seconds"], actual["seconds"], 1e-6, "s")
    for key in ("peak_db", "rms_db"):
        found += _scalar("audio", key.replace("_db", " level"), golden[key], actual[key], tolerance["level"], "dB")
    found += _onsets(golden["onsets"], actual["onsets"], tolerance["onset"])
    found += _peaks(golden["peaks"], actual["peaks"], tolerance)
    return found


def _onsets(golden: list, actual: list, tol: float) -> list:
    if len(golden) != len(actual):
        missing = [t for t in golden if not any(abs(t - a) <= tol for a in actual)]
        extra = [t for t in actual if not any(abs(t - g) <= tol for g in golden)]
        detail = f"{len(actual)}, the golden has {len(golden)}"
        if missing:
            detail += f"; gone: {', '.join(f'{t:.3f} s' for t in missing[:5])}"
        if extra:
            detail += f"; new: {', '.join(f'{t:.3f} s' for t in extra[:5])}"
        return [Finding("audio", "onsets", detail, math.inf)]
    shifts = np.abs(np.asarray(actual) - np.asarray(golden))
    if len(shifts) and shifts.max() > tol:
        k = int(np.argmax(shifts))
        return [Finding("audio", f"onset #{k + 1} (at {golden[k]:.4f} s)", f"moved by {shifts[k] * 1e3:.3g} ms "
                                                                           f"(tolerance {tol * 1e3:.3g} ms)",
                        _excess(float(shifts[k]), tol))]
    return []


def _peaks(golden: list, actual: list, tolerance: dict) -> list:
    found = []
    for peak in golden:
        f0 = peak["frequency"]
        near = [p for p in actual if abs(p["frequency"] - f0) <= tolerance["frequency"] * f0]
        what = f"spectral peak at {f0:.1f} Hz ({peak['level']:.1f} dB)"
        if not near:
            closest = min(actual, key=lambda p: abs(p["frequency"] - f0), default=None)
            detail = "gone" + (f"; the closest is at {closest['frequency']:.1f} Hz" if closest else "")
            found.append(Finding("audio", what, detail, math.inf))
            continue
        found += _scalar("audio", f"{what} level", peak["level"], near[0]["level"], tolerance["level"], "dB")
    return found


def _scalar(section: str, what: str, golden: float, actual: float, tol: float, unit: str) -> list:
    deviation = abs(actual - golden) if math.isfinite(actual - golden) else math.inf
    if deviation <= tol:
        return []
    unit = f" {unit}" if unit else ""
    return [Finding(section, what, f"{actual:.6g}, the golden has {golden:.6g} (off by {deviation:.3g}{unit}, "
                                   f"tolerance {tol:.3g})", _excess(deviation, tol))]


def _relative(section: str, what: str, golden: float, actual: float, tol: float, unit: str) -> list:
    deviation = abs(actual - golden) / max(abs(golden), 1e-12)
    if deviation <= tol:
        return []
    return [Finding(section, what, f"{actual:.6g} {unit}, the golden has {golden:.6g} ({deviation:.3g} relative, "
                                   f"tolerance {tol:.3g})", _excess(deviation, tol))]
