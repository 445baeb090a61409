"""Regenerate the golden IR of every example scene: scenes/golden/<name>.ir.json.

    python tests/lang/regen_goldens.py

Run it after a deliberate change to the IR or to a scene, then review the diff (git diff scenes/golden) before
committing: the goldens are the record of what each scene means.
"""
from __future__ import annotations

import sys
from pathlib import Path

from isaac_lang import ir
from isaac_lang.load import load_scene

ROOT = Path(__file__).resolve().parents[2]
SCENES = ROOT / "scenes"
GOLDEN = SCENES / "golden"


def golden_path(scene: Path) -> Path:
    return GOLDEN / (scene.name[: -len(".isaac")] + ".ir.json")


def canonical(scene: Path) -> str:
    return ir.to_json(load_scene(scene).scene) + "\n"


def main() -> int:
    GOLDEN.mkdir(exist_ok=True)
    for scene in sorted(SCENES.glob("*.isaac")):
        target = golden_path(scene)
        text = canonical(scene)
        changed = not target.exists() or target.read_text(encoding="utf-8") != text
        target.write_text(text, encoding="utf-8")
        print(f"{'wrote' if changed else 'same '} {target.relative_to(ROOT)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
