"""Live stage, pacing: the simulation held to the wall clock, and what it costs measured.

    pacer = Pacer(start=0.0, frame=0.02)
    pacer.begin()                  # the wall time (time.monotonic) at which scene time `start` is now
    pacer.wait_until(t)            # before the steps from scene time t: sleep until t is now
    pacer.done(t_next, compute)    # the frame at t_next is computed (compute: seconds of work for it)

Scene time t is due at wall time `origin + (t - start)`. The steps of a frame run when its start is due (so that
the breath they read is the breath of that moment, never one from their future), and the frame is late when it
is ready after its own time: its lag. A late frame is not raced after: when the lag passes CATCH_UP the clock
slips by it (`origin` moves on) and the run goes on slowed down. When the work of the frames takes longer than
the frames themselves, over a second of scene time or a second of work (whichever comes first: a very slow scene
is told within a second of the wall clock), the run says so once, with the factor it can keep up (frame time over
work).
A stall that is not the simulation's (a parameter re-planned) is forgiven with `forgive()`: the clock slips, and
the lag is not counted.
"""
from __future__ import annotations

import sys
import time
from collections import deque

# s: a frame later than this behind the wall clock is not caught up with: the clock slips instead
CATCH_UP = 0.1
# frames over which "it cannot keep up" is judged (a second at 50 Hz), or fewer (at least SLOW_FEWEST) once their
# work reaches SLOW_WORK seconds; and the fraction of real time below which it is said
SLOW_WINDOW = 50
SLOW_FEWEST = 5
SLOW_WORK = 1.0
SLOW_BELOW = 0.97


class Pacer:
    def __init__(self, start: float, frame: float, clock=time.monotonic, sleep=time.sleep, say=None):
        self.start, self.frame = float(start), float(frame)
        self.clock, self.sleep = clock, sleep
        self.say = say or (lambda text: print(text, file=sys.stderr, flush=True))
        self.origin = None
        self.lag = 0.0  # s: the lag of the last frame
        self.max_lag = 0.0  # s: the largest lag behind the wall clock of any frame
        self.late = 0  # frames ready after their time
        self.slips = 0  # times the clock slipped (the run slowed down)
        self.slipped = 0.0  # s: in all
        self.forgiven = 0.0  # s: of stalls that were not the simulation's
        self.slow_factor = None  # the factor it said it could keep up, once
        self.work = deque(maxlen=SLOW_WINDOW)  # s of work of the recent frames
        self.work_total = 0.0
        self.work_max = 0.0
        self.frames = 0

    def begin(self) -> float:
        self.origin = self.clock()
        return self.origin

    def due(self, t: float) -> float:
        return self.origin + (t - self.start)

    def wait_until(self, t: float) -> None:
        wait = self.due(t) - self.clock()
        if wait > 0:
            self.sleep(wait)

    def done(self, t: float, compute: float) -> None:
        """The frame at scene time t is ready now; `compute` seconds of work went into it."""
        now = self.clock()
        self.frames += 1
        self.work.append(compute)
        self.work_total += compute
        self.work_max = max(self.work_max, compute)
        self.lag = max(0.0, now - self.due(t))
        self.max_lag = max(self.max_lag, self.lag)
        if self.lag > 0.0:
            self.late += 1
        if self.lag > CATCH_UP:  # not raced after: the clock waits for the simulation
            self.origin += self.lag
            self.slips += 1
            self.slipped += self.lag
        self._judge()

    def _judge(self) -> None:
        if self.slow_factor is not None:
            return
        work = sum(self.work)
        if len(self.work) < self.work.maxlen and (len(self.work) < SLOW_FEWEST or work < SLOW_WORK):
            return
        factor = self.frame * len(self.work) / max(work, 1e-12)
        if factor < SLOW_BELOW:
            self.slow_factor = factor
            self.say(f"isaac live: the simulation cannot keep up with the wall clock: it runs at {factor:.2f}x real "
                     f"time (each {self.frame * 1e3:.0f} ms frame takes {self.frame / factor * 1e3:.0f} ms); "
                     f"going on slowed down")

    def forgive(self, since: float) -> None:
        """A stall since wall time `since` that is not the simulation's: the clock slips by it, uncounted."""
        stall = max(0.0, self.clock() - since)
        self.origin += stall
        self.forgiven += stall

    def report(self, wall: float) -> dict:
        """The pacing part of report.json's `realtime` section (ms where it says so)."""
        frames = max(self.frames, 1)
        return {"max_lag_ms": self.max_lag * 1e3, "frames_late": self.late, "clock_slips": self.slips,
                "slowed_ms": self.slipped * 1e3, "stalls_forgiven_ms": self.forgiven * 1e3,
                "slowed": self.slow_factor is not None, "keep_up_factor": self.slow_factor,
                "work_per_frame_mean_ms": self.work_total / frames * 1e3, "work_per_frame_max_ms": self.work_max * 1e3,
                "real_time_factor": (self.frames * self.frame / wall) if wall > 0 else None}
