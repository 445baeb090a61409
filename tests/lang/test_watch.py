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

    def __init__(self, scene: Path, *args: str, cwd: Path | None = None, launch=("-m", "isaac.cli")):
        """Watch scene from cwd (default: the scene's folder); launch: how python starts the command."""
        self.scene = scene
        self.lines: list = []
        self._queue: queue.Queue = queue.Queue()
        env = dict(os.environ, PYTHONUNBUFFERED="1")
        cwd = cwd or scene.parent
        # Ctrl-C (SIGINT) stops it, also when this test runs where SIGINT is ignored (a shell's background job
        # without job control): Python only installs its handler in a process that starts with SIGINT not ignored
        self.process = subprocess.Popen([sys.executable, *launch, "watch", str(scene.relative_to(cwd)), *args],
                                        cwd=cwd, stdout=subprocess.PIPE, stderr=subprocess.STDOUT,
                                        text=True, env=env,
                                        preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))
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

    def save(self, text, path: Path | None = None) -> None:
        """Save as an editor does: write a temporary file beside it, then rename it over the old one (text: str or
        bytes)."""
        path = path or self.scene
        temporary = path.with_name(f".{path.name}.swp~")
        if isinstance(text, bytes):
            temporary.write_bytes(text)
        else:
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
    result = subprocess.run([sys.executable, "-m", "isaac.cli", "watch", str(tmp_path / "nope.isaac")],
                            capture_output=True, text=True, timeout=60)
    assert result.returncode == 2 and "no such scene file" in result.stderr


@pytest.mark.skipif(shutil.which("isaac") is None and not (Path(sys.executable).parent / "isaac").exists(),
                    reason="the isaac command is not installed")
def test_watch_is_a_command(tmp_path):
    isaac = shutil.which("isaac") or str(Path(sys.executable).parent / "isaac")
    result = subprocess.run([isaac, "watch", "--help"], capture_output=True, text=True, timeout=60)
    assert result.returncode == 0 and "--port" in result.stdout


def test_the_tutorial_steps_load_and_its_mistake_is_the_one_it_shows():
    from isaac_ir.diagnostics import SceneError
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


# -- what a save can bring: our bugs, a folder made again, a vanished or binary scene ---------------------------------

# python -c: the command with two stand-ins for bugs of ours, one in the front end (a scene with the marker comment)
# and one in the run thread (a scene named `crash`); everything else is the real thing
BUGS = """
import sys
import isaac_lang.load as load
import isaac_runtime.run as run
real_load, real_simulate = load.load_scene, run.simulate

def load_scene(path, *args, **kwargs):
    if "# break the front end" in open(path, encoding="utf-8", errors="replace").read():
        raise RecursionError("maximum recursion depth exceeded (a stand-in for a bug in the front end)")
    return real_load(path, *args, **kwargs)

def simulate(scene, options):
    if scene.name == "crash":
        raise ZeroDivisionError("a stand-in for a bug in the run thread")
    return real_simulate(scene, options)

load.load_scene, run.simulate = load_scene, simulate
from isaac.cli import main
sys.exit(main(sys.argv[1:]))
"""
SHORT = PENDULUM.replace("time 0 s .. 10 s", "time 0 s .. 0.3 s")
# `internal error (Kind: ...); this is a bug in isaac, not in your scene. The traceback is in PATH; ...`
INTERNAL = r"internal error \({kind}: .*\); this is a bug in isaac, not in your scene\. The traceback is in (\S+);"


def traceback_file(match: re.Match) -> str:
    text = Path(match.group(1)).read_text()
    Path(match.group(1)).unlink()
    return text


def test_our_own_bugs_never_end_the_watch_and_the_page_says_them(tmp_path):
    scene = tmp_path / "short.isaac"
    scene.write_text(SHORT)
    watch = Session(scene, "--out", str(tmp_path / "out"), "--port", "0", launch=("-c", BUGS))
    viewer = tmp_path / "out" / "viewer.html"
    try:
        url = watch.wait_for(r"live viewer at (http://127\.0\.0\.1:\d+/)").group(1)
        watch.wait_for(r"result #1: complete")

        # the front end fails inside: one line, the traceback in a file; result #1 stays, on the page too
        watch.save(SHORT + "\n# break the front end\n")
        found = watch.wait_for(INTERNAL.format(kind="RecursionError") + r" the last good result \(#1\) stays; "
                               r"still watching")
        assert "RecursionError" in traceback_file(found) and watch.alive()
        page = status(url)
        assert page["state"] == "error" and page["result"] == 1 and "internal error" in page["diagnostic"]
        assert '"result":1' in viewer.read_text()
        watch.save(SHORT.replace("mass 1 kg", "mass 2 kg"))
        watch.wait_for(r"result #2: complete")
        assert status(url)["state"] == "complete" and status(url)["diagnostic"] is None

        # the run thread fails: said the same way; the page says error (not "running"), result #2 stays shown
        watch.save(SHORT.replace("scene pendulum", "scene crash"))
        found = watch.wait_for(r"result #3: " + INTERNAL.format(kind="ZeroDivisionError") + " still watching")
        assert "ZeroDivisionError" in traceback_file(found)
        page = status(url)
        assert page["state"] == "error" and "internal error" in page["message"] and page["result"] == 2
        assert "ZeroDivisionError" in page["diagnostic"] and '"result":2' in viewer.read_text()

        # and the next good save is taken
        watch.save(SHORT.replace("mass 1 kg", "mass 3 kg"))
        watch.wait_for(r"result #4: complete")
        assert status(url)["state"] == "complete" and '"result":4' in viewer.read_text()

        # constraints that cannot both hold, found when the plan is made: a positioned error, result #4 shown
        extra = "  constraint extra nail(bob @ (0, 0, 0), (5, 5, 5))\n}"
        watch.save(SHORT.rstrip().removesuffix("}") + extra + "\n")
        watch.wait_for(r"^short\.isaac:\d+:3: error: constraints `hang` and `extra` cannot both hold")
        watch.wait_for(r"result #5: error \(above\); fix it and save")
        assert status(url)["state"] == "error" and '"result":4' in viewer.read_text() and watch.alive()
    finally:
        assert watch.stop() == 0
    assert "Traceback" not in "\n".join(watch.lines)


