"""`isaac watch SCENE`: live reload. Every save of the scene, or of a file it includes, is re-parsed, re-planned
and re-run; a valid scene replaces the shown result, a bad edit prints its diagnostic and the last good result
stays. A scene error never ends the watch; Ctrl-C does, cleanly.

The stages of one reload (Watch.reload):
    load   parse -> expand -> lower -> check (isaac_lang.load); a SceneError ends the reload here
    same?  an edit that leaves the IR unchanged (a comment, spacing) keeps the running result
    run    a worker thread plans and simulates with the scene's own settings, publishing the viewer after the first
           FIRST_RESULT seconds of work and then every PUBLISH_EVERY seconds; a newer save cancels it
    write  at the end, the outputs of `isaac run` (trajectory, events, IR, report), viewer.html and plots

Files are watched through their folders (watchfiles, i.e. inotify/FSEvents/ReadDirectoryChangesW), because an
editor saves by writing a new file and renaming it over the old one: a watch on the old file would see nothing.
Latency is measured from the save (the saved file's modification time) to the moment the new result is in
viewer.html and on the live page; both the first result and the complete run are reported.
The runtime is imported lazily (the front end never needs the solvers).
"""
from __future__ import annotations

import dataclasses
import queue
import sys
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path

from .diagnostics import Diagnostic, SceneError, SourceCache

# seconds of stepping (after planning) before the first frames are shown: the motion has begun, the wait is short
FIRST_RESULT = 0.2
# seconds between later showings while the run goes on
PUBLISH_EVERY = 1.0
# how often the fallback poller (no watchfiles, or --poll) looks at the files
POLL_INTERVAL = 0.1


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
            self.files.add((path if path.is_absolute() else self.root / path).resolve())


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
    state: str = "running"  # then complete or failed (a numerical blow-up)
    message: str = ""
    failed: str | None = None  # the blow-up's message
    first_frame: float | None = None  # perf_counter when the first frame was recorded (the plan is made)
    shown_at: float | None = None  # perf_counter of the last showing
    first_latency: float | None = None
    thread: threading.Thread | None = None


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
        files = FileWatcher(self._folders, self.options.poll, self.say)
        self.say(f"watching {self.path} (Ctrl-C to stop)" +
                 (f"; live viewer at {self.server.url}" if self.server else ""))
        try:
            files.start()  # before the first load: a save during it is not missed
            self.reload(time.time(), "start")
            while True:
                relevant = self.relevant(files.next_changes())
                if relevant:
                    self.reload(_saved_at(relevant), ", ".join(sorted(_short(p, self.folder) for p in relevant)))
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

    def reload(self, saved_at: float, what: str) -> None:
        from . import ir
        from .load import load_scene

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
        if canonical == self.good_ir and self.job is not None:
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
                 f"({len(loaded.scene.bodies)} bodies, {loaded.scene.time.start:g} s .. {loaded.scene.time.end:g} s)")
        self.start_job(job)

    def say_warnings(self, warnings: list, sources=None) -> None:
        """Warnings the gcc way (`file:line:col: warning: ...`), as `isaac run` prints them."""
        from .diagnostics import warning_diagnostic

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
            from isaac_runtime.run import RunOptions

            options = RunOptions(solver=self.options.solver, step=self.options.step, until=self.options.until,
                                 folder=job.folder)
            result = _simulate(job.scene, options, lambda sim, recorder: self._on_frame(job, recorder))
            self._finish(job, result)
        except Superseded:
            self.say(f"result #{job.n} stopped: {job.cancel_reason}")
        except SceneError as error:  # found by the planner: as a load's error, but the old result is gone
            self.job_error(job, error)
        except Exception as error:  # a bug in the tool: say so, keep watching
            import traceback

            with self._print_lock:
                traceback.print_exc(file=sys.stderr)
            self.say(f"result #{job.n}: internal error ({type(error).__name__}: {error}); this is a bug in isaac. "
                     f"Still watching.")

    def job_error(self, job: Job, error: SceneError) -> None:
        text = self.format_error(error, job.sources)
        with self._print_lock:
            print(text, file=sys.stderr, flush=True)
        self.say(f"result #{job.n}: scene error found while planning; fix the scene and save")
        job.state, job.message, job.failed = "error", f"result #{job.n}: scene error", text
        if self.server:
            self.server.set_status(state="error", diagnostic=text, message=job.message)

    def _on_frame(self, job: Job, recorder) -> None:
        """Called after every recorded frame: stop when superseded; show the frames so far when it is time."""
        if job.cancel.is_set():
            raise Superseded()
        now = time.perf_counter()
        if job.first_frame is None:
            job.first_frame = now  # planned; the stepping starts
        due = FIRST_RESULT if job.shown_at is None else PUBLISH_EVERY
        if now - (job.shown_at or job.first_frame) >= due:
            self._show(job, recorder.arrays(), complete=False)

    def _show(self, job: Job, arrays: dict, complete: bool, audio: Path | None = None, failed: str = "") -> None:
        """Put a result (all of it, or the frames so far) in viewer.html and on the live page."""
        from isaac_runtime.viewer import viewer_data
        from isaac_runtime.viewer.write import audio_url, render_html
        from isaac_runtime.outputs import write_atomic

        scene = job.scene
        frames, t = len(arrays["time"]), (float(arrays["time"][-1]) if len(arrays["time"]) else scene.time.start)
        note = "" if complete else f"running: {t - scene.time.start:.2f} s of {scene.time.end - scene.time.start:g} s so far"
        data = viewer_data(scene, arrays, job.folder, note=note)
        if audio is not None and audio.is_file():
            data["audio"] = audio_url(audio, job.out)
        data["result"] = job.n
        write_atomic(job.out / "viewer.html", render_html(data).encode("utf-8"))
        latency = time.time() - job.saved_at
        state = "failed" if failed else ("complete" if complete else "running")
        message = f"result #{job.n}: {note or state}"
        job.state, job.message, job.failed = state, message, failed or None
        if self.server:
            if self.scene_error is not None:  # the last good result goes on running under the broken scene's error
                self.server.publish(data, state="error", message=message, diagnostic=self.scene_error)
            else:
                self.server.publish(data, state=state, message=message, diagnostic=job.failed)
        job.shown_at = time.perf_counter()
        if job.first_latency is None:
            job.first_latency = latency
            if not complete:
                self.say(f"result #{job.n}: first frames {latency:.2f} s after the save "
                         f"({frames} frames, up to t = {t:.3g} s); the run goes on")

    def _finish(self, job: Job, result) -> None:
        written = _write_outputs(job.scene, result, job.out) + [job.out / "viewer.html"]
        arrays = result.recorder.arrays()
        audio = job.out / "audio.wav" if job.scene.sounds else None  # not a stale one from an earlier scene
        failed = str(result.error) if result.error is not None else ""
        self._show(job, arrays, complete=True, audio=audio, failed=failed)
        latency = time.time() - job.saved_at
        report = result.report
        self.say_warnings(report.get("warnings", []), job.sources)  # the plan's and the run's
        if failed:
            self.say(f"result #{job.n}: error: {failed}; the trajectory up to the blow-up is shown "
                     f"(try a smaller step or --solver procedural)")
        else:
            self.say(f"result #{job.n}: complete {latency:.2f} s after the save (first frames after "
                     f"{job.first_latency:.2f} s); {report['frames']} frames, max constraint error "
                     f"{report['max_constraint_error']:.2e}; outputs in {job.out}/")
        if self.options.plots:
            written += self._plots(job, arrays, audio)
        _clear_stale(job.out, written)

    def _plots(self, job: Job, arrays: dict, audio: Path) -> list:
        try:
            from isaac_runtime.plots import write_plots

            return write_plots(job.out / "plots", arrays, audio if audio and audio.is_file() else None,
                               title=job.scene.name)
        except ImportError as error:  # matplotlib is the optional `plots` extra
            self.say(f"plots skipped: {error} (pip install 'isaac[plots]')")
            return []

    # -- files ----------------------------------------------------------------------------------------------

    # -- output ---------------------------------------------------------------------------------------------

    def say(self, message: str) -> None:
        with self._print_lock:
            print(f"[{time.strftime('%H:%M:%S')}] {message}", flush=True)


