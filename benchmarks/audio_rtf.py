"""Audio: the real-time factor of the audio graph, from benchmarks/bench_audio.py (the audio engineer's
benchmark): a synthetic scene of impacts, scraping and wind rendered without simulating, and scenes/chimes.isaac
run as `isaac run` runs it (full mode only). Writes audio.csv.
"""
from __future__ import annotations

import math
from pathlib import Path

from . import common

SECONDS, QUICK_SECONDS = 20.0, 3.0


def run(quick: bool = False, out: Path | None = None) -> dict:
    rows = []
    try:
        from . import bench_audio
    except Exception as error:  # noqa: BLE001 (no audio stage yet, or soundfile missing)
        rows.append({"case": "audio", "status": f"not measured: {type(error).__name__}: {error}"})
    else:
        jobs = [("impacts + scrape", lambda: bench_audio.bench_synthetic(QUICK_SECONDS if quick else SECONDS))]
        if not quick and (common.SCENES / "chimes.isaac").is_file():
            jobs.append(("chimes", bench_audio.bench_chimes))
        for label, job in jobs:
            try:
                row = {**job(), "status": "ok"}
            except Exception as error:  # noqa: BLE001
                row = {"case": label, "status": f"failed: {type(error).__name__}: {error}"}
            rows.append(row)
            common.log(f"  {row.get('case', label):<18} RTF {row.get('rtf', math.nan):.1f}  "
                       f"with simulation {row.get('rtf_with_simulation', math.nan):.1f}  [{row['status']}]")
    if out is not None:
        common.write_csv(out / "audio.csv", rows)
    return {"rows": rows}
