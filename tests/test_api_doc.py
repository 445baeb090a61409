"""docs/api.md runs as written: each ```python block, in order, in one namespace, from the repository's root (the
paths it names are relative to it)."""

from __future__ import annotations

import os
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


def python_blocks(document: Path) -> list:
    return re.findall(r"```python\n(.*?)```", document.read_text(encoding="utf-8"), re.S)


def test_the_embedding_api_runs_as_documented(capsys):
    blocks = python_blocks(ROOT / "docs" / "api.md")
    assert len(blocks) >= 3
    namespace: dict = {}
    here = os.getcwd()
    os.chdir(ROOT)
    try:
        for block in blocks:
            exec(compile(block, "docs/api.md", "exec"), namespace)  # noqa: S102 (the documentation's own code)
    finally:
        os.chdir(here)
    assert namespace["sim"].plan.scene.name and namespace["result"].error is None
    assert namespace["sim"].overrides == {"length": "2 m"}  # set_parameter re-planned the scene with the new value
