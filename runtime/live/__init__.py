"""Real time: `isaac live SCENE` runs the scene paced to the wall clock, with a page on 127.0.0.1 that draws it as
it is computed, plays its sound, shows the breath, and lets the user drag a body and change a parameter.

    code = run_live(scene, LiveOptions(scene_path=..., out=..., mic="scenes/assets/breath.wav", until=4.0))

The driver reads as the stages, one module each:

    breath.py    the input: a microphone, or a WAV file fed in real time through the same streaming path; it
                 stands in for the recordings the winds follow, and its latency is measured
    (plan)       the scene planned as `isaac run` plans it, the compiled core warmed before the clock starts
    server.py    the page and its stream of poses (server-sent events), the page's commands (drag, parameter)
    session.py   the loop: a frame at a time, held to the wall clock (clock.py), dragged (drag.py), sounding
                 (audio.py), until --until, the scene's end, or Ctrl-C
    results.py   the outputs of `isaac run` for what happened live, and report.json's `realtime` section

sounddevice (the `live` extra) is imported only when a device is used: `--mic FILE.wav` and no `--mic` need it not.
"""
from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .. import signals as S
from ..plan.extras import check_extras
from ..plan import PlanOptions, compile_plan
from ..simulation import Simulation

EXIT_OK, EXIT_SCENE = 0, 2


@dataclass
class LiveOptions:
    scene_path: Path
    out: Path
    overrides: dict = field(default_factory=dict)
    solver: str | None = None
    step: float | None = None
    until: float | None = None
    port: int | None = None  # None: 8766, or any free port when it is taken
    browser: bool = True
    mic: str | None = None  # None: no input; "": the default device; a device name or index; a sound file
    sliders: list = field(default_factory=list)  # the declared parameters the page offers (isaac.live_command)
    viewer: bool = True
    verbosity: int = 0
    scene_warnings: tuple = ()
    max_constraint_error: float | None = None
    # overrides -> the plan of the scene with them (the application loads and plans it again): a slider's change
    replan: object = None

    @property
    def folder(self) -> Path:
        return Path(self.scene_path).parent


def run_live(scene, options: LiveOptions) -> int:
    """`isaac live` after the scene is loaded: the stages (module docstring), then the exit code."""
    from .breath import open_breath
    from .results import build_report, check_out, write_results

    check_out(options)
    breath = open_breath(options.mic) if options.mic is not None else None
    if breath is not None:
        S.use_microphone(breath)
    server = None
    try:
        sim = _simulation(scene, options)
        server, session = _serve(sim, breath, options)
        result = session.run()
    finally:
        if breath is not None:
            breath.close()
            S.use_microphone(None)
    try:
        frame_period = session.pacer.frame
        report = build_report(result, options, breath, server.hub, frame_period)
        scene_out = sim.plan.scene if list(result.simulation.plan.names) == [str(n) for n in
                                                                              result.recorder.bodies] else scene
        write_results(scene_out, result, report, options)
    finally:
        server.close()
    _say(scene, report, result, options)
    return EXIT_SCENE if result.error is not None else EXIT_OK


# ---- the stages ----------------------------------------------------------------------------------------------

def _simulation(scene, options: LiveOptions) -> Simulation:
    """The plan of `isaac run`, and its simulation."""
    plan_options = {"solver": options.solver, "step": options.step, "until": options.until}
    plan = compile_plan(scene, PlanOptions(folder=options.folder, **plan_options))
    check_extras(plan)
    if options.verbosity > 0:
        print(plan.describe(), file=sys.stderr)
    return Simulation(plan)


def _serve(sim: Simulation, breath, options: LiveOptions):
    """The page's server and the loop, wired together; the address said (and opened in a browser)."""
    from ..viewer import render_live_html
    from .server import LiveServer
    from .session import LiveSession

    holder = {}
    sliders = {s["name"]: s["text"] for s in options.sliders}

    def describe():
        return _page_data(holder["session"].sim, breath, options, holder["session"].version)

    def status():
        session = holder.get("session")
        if session is None:
            return {"state": "starting"}
        return {"state": "running", "frame": session.frame, "t": float(session.sim.state.t),
                "lag_ms": session.pacer.lag * 1e3, "clients": server.hub.clients, "frames_dropped": server.hub.dropped,
                "version": session.version}

    server = LiveServer(render_live_html(_page_data(sim, breath, options, 0)).encode("utf-8"), options.port, status)

    def publish(kind: str, data: dict) -> None:
        if kind == "scene":
            server.set_page(render_live_html(data).encode("utf-8"))
        server.hub.publish(kind, data)

    def say(text: str) -> None:
        if options.verbosity >= -1:
            print(text, file=sys.stderr, flush=True)

    session = LiveSession(sim, sim.plan.frame_times, breath, publish, server.commands, say, describe, sliders,
                          replan=options.replan, overrides=options.overrides)
    holder["session"] = session
    if options.verbosity >= -1:
        what = f"; breath from {breath.source.name}" if breath is not None else ""
        print(f"[{time.strftime('%H:%M:%S')}] {sim.plan.scene.name}: live at {server.url} "
              f"(Ctrl-C to stop){what}", file=sys.stderr, flush=True)
    if options.browser:
        import webbrowser

        webbrowser.open(server.url)
    return server, session


def _page_data(sim: Simulation, breath, options: LiveOptions, version: int) -> dict:
    """The live page's data: the viewer's drawing of the scene at the state now, and what the page offers."""
    from ..viewer import viewer_data

    n = sim.plan.n
    y = sim.state.y[:n]
    arrays = {"time": np.array([sim.state.t]), "bodies": np.array(sim.plan.names), "position": y[None, :, 0:3],
              "orientation": y[None, :, 3:7]}
    data = viewer_data(sim.plan.scene, arrays, options.folder)
    data.update(stream=True, version=version, until=float(sim.plan.end),
                sliders=[dict(s, value_text=s["text"]) for s in options.sliders],
                breath={"source": breath.source.kind, "name": breath.source.name} if breath is not None else None,
                winds=list(sim.plan.forces.wind.fields.names) if sim.plan.forces.wind is not None else [])
    return data


def _say(scene, report: dict, result, options: LiveOptions) -> None:
    if result.error is not None:
        print(f"{options.scene_path}: error: {result.error}\nhint: the trajectory up to t = "
              f"{result.error.time:.6g} s is in {options.out / 'trajectory.npz'}", file=sys.stderr)
        return
    if options.verbosity < -1:
        return
    r = report["realtime"]
    latency = (f"; breath to wind {r['input_latency_ms']:.1f} ms (at most {r['input']['latency_max_ms']:.1f} ms)"
               if r["input_latency_ms"] is not None else "")
    print(f"{scene.name}: {r['frames']} frames live in {r['wall_time']:.2f} s; largest lag {r['max_lag_ms']:.1f} ms, "
          f"{r['frames_late']} late, {r['frames_dropped']} dropped{latency}; outputs in {options.out}/")