class FileWatcher:
    """Changed paths, from a background thread: OS notifications through watchfiles, or polling (--poll, or
    without watchfiles). It watches folders, as `folders()` names them at the time, and follows when they change."""

    def __init__(self, folders, poll: bool, say):
        self.folders = folders
        self.poll = poll
        self.say = say
        self._queue: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._ready = threading.Event()

    def start(self) -> None:
        try:
            import watchfiles
        except ImportError:
            watchfiles = None
            self.say(f"(watchfiles is not installed: polling every {POLL_INTERVAL} s; pip install watchfiles)")
        target = self._polling if watchfiles is None or self.poll else self._notified
        threading.Thread(target=target, args=(watchfiles,), name="isaac-files", daemon=True).start()
        self._ready.wait(5.0)

    def stop(self) -> None:
        self._stop.set()

    def next_changes(self) -> set:
        """The next set of changed paths (resolved); blocks, but a Ctrl-C gets through."""
        while True:
            try:
                return self._queue.get(timeout=0.2)
            except queue.Empty:
                continue

    def _notified(self, watchfiles) -> None:
        while not self._stop.is_set():
            folders = self.folders()
            # step: report once nothing more changed for 50 ms (an editor's write-and-rename is one save);
            # the empty reports every 200 ms say the watch is up, and let it follow new folders
            for changes in watchfiles.watch(*folders, step=50, debounce=1600, stop_event=self._stop,
                                            yield_on_timeout=True, rust_timeout=200, raise_interrupt=False):
                self._ready.set()
                if changes:
                    self._queue.put({Path(p).resolve() for _, p in changes})
                if self.folders() != folders:
                    break  # a new include in another folder: watch that folder too

    def _polling(self, watchfiles=None) -> None:
        seen = self._stamps()
        self._ready.set()
        while not self._stop.wait(POLL_INTERVAL):
            now = self._stamps()
            changed = {p for p in set(now) | set(seen) if now.get(p) != seen.get(p)}
            seen = now
            if changed:
                self._queue.put(changed)

    def _stamps(self) -> dict:
        stamps = {}
        for folder in self.folders():
            for path in folder.iterdir():
                try:
                    st = path.stat()
                except OSError:
                    continue
                stamps[path.resolve()] = (st.st_mtime_ns, st.st_size, st.st_ino)
        return stamps


def _simulate(scene, options, on_frame):
    """isaac_runtime.run.simulate with on_frame(sim, recorder) after every recorded frame (it may raise Superseded)."""
    from isaac_runtime import run

    return run.simulate(scene, dataclasses.replace(options, on_frame=on_frame))


def _write_outputs(scene, result, out: Path) -> list:
    """The files `isaac run` writes; their paths."""
    from isaac_runtime import run

    return run.write_outputs(scene, result, out)


def _clear_stale(out: Path, written: list) -> None:
    """What an earlier run wrote into out and this one did not (a sound the scene no longer has)."""
    from isaac_runtime.outputs import clear_stale

    clear_stale(out, written)


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
    return {(folder / name).resolve() for name in names}


def _short(path: Path, folder: Path) -> str:
    try:
        return path.relative_to(folder.resolve()).as_posix()
    except ValueError:
        return str(path)
