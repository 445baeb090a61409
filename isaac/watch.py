"""`isaac watch SCENE`: live reload. Every save of the scene, or of a file it includes, is re-parsed, re-planned
and re-run; a valid scene replaces the shown result, a bad edit prints its diagnostic and the last good result
stays. Nothing a save brings ends the watch, a bug of ours included; Ctrl-C does, cleanly.

The stages of one reload (Watch.reload):
    load   parse -> expand -> lower -> check (isaac_lang.load); a SceneError ends the reload here
    same?  an edit that leaves the IR unchanged (a comment, spacing) keeps the running result
    run    a worker thread plans and simulates with the scene's own settings, publishing the viewer after the first
           FIRST_RESULT seconds of work and then every PUBLISH_EVERY seconds; a newer save cancels it
    write  at the end, the outputs of `isaac run` (trajectory, events, IR, report), viewer.html and plots

The output folder holds one result's files at a time (runtime/outputs/outputset.py): a result's first showing replaces the
folder with its viewer.html (the frames so far), each later showing likewise, and its end with the whole set.
An internal error (in loading, in the run thread, in the file watch) is said in one line with the file its
traceback went to; the page says it too (state `error`), the last good result stays shown, and the next save is
tried afresh (a save of the same scene re-runs a result that failed so). The file watch is isaac/watch_files.py.
Latency is measured from the save (the saved file's modification time) to the moment the new result is in
viewer.html and on the live page; both the first result and the complete run are reported.
The runtime is imported lazily (the front end never needs the solvers).
"""
from __future__ import annotations

import dataclasses
import os
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from isaac.crash import internal_error
from isaac_ir.diagnostics import Diagnostic, SceneError, SourceCache, counted
from isaac.watch_files import FileWatcher

# seconds of stepping (after planning) before the first frames are shown: the motion has begun, the wait is short
FIRST_RESULT = 0.2
# seconds between later showings while the run goes on
PUBLISH_EVERY = 1.0


class Superseded(Exception):
    """Raised inside a run that a newer save has replaced."""


class RecordingSources(SourceCache):
    """A SourceCache that remembers which files a load read (the scene and its includes): the files to watch."""

    def __init__(self, root: Path):
        super().__init__()
        self.root = root
        self.files: set = set()

    def add(self, name: str, text: str) -> None:
        super().add(name, text)
        if not name.startswith("--set"):
            path = Path(name)
            self.files.add(_real(path if path.is_absolute() else self.root / path))


@dataclass
class Job:
    """One run of one valid scene: result number n."""

    n: int
    scene: object
    saved_at: float  # wall clock (time.time) of the save that started it
    folder: Path
    out: Path
    sources: SourceCache  # the text the scene was loaded from (for diagnostics found later)
    cancel: threading.Event = field(default_factory=threading.Event)
    cancel_reason: str = ""
    state: str = "running"  # then complete, failed (a numerical blow-up) or error (a scene error, or ours)
    message: str = ""
    failed: str | None = None  # the blow-up's message
    first_frame: float | None = None  # perf_counter when the first frame was recorded (the plan is made)
    shown_at: float | None = None  # perf_counter of the last showing
    first_latency: float | None = None
    thread: threading.Thread | None = None
    crashed: bool = False  # ended by an internal error: a save of the same scene runs it again


@dataclass
class WatchOptions:
    out: Path | None = None  # default out/<scene file stem>/
    overrides: dict = field(default_factory=dict)
    solver: str | None = None
    step: float | None = None
    until: float | None = None
    limits: object = None
    serve: bool = True
    port: int = 8765
    poll: bool = False
    plots: bool = False


