"""Make the tutorial's screenshots by doing the tutorial: save each step of docs/tutorial.md into a watched file
and photograph the live viewer with headless Chromium.

    python docs/figures/make_tutorial_figures.py          # needs chromium; writes docs/figures/tutorial-*.png

The ```isaac blocks of docs/tutorial.md are the steps, in order (each is the whole file at that step).
The terminal output of the session is printed, so the tutorial's transcripts can be checked against it.
"""
from __future__ import annotations

import os
import re
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent
TUTORIAL = HERE.parent / "tutorial.md"
FLAGS = ["--headless", "--no-sandbox", "--disable-gpu", "--disable-quic", "--no-first-run",
         "--disable-background-networking", "--disable-component-update", "--disable-sync", "--hide-scrollbars",
         "--mute-audio"]


def steps() -> list:
    return re.findall(r"^```isaac\n(.*?)^```", TUTORIAL.read_text(), re.S | re.M)


def shoot(url: str, name: str, size=(900, 520), budget_ms: int = 1500) -> None:
    chromium = shutil.which("chromium") or shutil.which("chromium-browser") or shutil.which("google-chrome")
    with tempfile.TemporaryDirectory() as profile:
        subprocess.run([chromium, *FLAGS, f"--user-data-dir={profile}", f"--window-size={size[0]},{size[1]}",
                        f"--virtual-time-budget={budget_ms}", f"--screenshot={HERE / name}", url],
                       capture_output=True, timeout=120)
    print(f"  -> {HERE / name}")


class Watch:
    def __init__(self, folder: Path):
        self.process = subprocess.Popen([sys.executable, "-m", "isaac.cli", "watch", "swing.isaac",
                                         "--port", "0"], cwd=folder, stdout=subprocess.PIPE,
                                        stderr=subprocess.STDOUT, text=True, env=dict(os.environ, PYTHONUNBUFFERED="1"))

    def until(self, pattern: str, timeout: float = 300) -> re.Match:
        deadline = time.monotonic() + timeout
        for line in self.process.stdout:
            print("  | " + line.rstrip())
            match = re.search(pattern, line)
            if match:
                return match
            if time.monotonic() > deadline:
                break
        raise SystemExit(f"no {pattern!r} from isaac watch")


def main() -> None:
    blocks = steps()
    with tempfile.TemporaryDirectory(prefix="isaac-tutorial-") as tmp:
        folder = Path(tmp)
        scene = folder / "swing.isaac"
        scene.write_text("")
        watch = Watch(folder)
        url = watch.until(r"live viewer at (\S+)").group(1)
        watch.until(r"scene error")

        def save(text: str) -> None:
            temporary = folder / ".swing.isaac~"
            temporary.write_text(text)
            os.replace(temporary, scene)

        save(blocks[0])  # a falling ball
        watch.until(r"result #1: complete")
        shoot(url + "#t=0.35", "tutorial-1-falling.png")
        save(blocks[1])  # nailed: it swings
        watch.until(r"result #2: complete")
        shoot(url + "#t=0.45", "tutorial-2-swinging.png")
        save(blocks[2])  # a typo
        watch.until(r"scene error")
        shoot(url + "#t=0.45", "tutorial-3-error.png")
        save(blocks[3])  # the bell and its sound
        watch.until(r"result #3: complete")
        shoot(url + "#t=0.66", "tutorial-4-sounding.png")
        watch.process.send_signal(signal.SIGINT)
        watch.until(r"stopped watching")


if __name__ == "__main__":
    main()
