"""The optional extras a plan needs, checked when the plan is made (never after the simulation).

    check_extras(plan, plots=True)      # raises MissingExtra (a SceneError: exit 2) naming what to install

Each extra is imported only by the scenes and options that need it (docs/design/architecture.md, the plan): python-fcl
for pairs without a closed-form test (meshes, cylinders against boxes), soundfile for sound (a core dependency, but its
C library may still be missing), matplotlib for `--plots`, sounddevice for `--mic` (checked where the microphone is
opened, isaac_runtime.signals).
"""
from __future__ import annotations

import importlib

from isaac_ir.diagnostics import Diagnostic, SceneError


class MissingExtra(SceneError):
    """An optional package this run needs is not installed (exit 2, like any problem the user can fix)."""


# module -> (pip name, extra of isaac that installs it)
EXTRAS = {
    "fcl": ("python-fcl", "mesh"),
    "soundfile": ("soundfile", "sound"),
    "matplotlib": ("matplotlib", "plots"),
    "sounddevice": ("sounddevice", "mic"),
}


def check_extras(plan, plots: bool = False) -> None:
    """Import, now, every optional module the plan (and --plots) will use; MissingExtra names each missing one."""
    check_modules(needed_modules(plan, plots))


def check_modules(needed: list) -> None:
    """needed: (module, why) pairs; MissingExtra for those that cannot be imported."""
    problems = [p for p in (_importable(module, why) for module, why in needed) if p is not None]
    if problems:
        raise MissingExtra(problems)


def needed_modules(plan, plots: bool = False) -> list:
    """(module, why) for each optional module this run will import."""
    needed = []
    collisions = getattr(plan, "collisions", None)
    fcl_bodies = [int(i) for i in getattr(collisions, "fcl_bodies", ())] if collisions is not None else []
    if fcl_bodies:
        names = [plan.names[i] for i in fcl_bodies[:5]]
        more = ", ..." if len(fcl_bodies) > 5 else ""
        needed.append(("fcl", f"bodies {', '.join(f'`{n}`' for n in names)}{more} collide in pairs without a "
                              f"closed-form test (meshes, cylinders against boxes)"))
    if getattr(plan, "audio", None) is not None:
        needed.append(("soundfile", "the scene has sounds (audio.wav)"))
    if plots:
        needed.append(("matplotlib", "--plots"))
    return needed


def _importable(module: str, why: str) -> Diagnostic | None:
    try:
        importlib.import_module(module)
    except ImportError as error:  # also a package whose C library is missing (soundfile raises OSError: below)
        return _missing(module, why, error)
    except OSError as error:
        return _missing(module, why, error)
    return None


def _missing(module: str, why: str, error: Exception) -> Diagnostic:
    package, extra = EXTRAS[module]
    return Diagnostic(f"this run needs the optional package {package} ({why}), which cannot be imported: {error}",
                      None, f"install it with: pip install 'isaac[{extra}]'  (or: pip install {package})")