class Watch:
    def __init__(self, scene_path: Path, options: WatchOptions, format_error=None):
        self.path = Path(scene_path)
        self.folder = self.path.parent
        self.options = options
        # turns a SceneError and the sources it was read from into the text to print
        self.format_error = format_error or (lambda error, sources: error.format(sources))
        self.files = {self.path.resolve()}  # what the last load read, plus files the scene names
        self.good_ir = None  # canonical IR JSON of the last valid scene (the one self.job runs)
        self.last_ok = True  # whether the last load was valid
        self.scene_error = None  # the diagnostic of the saved scene while it is broken: it stays on the page
        self.count = 0
        self.job: Job | None = None
        self.server = None
        self._print_lock = threading.Lock()

    # -- the loop -------------------------------------------------------------------------------------------

    def run(self) -> int:
        if self.options.serve:
            from isaac_runtime.viewer.serve import LiveServer

            self.server = LiveServer(self.path.stem, self.options.port)
        # the runtime loads while the scene does: the first result does not wait for imports
        threading.Thread(target=_warm_up, name="isaac-imports", daemon=True).start()
        files = FileWatcher(self._folders, self.options.poll, self.say, files=lambda: self.files)
        self.say(f"watching {self.path} (Ctrl-C to stop)" +
                 (f"; live viewer at {self.server.url}" if self.server else ""))
        try:
            files.start()  # before the first load: a save during it is not missed
            self.reload_safely(time.time(), "start")
            while True:
                changed = files.next_changes()
                self.reload_safely(None, "", changed)
        except KeyboardInterrupt:
            pass
        finally:
            files.stop()
            self.stop_job("the watch ends")
            if self.server:
                self.server.close()
        self.say("stopped watching")
        return 0

    def _folders(self) -> list:
        """The folders to watch: the scene's, and those of every file the last load read."""
        files = self.files  # replaced, never changed in place, by the main thread
        return sorted({p.parent for p in files if p.parent.is_dir()} | {self.folder.resolve()})

    def relevant(self, changed: set) -> set:
        """The changed files this scene depends on; after a failed load, any scene file (a new include?)."""
        hits = {p for p in changed if p in self.files}
        if not self.last_ok:
            hits |= {p for p in changed if p.suffix == ".isaac"}
        return hits

    # -- one reload -----------------------------------------------------------------------------------------

    def reload_safely(self, saved_at: float | None, what: str, changed: set | None = None) -> None:
        """reload for the changed paths that matter (all of them when changed is None); an internal error is
        said, and the watch goes on."""
        try:
            if changed is not None:
                relevant = self.relevant(changed)
                if not relevant:
                    return
                saved_at = _saved_at(relevant)
                what = ", ".join(sorted(_short(p, self.folder) for p in relevant))
            self.reload(saved_at, what)
        except Exception as error:  # a bug of ours in the front end (or in starting the run): never the end
            self.report_internal(error, what)

    def reload(self, saved_at: float, what: str) -> None:
        from isaac_ir import ir
        from isaac_lang.load import load_scene

        sources = RecordingSources(self.folder)
        try:
            if not self.path.is_file():  # between the two halves of a save by rename, or deleted
                raise SceneError([Diagnostic(f"no such scene file: {self.path}", None)])
            loaded = load_scene(self.path, self.options.overrides, self.options.limits, sources)
        except SceneError as error:
            self.files = sources.files | self.files
            self.last_ok = False
            self.report_error(error, sources)
            return
        self.last_ok = True
        self.scene_error = None
        self.files = sources.files | {self.path.resolve()} | _named_files(loaded.scene, self.folder)
        self.say_warnings(loaded.warnings, sources)
        canonical = ir.to_json(loaded.scene)
        if canonical == self.good_ir and self.job is not None and not self.job.crashed:
            self.say(f"{what}: no change to the scene (same IR); result #{self.job.n} stays")
            if self.server:  # the diagnostic of an edit in between goes; the result's own status comes back
                self.server.set_status(state=self.job.state, message=self.job.message, diagnostic=self.job.failed)
            return
        self.stop_job("a newer save replaces it")
        self.count += 1
        out = self.options.out or Path("out") / self.path.stem  # named after the file, as `isaac run` does
        job = Job(self.count, loaded.scene, saved_at, self.folder, out, sources)
        self.good_ir = canonical
        if self.server:
            self.server.set_status(state="running", message=f"result #{job.n}: starting", diagnostic=None)
        self.say(f"{what}: result #{job.n}: running {loaded.scene.name} "
                 f"({counted(len(loaded.scene.bodies), 'body')}, {loaded.scene.time.start:g} s .. {loaded.scene.time.end:g} s)")
        self.start_job(job)

    def say_warnings(self, warnings: list, sources=None) -> None:
        """Warnings the gcc way (`file:line:col: warning: ...`), as `isaac run` prints them."""
        from isaac_ir.diagnostics import warning_diagnostic

        if warnings:
            text = self.format_error(SceneError([warning_diagnostic(w) for w in warnings]), sources or SourceCache())
            with self._print_lock:
                print(text, file=sys.stderr, flush=True)

    def report_error(self, error: SceneError, sources) -> None:
        text = self.format_error(error, sources)
        kept = f"the last good result (#{self.job.n}) stays" if self.job else "no result yet"
        self.scene_error = text
        # the page first, then the terminal: whoever reads the message finds the page already saying it
        if self.server:
            self.server.set_status(state="error", diagnostic=text, message=f"scene error: {kept}")
        with self._print_lock:
            print(text, file=sys.stderr, flush=True)
        self.say(f"scene error: {kept}; fix the scene and save")

    def report_internal(self, error: Exception, what: str) -> None:
        """A bug of ours while loading: one line (and the traceback's file); the last good result stays, and any
        scene file's next save is tried."""
        line = internal_error(error)
        kept = f"the last good result (#{self.job.n}) stays" if self.job else "no result yet"
        self.last_ok = False
        self.scene_error = line  # on the page while the last good result goes on running
        if self.server:
            self.server.set_status(state="error", diagnostic=line, message=f"internal error: {kept}")
        self.say(f"{what + ': ' if what else ''}{line}; {kept}; still watching")

    # -- the run --------------------------------------------------------------------------------------------

    def start_job(self, job: Job) -> None:
        self.job = job
        job.thread = threading.Thread(target=self._run_job, args=(job,), name=f"isaac-run-{job.n}", daemon=True)
        job.thread.start()

    def stop_job(self, reason: str) -> None:
        job = self.job
        if job is not None and job.thread is not None and job.thread.is_alive():
            job.cancel_reason = reason
            job.cancel.set()
            job.thread.join()

    def _run_job(self, job: Job) -> None:
        try:
            from isaac_runtime.outputs.outputset import OutputSet
            from isaac_runtime.run import RunOptions

            OutputSet(job.out, "watch").check()  # a folder that is not isaac's: said now, as a scene error
            options = RunOptions(solver=self.options.solver, step=self.options.step, until=self.options.until,
                                 folder=job.folder)
            result = _simulate(job.scene, options, lambda sim, recorder: self._on_frame(job, recorder))
            self._finish(job, result)
        except Superseded:
            self.say(f"result #{job.n} stopped: {job.cancel_reason}")
        except SceneError as error:  # found by the planner: as a load's error, but the old result is gone
            self.job_error(job, error)
        except Exception as error:  # a bug in the tool: say so in one line, keep watching
            self.job_crashed(job, error)

    def job_crashed(self, job: Job, error: Exception) -> None:
        line = internal_error(error)
        job.crashed = True
        job.state, job.message, job.failed = "error", f"result #{job.n}: internal error", line
        if self.server:
            self.server.set_status(state="error", message=f"{job.message}; the page keeps what it last showed",
                                   diagnostic=line)
        self.say(f"result #{job.n}: {line}; still watching (save to run it again)")

    def job_error(self, job: Job, error: SceneError) -> None:
        text = self.format_error(error, job.sources)
        job.state, job.message, job.failed = "error", f"result #{job.n}: scene error", text
        if self.server:  # the page first, then the terminal (report_error)
            self.server.set_status(state="error", diagnostic=text, message=job.message)
        with self._print_lock:
            print(text, file=sys.stderr, flush=True)
        self.say(f"result #{job.n}: error (above); fix it and save")

    def _on_frame(self, job: Job, recorder) -> None:
        """Called after every recorded frame: stop when superseded; show the frames so far when it is time."""
        if job.cancel.is_set():
            raise Superseded()
        now = time.perf_counter()
        if job.first_frame is None:
            job.first_frame = now  # planned; the stepping starts
        due = FIRST_RESULT if job.shown_at is None else PUBLISH_EVERY
        if now - (job.shown_at or job.first_frame) >= due:
            self._show(job, recorder.arrays())

    def _show(self, job: Job, arrays: dict) -> None:
        """The frames so far: the output folder becomes this result's (its viewer.html), and the live page."""
        scene = job.scene
        t = float(arrays["time"][-1]) if len(arrays["time"]) else scene.time.start
        note = f"running: {t - scene.time.start:.2f} s of {scene.time.end - scene.time.start:g} s so far"
        with _output_set(job.out) as folder:
            data, viewer = self._viewer(job, arrays, folder.path, note)
            folder.commit([viewer], scene=scene.name, result=job.n, run="running")
        self._publish(job, data, "running", f"result #{job.n}: {note}")
        if job.first_latency is None:
            job.first_latency = time.time() - job.saved_at
            self.say(f"result #{job.n}: first frames {job.first_latency:.2f} s after the save "
                     f"({len(arrays['time'])} frames, up to t = {t:.3g} s); the run goes on")

    def _finish(self, job: Job, result) -> None:
        """The whole result: the files of `isaac run`, viewer.html and plots as one set; the live page."""
        from isaac_runtime.run import set_info

        arrays = result.recorder.arrays()
        failed = str(result.error) if result.error is not None else ""
        with _output_set(job.out) as folder:
            written = _write_outputs(job.scene, result, folder.path)
            audio = folder.path / "audio.wav" if result.audio is not None else None
            data, viewer = self._viewer(job, arrays, folder.path, "", audio)
            if self.options.plots:
                written += self._plots(job, arrays, folder.path, audio)
            folder.commit(written + [viewer], result=job.n, **set_info(job.scene, result))
        self._publish(job, data, "failed" if failed else "complete",
                      f"result #{job.n}: {'failed' if failed else 'complete'}", failed)
        latency = time.time() - job.saved_at
        if job.first_latency is None:
            job.first_latency = latency
        report = result.report
        self.say_warnings(report.get("warnings", []), job.sources)  # the plan's and the run's
        if failed:
            hint = getattr(result.error, "hint", None)
            self.say(f"result #{job.n}: error: {failed}; the trajectory up to the blow-up is shown"
                     + (f" ({hint})" if hint else ""))
        else:
            self.say(f"result #{job.n}: complete {latency:.2f} s after the save (first frames after "
                     f"{job.first_latency:.2f} s); {report['frames']} frames, max constraint error "
                     f"{report['max_constraint_error']:.2e}; outputs in {job.out}/")

    def _viewer(self, job: Job, arrays: dict, folder: Path, note: str, audio: Path | None = None) -> tuple:
        """(viewer data, the viewer.html written into folder) of a result."""
        from isaac_runtime.outputs import write_atomic
        from isaac_runtime.viewer import viewer_data
        from isaac_runtime.viewer.write import audio_url, render_html

        data = viewer_data(job.scene, arrays, job.folder, note=note)
        if audio is not None and audio.is_file():
            data["audio"] = audio_url(audio, folder)
        data["result"] = job.n
        write_atomic(folder / "viewer.html", render_html(data).encode("utf-8"))
        return data, folder / "viewer.html"

    def _publish(self, job: Job, data: dict, state: str, message: str, failed: str = "") -> None:
        job.state, job.message, job.failed = state, message, failed or None
        if self.server:
            if self.scene_error is not None:  # the last good result goes on running under the broken scene's error
                self.server.publish(data, state="error", message=message, diagnostic=self.scene_error)
            else:
                self.server.publish(data, state=state, message=message, diagnostic=job.failed)
        job.shown_at = time.perf_counter()

    def _plots(self, job: Job, arrays: dict, folder: Path, audio: Path | None) -> list:
        try:
            from isaac_runtime.outputs.plots import write_plots

            return write_plots(folder / "plots", arrays, audio if audio and audio.is_file() else None,
                               title=job.scene.name)
        except ImportError as error:  # matplotlib is the optional `plots` extra
            self.say(f"plots skipped: {error} (pip install 'isaac[plots]')")
            return []

    # -- output ---------------------------------------------------------------------------------------------

    def say(self, message: str) -> None:
        with self._print_lock:
            print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


