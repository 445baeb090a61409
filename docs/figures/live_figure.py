"""Make docs/figures/live.png, and measure the figures docs/live.md quotes: `isaac live` of the mobile blown by
scenes/assets/breath.wav with its page open in headless Chromium (photographed while the breath blows), then the
chimes; each run's realtime figures from its report.json.

    python docs/figures/live_figure.py        # needs chromium; writes docs/figures/live.png, prints the figures
"""
from __future__ import annotations

import json
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT))

from tests.cdp import Browser, chromium  # noqa: E402
from tests.runtime.test_live import LiveRun, report  # noqa: E402

FIGURE = ROOT / "docs" / "figures" / "live.png"
SHOT_AT = 4.5  # s of scene time: the second breath at its loudest


def mobile(out: Path) -> dict:
    with Browser() as browser, LiveRun(["scenes/mobile.isaac", "--mic", "scenes/assets/breath.wav", "--until", "5",
                                        "--out", str(out)]) as live:
        page = browser.open(live.address(), size=(960, 600))
        page.wait_for(f"Number(document.body.dataset.t) >= {SHOT_AT}", timeout=300, every=0.01)
        page.screenshot(FIGURE)
        code = live.wait()
    assert code == 0, live.stderr
    return report(out)["realtime"]


def chimes(out: Path) -> dict:
    with LiveRun(["scenes/chimes.isaac", "--until", "5", "--out", str(out)]) as live:
        assert live.wait() == 0, live.stderr
    return report(out)["realtime"]


def figures(name: str, realtime: dict) -> str:
    keep = ("input_latency_ms", "max_lag_ms", "frames", "frames_late", "frames_dropped", "real_time_factor",
            "work_per_frame_mean_ms", "work_per_frame_max_ms", "slowed")
    picked = {k: realtime[k] for k in keep}
    if realtime["input"]:
        picked.update({k: realtime["input"][k] for k in ("latency_p95_ms", "latency_max_ms", "to_pose_max_ms")})
    return f"{name}: {json.dumps(picked, indent=1)}"


def main() -> int:
    if chromium() is None:
        print("needs Chromium (apt-get install -y chromium)", file=sys.stderr)
        return 2
    with tempfile.TemporaryDirectory(prefix="isaac-live-figure-") as folder:
        print(figures("mobile", mobile(Path(folder) / "mobile")))
        print(figures("chimes", chimes(Path(folder) / "chimes")))
    print(f"wrote {FIGURE.relative_to(ROOT)} at {time.strftime('%H:%M:%S')}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