@pytest.mark.parametrize("how", ["notifications", "--poll"])
def test_a_folder_made_again_a_scene_that_vanishes_and_a_binary_save(tmp_path, how):
    folder = tmp_path / "scenes"
    folder.mkdir()
    scene = folder / "short.isaac"
    scene.write_text(SHORT)
    out = tmp_path / "out"
    poll = ("--poll",) if how == "--poll" else ()
    watch = Session(scene, "--out", str(out), "--no-serve", *poll, cwd=tmp_path)
    try:
        watch.wait_for(r"result #1: complete")

        # the folder deleted and made again (git checkout, some editors): the watch follows the new folder
        shutil.rmtree(folder)
        watch.wait_for(r"scene error: the last good result \(#1\) stays")
        assert (out / "viewer.html").is_file()  # the last good result's files stay
        folder.mkdir()
        scene.write_text(SHORT.replace("mass 1 kg", "mass 2 kg"))
        watch.wait_for(r"result #2: complete")
        watch.save(SHORT.replace("mass 1 kg", "mass 3 kg"))  # and keeps hearing it
        watch.wait_for(r"result #3: complete")

        # the scene alone vanishes, then comes back
        scene.unlink()
        watch.wait_for(r"no such scene file")
        watch.wait_for(r"scene error: the last good result \(#3\) stays")
        scene.write_text(SHORT.replace("mass 1 kg", "mass 4 kg"))
        watch.wait_for(r"result #4: complete")

        # a binary file saved as the scene: a scene error at its position; the fix is taken
        watch.save(b"\x89PNG\r\n\x1a\n\x00\x00\x00\rIHDR\xff\xfe")
        watch.wait_for(r"short\.isaac:\d+:\d+: error: ")
        watch.wait_for(r"scene error: the last good result \(#4\) stays")
        watch.save(SHORT.replace("mass 1 kg", "mass 5 kg"))
        watch.wait_for(r"result #5: complete")
        assert json.loads((out / "ir.json").read_text())["bodies"][0]["mass"] == 5.0
    finally:
        assert watch.stop() == 0
    output = "\n".join(watch.lines)
    assert "Traceback" not in output and "internal error" not in output and "file watch failed" not in output


@pytest.mark.parametrize("poll", [True, False])
def test_a_failure_of_the_file_watch_itself_is_said_and_the_watch_goes_on(tmp_path, poll):
    from isaac.watch_files import FileWatcher

    said, calls = [], []

    def folders():  # the second look at the folders fails, as a bug of ours (or the system's) would
        calls.append(1)
        if len(calls) == 2:
            raise OSError("a stand-in for a failure of the file watch")
        return [tmp_path]

    files = FileWatcher(folders, poll, said.append)
    files.start()
    try:
        deadline = time.monotonic() + 20
        while not any("file watch failed" in s for s in said) and time.monotonic() < deadline:
            time.sleep(0.05)
        failed = next(s for s in said if "file watch failed" in s)
        assert "internal error (OSError: a stand-in" in failed and "watching again" in failed
        path = re.search(r"The traceback is in (\S+);", failed).group(1)
        assert "OSError" in Path(path).read_text()
        Path(path).unlink()
        time.sleep(1.0)  # watching again after RESTART_AFTER
        (tmp_path / "scene.isaac").write_text("scene s { }\n")
        changed = set()
        while (tmp_path / "scene.isaac").resolve() not in changed and time.monotonic() < deadline:
            try:
                changed |= files._queue.get(timeout=0.2)
            except queue.Empty:
                continue
        assert (tmp_path / "scene.isaac").resolve() in changed, said
    finally:
        files.stop()
