"""`isaac golden SCENE... [--update] [--set NAME=VALUE ...]`: check (or record) the goldens of each scene.

Exit codes: 0 every scene within its tolerances (or written), 3 a mismatch in at least one, 2 a problem with a
scene, its settings or its goldens (a missing golden included: record it with --update), 1 a bug. Each scene's
outcome is printed as it is known, so a long list shows its progress.
"""
from __future__ import annotations

import sys
from pathlib import Path

from isaac_ir.diagnostics import Diagnostic, SceneError, SourceCache
from isaac.golden.store import golden_folder
from isaac.writable import check_output_folder

EXIT_OK, EXIT_SCENE, EXIT_MISMATCH = 0, 2, 3


def run_golden(scenes: list, update: bool, overrides: dict, verbosity: int, format_error) -> int:
    """Each scene in turn; the worst exit code (2 before 3: a scene that cannot be checked is not a pass)."""
    from isaac.golden import check_scene

    codes = []
    for name in scenes:
        path = Path(name)
        sources = SourceCache()
        try:
            if not path.is_file():
                raise SceneError([Diagnostic(f"no such scene file: {path}", None)])
            if update:  # refused before the run, as run and export refuse their --out
                check_output_folder(golden_folder(path), "--update: the golden folder")
            outcome = check_scene(path, update=update, overrides=overrides, sources=sources)
        except SceneError as error:
            print(format_error(error, str(path), sources), file=sys.stderr)
            codes.append(EXIT_SCENE)
            continue
        except ValueError as error:  # a golden file that cannot be read
            print(f"{path}: error: {error}\nhint: record it again with `isaac golden {path} --update`",
                  file=sys.stderr)
            codes.append(EXIT_SCENE)
            continue
        codes.append(_say(outcome, verbosity))
    return EXIT_SCENE if EXIT_SCENE in codes else (EXIT_MISMATCH if EXIT_MISMATCH in codes else EXIT_OK)


def _say(outcome, verbosity: int) -> int:
    if outcome.status == "missing":
        print(f"{outcome.scene}: error: no golden files ({outcome.scene.stem}.golden/)\n"
              f"hint: record them with `isaac golden {outcome.scene} --update`", file=sys.stderr)
        return EXIT_SCENE
    if outcome.status == "mismatch":
        print(outcome.text(limit=60 if verbosity <= 0 else 1000), file=sys.stdout)
        return EXIT_MISMATCH
    if verbosity >= -1:
        print(outcome.text(limit=20 if verbosity > 0 else 5))
    return EXIT_OK
