"""Golden files for any scene: `isaac golden SCENE... [--update]`, the pytest plugin, and this API.

    outcome = check_scene("swing.isaac")                  # against swing.golden/: outcome.status "pass" or
    outcome = check_scene("swing.isaac", update=True)     # "mismatch" (outcome.findings); or (re)write them
    print(outcome.text())

The stages, one module each: settings (run options and tolerances: the defaults, then swing.golden.toml) ->
record (load the scene, run it, keep what a golden keeps) -> compare (each quantity against the stored golden,
within its tolerance) -> the text of the outcome: what moved, and by how much. store.py reads and writes the
files. A problem in the scene or in the TOML is a SceneError (exit 2), as for every command.
"""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

from isaac_ir.diagnostics import Diagnostic, SceneError, SourceCache, SourcePos, counted
from isaac.golden.compare import Finding, GoldenShapeError, compare, golden_section, golden_times
from isaac.golden.record import make_record
from isaac.golden.settings import MAX_GOLDEN_SAMPLES, check_sample_count, load_settings, settings_path
from isaac.golden.store import golden_folder, has_golden, read_golden, write_golden

__all__ = ["Outcome", "check_scene", "golden_folder", "has_golden", "Finding"]


@dataclass
class Outcome:
    scene: Path
    status: str  # pass | mismatch | written | missing
    findings: list = field(default_factory=list)  # Finding, worst first (a mismatch; or what --update changed)
    notes: list = field(default_factory=list)  # things to know that are not mismatches (positions moved, ...)
    summary: str = ""  # what the goldens hold, e.g. "ir, 101 samples of 1 body, 2 impacts, report, audio"

    @property
    def ok(self) -> bool:
        return self.status in ("pass", "written")

    def text(self, limit: int = 20) -> str:
        """The readable report: one line of outcome, then what moved and by how much, worst first."""
        folder = golden_folder(self.scene).name
        head = {"pass": f"{self.scene}: golden ok ({self.summary})",
                "written": f"{self.scene}: goldens written to {folder}/ ({self.summary})",
                "missing": f"{self.scene}: no golden files ({folder}/); record them with "
                           f"`isaac golden {self.scene} --update`",
                "mismatch": f"{self.scene}: golden mismatch: {len(self.findings)} "
                            f"{'quantity' if len(self.findings) == 1 else 'quantities'} outside "
                            f"{'its tolerance' if len(self.findings) == 1 else 'their tolerances'}"}[self.status]
        lines = [head] + [f"  note: {note}" for note in self.notes]
        shown = self.findings[:limit]
        if self.status == "written" and shown:
            lines.append("  changed from the previous goldens:")
        lines += [f"  {f.section:<10} {f.what}: {f.detail}" for f in shown]
        if len(self.findings) > limit:
            lines.append(f"  ... and {len(self.findings) - limit} more")
        if self.status == "mismatch":
            toml = settings_path(self.scene)
            lines.append(f"  tolerances: {toml.name if toml.is_file() else 'the defaults'} (docs/golden.md); "
                         f"if the change is meant: isaac golden {self.scene} --update")
        return "\n".join(lines)


def check_scene(path, update: bool = False, overrides: dict | None = None,
                sources: SourceCache | None = None) -> Outcome:
    """Record the scene and compare it with its goldens, or (update) write them. SceneError for a bad scene."""
    from isaac_lang.load import load_scene

    path = Path(path)
    sources = sources if sources is not None else SourceCache()
    settings = load_settings(path, sources).with_overrides(overrides or {})
    golden = read_golden(path) if has_golden(path) else None
    if golden is None and not update:
        return Outcome(path, "missing")
    loaded = load_scene(path, settings.overrides, sources=sources)
    check_sample_count(settings, loaded.scene.time.start, loaded.scene.time.end)
    try:
        times = None if update or not golden else golden_times(golden, MAX_GOLDEN_SAMPLES)
    except GoldenShapeError as error:
        raise _shape_error(path, error) from None
    record = make_record(loaded.scene, path.parent, settings, times)
    try:
        findings = compare(golden, record.sections, settings.tolerance, record.energy_scale) if golden else []
        notes = _notes(golden, record, settings)
    except GoldenShapeError as error:
        if not update:
            raise _shape_error(path, error) from None
        findings, notes = [], []  # the goldens that could not be compared are written anew
    outcome = Outcome(path, "pass" if not findings else "mismatch", findings, notes, _summary(record.sections))
    if update:
        write_golden(path, record.sections)
        outcome.status, outcome.notes = "written", []
    return outcome


def _shape_error(scene: Path, error: GoldenShapeError) -> SceneError:
    """A golden file of the wrong shape, positioned at the file (whose text is not quoted)."""
    where = SourcePos(f"{golden_folder(scene).name}/{error.section}.json", 1, 1)
    return SceneError([Diagnostic(f"the golden file does not hold what `isaac golden --update` writes: "
                                  f"{error.detail}", where,
                                  f"record the goldens again with `isaac golden {scene} --update`")])


def _notes(golden: dict | None, record, settings) -> list:
    """What differs and is not compared: positions; the options the goldens were made with."""
    if not golden:
        return []
    with golden_section("positions"):
        return _notes_of(golden, record, settings)


def _notes_of(golden: dict, record, settings) -> list:
    notes = []
    old, new = dict(golden.get("positions", {})), record.sections["positions"]
    moved = sorted(k for k in set(old) | set(new) if old.get(k) != new.get(k))
    if moved:
        notes.append(f"{len(moved)} source position{'s' if len(moved) > 1 else ''} moved ({', '.join(moved[:3])}"
                     f"{', ...' if len(moved) > 3 else ''}); positions are kept apart and not compared")
    with golden_section("meta"):
        made_with = dict(golden.get("meta") or {}).get("run")
        if made_with is not None and made_with != settings.run_record():
            notes.append(f"the goldens were made with {_options(dict(made_with))}; this check runs with "
                         f"{_options(settings.run_record())}")
    return notes


def _options(run: dict) -> str:
    parts = [f"--set {k}={v}" for k, v in (run.get("set") or {}).items()]
    parts += [f"--{k} {run[k]:g}" if isinstance(run[k], float) else f"--{k} {run[k]}"
              for k in ("until", "solver", "step") if run.get(k) is not None]
    return " ".join(parts) or "the scene's own settings"


def _summary(sections: dict) -> str:
    parts = ["ir"]
    trajectory = sections.get("trajectory")
    if trajectory is not None:
        bodies = len(trajectory["bodies"])
        parts.append(f"{len(trajectory['time'])} samples of {bodies} bod{'y' if bodies == 1 else 'ies'}")
    events = sections.get("events")
    if events is not None:
        parts.append(f"{events['impact_count']} impact{'' if events['impact_count'] == 1 else 's'}"
                     + (f", {counted(len(events['contacts']), 'contact pair')}" if events["contacts"] else ""))
    if "report" in sections:
        parts.append("report")
    if "audio" in sections:
        audio = sections["audio"]
        parts.append(f"audio: {counted(len(audio['onsets']), 'onset')}, {counted(len(audio['peaks']), 'spectral peak')}")
    return ", ".join(parts)
