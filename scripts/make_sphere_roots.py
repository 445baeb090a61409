"""Regenerate runtime/audio/sphere_roots.py's table from the solver it caches (audio/modal.py solve_sphere_roots):
`python scripts/make_sphere_roots.py` after changing the search there."""

import pathlib
import re

from isaac_runtime.audio.modal import solve_sphere_roots

TABLE = pathlib.Path(__file__).resolve().parent.parent / "runtime" / "audio" / "sphere_roots.py"


def table_text() -> str:
    """SPHERE_ROOTS for Poisson's ratios 0.00, 0.01, ..., 0.49."""
    lines = [f"    {round(k / 100, 4)!r}: {solve_sphere_roots(round(k / 100, 4))!r}," for k in range(50)]
    return "SPHERE_ROOTS = {\n" + "\n".join(lines) + "\n}\n"


if __name__ == "__main__":
    text = TABLE.read_text()
    TABLE.write_text(re.sub(r"SPHERE_ROOTS = \{.*?\n\}\n", lambda m: table_text(), text, count=1, flags=re.S))
