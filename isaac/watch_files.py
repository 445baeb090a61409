"""The file watch of `isaac watch`: changed paths, from a background thread that nothing a save brings ends.

Files are watched through their folders (watchfiles, i.e. inotify/FSEvents/ReadDirectoryChangesW), because an
editor saves by writing a new file and renaming it over the old one: a watch on the old file would see nothing.
A folder that is deleted and made again (`git checkout`, some editors) is a new folder to the system: the watch
notices that the folder it watches is gone or another one (its device and inode), reports the watched files in it
as changed, attaches to the new one when it is there, and reports them once more when that watch is up (what was
written in between is not missed). Polling (--poll, or without watchfiles) compares the
files' stamps and sees the same things. A failure of the watch itself (a bug of ours or of the system) is said in
one line with where its traceback went, and the watch starts again; notifications that fail three times in a row
give way to polling.
"""
from __future__ import annotations

import os
import queue
import threading
from pathlib import Path

# how often the fallback poller (no watchfiles, or --poll) looks at the files, and a missing folder is looked for
POLL_INTERVAL = 0.1
# seconds before a failed watch starts again
RESTART_AFTER = 0.5
# failures of the notifications in a row before polling takes over
NOTIFY_FAILURES = 3


class FileWatcher:
    """Changed paths, from a background thread: OS notifications through watchfiles, or polling. It watches the
    folders `folders()` names at the time and follows when they change; `files()` are the files that matter (they
    are reported when their folder goes or comes back)."""

    def __init__(self, folders, poll: bool, say, files=lambda: set()):
        self.folders = folders
        self.files = files
        self.poll = poll
        self.say = say
        self._queue: queue.Queue = queue.Queue()
        self._stop = threading.Event()
        self._ready = threading.Event()
        self._marks: dict = {}  # folder -> (device, inode) or None when missing, as last seen
        # folders made again since the last watch began: their files are reported once more when it is up (a file
        # written between the folder's coming back and the new watch would be missed)
        self._came_back: set = set()
        self._pins: dict = {}  # folder -> (an open descriptor of it, its mark): see _pin

    def start(self) -> None:
        try:
            import watchfiles
        except ImportError:
            watchfiles = None
            self.say(f"(watchfiles is not installed: polling every {POLL_INTERVAL} s; pip install watchfiles)")
        self.poll = self.poll or watchfiles is None
        threading.Thread(target=self._supervise, args=(watchfiles,), name="isaac-files", daemon=True).start()
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

    def _supervise(self, watchfiles) -> None:
        """Run the watch; when it fails, say so and run it again (polling after repeated notification failures)."""
        from isaac.crash import internal_error

        failures = 0
        while not self._stop.is_set():
            try:
                if self.poll:
                    self._polling()
                else:
                    self._notified(watchfiles)
            except Exception as error:  # never the end of the watch
                failures += 1
                switch = not self.poll and failures >= NOTIFY_FAILURES
                self.say(f"the file watch failed: {internal_error(error)}; "
                         + ("polling the files from now on" if switch else "watching again"))
                self.poll = self.poll or switch
                self._ready.set()
                self._stop.wait(RESTART_AFTER)
        self._pin({})  # the folders held open are let go

    def _notified(self, watchfiles) -> None:
        while not self._stop.is_set():
            folders = self.folders()
            marks = self._check_marks(folders)
            present = [folder for folder in folders if marks[folder] is not None]
            if not present:  # every folder is gone: wait for one to come back
                self._ready.set()
                self._stop.wait(POLL_INTERVAL)
                continue
            # step: report once nothing more changed for 50 ms (an editor's write-and-rename is one save);
            # the empty reports every 200 ms say the watch is up, and let it follow new or re-made folders
            came_back, self._came_back = self._came_back, set()
            for changes in watchfiles.watch(*present, step=50, debounce=1600, stop_event=self._stop,
                                            yield_on_timeout=True, rust_timeout=200, raise_interrupt=False):
                self._ready.set()
                if came_back:  # the watch of a folder made again is up: what was written before it, once more
                    self._queue.put(self._files_in(came_back))
                    came_back = set()
                if changes:
                    self._queue.put({Path(p).resolve() for _, p in changes})
                if self.folders() != folders or any(_mark(f) != marks[f] for f in folders):
                    break  # a new include elsewhere, or a folder gone or made again: watch afresh

    def _check_marks(self, folders) -> dict:
        """Each folder's mark now; the watched files of a folder that went or came back are reported changed."""
        marks = {folder: _mark(folder) for folder in folders}
        for folder, mark in marks.items():
            if folder in self._marks and self._marks[folder] != mark:
                self._queue.put(self._files_in({folder}))
                if mark is not None:
                    self._came_back.add(folder)
        self._marks = marks
        self._pin(marks)
        return marks

    def _pin(self, marks: dict) -> None:
        """Hold each watched folder open: a folder deleted and made again at once could otherwise get the same
        inode number back, and look unchanged. (Where folders cannot be opened, Windows, nothing is held.)"""
        for folder in list(self._pins):
            if marks.get(folder) is None or self._pins[folder][1] != marks[folder]:
                os.close(self._pins.pop(folder)[0])
        for folder, mark in marks.items():
            if mark is not None and folder not in self._pins:
                try:
                    self._pins[folder] = (os.open(folder, os.O_RDONLY), mark)
                except OSError:
                    continue

    def _files_in(self, folders: set) -> set:
        """The watched files in those folders, and the folders (reported as changed)."""
        return {path for path in self.files() if path.parent in folders} | set(folders)

    def _polling(self) -> None:
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
            try:
                entries = list(os.scandir(folder))
            except OSError:  # gone (its files are then missing from the stamps: changed)
                continue
            for entry in entries:
                try:
                    st = entry.stat()
                except OSError:
                    continue
                stamps[Path(entry.path).resolve()] = (st.st_mtime_ns, st.st_size, st.st_ino)
        return stamps


def _mark(folder: Path):
    """(device, inode) of a folder, None when it is not there: a folder made again has another inode."""
    try:
        st = os.stat(folder)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)