def _simulate(scene, options, on_frame):
    """isaac_runtime.run.simulate with on_frame(sim, recorder) after every recorded frame (it may raise Superseded)."""
    from isaac_runtime import run

    return run.simulate(scene, dataclasses.replace(options, on_frame=on_frame))


def _write_outputs(scene, result, out: Path) -> list:
    """The files `isaac run` writes; their paths."""
    from isaac_runtime import run

    return run.write_outputs(scene, result, out)


def _output_set(out: Path):
    """A new set of files for the output folder (runtime/outputs/outputset.py)."""
    from isaac_runtime.outputs.outputset import OutputSet

    return OutputSet(out, "watch")


def _warm_up() -> None:
    import isaac_runtime.run  # noqa: F401
    import isaac_runtime.simulation  # noqa: F401
    import isaac_runtime.viewer  # noqa: F401


def _saved_at(paths: set) -> float:
    """When the save happened: the newest modification time among the changed files (not after now)."""
    now = time.time()
    stamps = []
    for path in paths:
        try:
            stamps.append(path.stat().st_mtime)
        except OSError:
            pass  # deleted (the first half of a save by rename)
    return min(max(stamps), now) if stamps else now


def _named_files(scene, folder: Path) -> set:
    """Files the scene names besides its includes: meshes and surface textures."""
    names = [b.shape.file for b in scene.bodies if b.shape.file] + [m.texture for m in scene.materials if m.texture]
    return {_real(folder / name) for name in names if "\0" not in name}


def _real(path: Path) -> Path:
    """The path with its links followed; a loop of links (refused by the load) stays as written, where
    Path.resolve would raise."""
    return Path(os.path.realpath(path))


def _short(path: Path, folder: Path) -> str:
    try:
        return path.relative_to(folder.resolve()).as_posix()
    except ValueError:
        return str(path)
