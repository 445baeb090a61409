"""`isaac watch`, driven as a user would: a scripted editing session on a copy of the pendulum.

Saves go through a temporary file and a rename, as editors do. The session checks that a valid edit gives a new
result within a second of the save (the first frames; the run then goes on), that a broken edit prints its
diagnostic with file, line and column while the last good result stays (on the live page too), that the fix is
taken, that editing an included file reloads, that an edit which leaves the IR unchanged does not re-run, that
the process stays alive throughout, and that Ctrl-C ends it cleanly with exit code 0.
"""
from __future__ import annotations

import json
import os
import queue
import re
import shutil
import signal
import subprocess
import sys
import threading
import time
import urllib.request
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
PENDULUM = (ROOT / "scenes" / "pendulum.isaac").read_text()
# the bound on save-to-result latency for the pendulum
LATENCY_BOUND = 1.0


class Session:
    """An `isaac watch` process, its output read line by line in the background."""

    def __init__(self, scene: Path, *args: str):
        self.scene = scene
        self.lines: list = []
        self._queue: queue.Queue = queue.Queue()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        self.process = subprocess.Popen([sys.executable, "-m", "isaac_lang.cli", "watch", scene.name, *args],
                                        cwd=scene.parent, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True, env=env)
        self._reader = threading.Thread(target=self._read, daemon=True)
        self._reader.start()

    def _read(self):
        for line in self.process.stdout:
            self._queue.put(line.rstrip("\n"))

    def wait_for(self, pattern: str, timeout: float = 30.0) -> re.Match:
        """The first new line matching pattern (a regex); fails with the output so far after timeout."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            try:
                line = self._queue.get(timeout=0.05)
            except queue.Empty:
                assert self.alive(), "isaac watch exited:\n" + "\n".join(self.lines)
                continue
            self.lines.append(line)
            match = re.search(pattern, line)
            if match:
                return match
        raise AssertionError(f"no line matching {pattern!r} within {timeout} s:\n" + "\n".join(self.lines))

    def save(self, text: str, path: Path | None = None) -> None:
        """Save as an editor does: write a temporary file beside it, then rename it over the old one."""
        path = path or self.scene
        temporary = path.with_name(f".{path.name}.swp~")
        temporary.write_text(text)
        os.replace(temporary, path)

    def alive(self) -> bool:
        return self.process.poll() is None

    def stop(self) -> int:
        """Ctrl-C; the exit code. Every line the process wrote is in self.lines afterwards."""
        if self.alive():
            self.process.send_signal(signal.SIGINT)
        try:
            return self.process.wait(timeout=15)
        finally:
            if self.alive():
                self.process.kill()
            self._reader.join(timeout=5)
            while not self._queue.empty():
                self.lines.append(self._queue.get())


def status(url: str) -> dict:
    with urllib.request.urlopen(url + "status.json", timeout=5) as response:
        return json.loads(response.read())


@pytest.fixture
def session(tmp_path):
    (tmp_path / "angles.isaac").write_text("let theta0 = 60 deg\n")
    scene = tmp_path / "pendulum.isaac"
    # long enough (3000 s: about ten seconds of stepping) that a result is still running when the next save comes
    scene.write_text(PENDULUM.replace("let theta0 = 60 deg", 'include "angles.isaac"')
                     .replace("time 0 s .. 10 s", "time 0 s .. 3000 s").replace("frames 100 Hz", "frames 5 Hz"))
    watch = Session(scene, "--out", str(tmp_path / "out"), "--port", "0")
    yield watch
    watch.stop()


def test_a_scripted_editing_session(session, tmp_path):
    url = session.wait_for(r"live viewer at (http://127\.0\.0\.1:\d+/)").group(1)
    session.wait_for(r"result #1: first frames")
    text = session.scene.read_text()

    # a valid edit: a new result, first frames within the bound
    session.save(text.replace("mass 1 kg", "mass 2 kg"))
    latency = float(session.wait_for(r"result #2: first frames ([\d.]+) s after the save").group(1))
    assert latency < LATENCY_BOUND, f"save-to-result latency {latency} s"
    assert status(url)["result"] == 2
    viewer = (tmp_path / "out" / "viewer.html").read_text()
    assert '"result":2' in viewer

    # a broken edit: the diagnostic with its position; result #2 stays (and is not even stopped)
    session.save(text.replace("mass 1 kg", "mass 1 kilo"))
    session.wait_for(r"^pendulum\.isaac:\d+:\d+: error: ")
    session.wait_for(r"scene error: the last good result \(#2\) stays")
    page = status(url)
    assert page["state"] == "error" and page["result"] == 2 and "pendulum.isaac:" in page["diagnostic"]
    assert '"result":2' in (tmp_path / "out" / "viewer.html").read_text()
    assert session.alive()

    # the fix
    session.save(text.replace("mass 1 kg", "mass 3 kg"))
    session.wait_for(r"result #2 stopped: a newer save replaces it")
    latency = float(session.wait_for(r"result #3: first frames ([\d.]+) s after the save").group(1))
    assert latency < LATENCY_BOUND
    assert status(url)["state"] == "running" and status(url)["diagnostic"] is None

    # an included file is watched too
    session.save("let theta0 = 30 deg\n", tmp_path / "angles.isaac")
    session.wait_for(r"angles\.isaac: result #4: running")

    # a comment changes nothing in the IR: the running result stays
    session.save(session.scene.read_text() + "\n# swings\n")
    session.wait_for(r"no change to the scene \(same IR\); result #4 stays")
    assert session.alive()

    assert session.stop() == 0
    output = "\n".join(session.lines)
    assert "result #4 stopped: the watch ends" in output and output.endswith("stopped watching")
    assert "Traceback" not in output


def test_a_complete_run_writes_the_outputs_and_a_bad_start_waits_for_a_fix(tmp_path):
    scene = tmp_path / "short.isaac"
    scene.write_text(PENDULUM.replace("time 0 s .. 10 s", "time 0 s .. 0.2 s").replace("mass 1 kg", "mass 1 kgg"))
    watch = Session(scene, "--out", str(tmp_path / "out"), "--no-serve", "--poll")
    try:
        watch.wait_for(r"short\.isaac:\d+:\d+: error:")
        watch.wait_for(r"scene error: no result yet")
        watch.save(scene.read_text().replace("mass 1 kgg", "mass 1 kg"))
        watch.wait_for(r"result #1: complete ([\d.]+) s after the save")
        out = tmp_path / "out"
        assert {"trajectory.npz", "events.json", "ir.json", "report.json", "viewer.html"} <= {
            p.name for p in out.iterdir()}
        assert json.loads((out / "report.json").read_text())["frames"] == 21
    finally:
        assert watch.stop() == 0


def test_watch_of_a_missing_file_is_a_usage_error(tmp_path):
    result = subprocess.run([sys.executable, "-m", "isaac_lang.cli", "watch", str(tmp_path / "nope.isaac")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "no such scene file" in result.stderr


@pytest.mark.skipif(shutil.which("isaac") is None and not (Path(sys.executable).parent / "isaac").exists(),
                    reason="the isaac command is not installed")
def test_watch_is_a_command(tmp_path):
    isaac = shutil.which("isaac") or str(Path(sys.executable).parent / "isaac")
    result = subprocess.run([isaac, "watch", "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and "--port" in result.stdout


def test_the_tutorial_steps_load_and_its_mistake_is_the_one_it_shows():
    from isaac_lang.diagnostics import SceneError
    from isaac_lang.load import load_text

    text = (ROOT / "docs" / "tutorial.md").read_text()
    steps = re.findall(r"^```isaac\n(.*?)^```", text, re.S | re.M)
    assert len(steps) == 4
    for step in (steps[0], steps[1], steps[3]):
        assert load_text(step, "swing.isaac").scene.name == "swing"
    with pytest.raises(SceneError) as error:
        load_text(steps[2], "swing.isaac")
    shown = error.value.format()
    assert shown.splitlines()[0] in text  # the transcript in the tutorial is what Isaac says
    assert "did you mean `bob`?" in shown
