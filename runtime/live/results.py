"""Live stage, outputs: what happened live, written as `isaac run` writes a run (runtime/run.py's writers, into
one output set), with report.json's `realtime` section.

realtime:
    input_latency_ms      the mean time from a breath sample to the wind in the step that reads it (measured at
                          every latch: the latch's wall time minus each sample's capture time); null without --mic
    input                 the breath's source and the latency's spread: latency_p95_ms, latency_max_ms (the first
                          sample of a block, which waits longest), to_pose_max_ms (to the end of those steps)
    max_lag_ms            the largest lag of a frame behind the wall clock (ready after its time)
    frames, frames_late, frames_dropped (frames a connected page missed: it fell more than the stream's buffer
                          behind), pages (that connected), clock_slips, slowed, keep_up_factor, real_time_factor
    work_per_frame_mean_ms, work_per_frame_max_ms   the simulation's own cost of a frame
    replans, drags, interrupted, notices
"""
from __future__ import annotations

import math

from ..outputs.outputset import OutputSet
from ..run import (RunResult, RunOptions, run_report, set_info, tolerance_checks, too_deep_warning, write_extras,
                   write_outputs)


def realtime_section(result, breath, hub, frame_period: float) -> dict:
    source = breath.report() if breath is not None else None
    section = {
        "input_latency_ms": source["latency_mean_ms"] if source else None,
        "input": source,
        **result.pacer.report(result.wall),
        "frames": int(result.recorder.count), "frame_period_ms": frame_period * 1e3,
        "frames_dropped": int(hub.dropped), "pages": int(hub.pages),
        "replans": result.replans, "drags": int(result.drags), "interrupted": bool(result.interrupted),
        "notices": list(result.notices), "wall_time": result.wall,
    }
    return section


def build_report(result, options, breath, hub, frame_period: float) -> dict:
    """report.json of `isaac run` (its figures of the motion) with the `realtime` section."""
    recorder = result.recorder
    energy0 = float(recorder.energy[0]) if recorder.count and math.isfinite(recorder.energy[0]) else \
        result.simulation.energy()
    report = run_report(result.simulation, recorder, energy0, result.wall, result.error)
    report["warnings"] = list(options.scene_warnings) + report["warnings"]
    report["checks"] = tolerance_checks(report, options.max_constraint_error)
    report["warnings"] += too_deep_warning(report, result.simulation.plan.scene)
    report["realtime"] = realtime_section(result, breath, hub, frame_period)
    return report


def write_results(scene, result, report: dict, options) -> list:
    """Every file of the run into options.out, as one set; their paths."""
    sim = result.simulation
    sim.events = result.events  # every event of the run, through its re-plans
    run = RunResult(sim, result.recorder, report, result.error, result.audio)
    outputs = OutputSet(options.out, "live")
    with outputs:
        written = write_outputs(scene, run, outputs.path)
        written += write_extras(scene, run, outputs.path, RunOptions(folder=options.folder, viewer=options.viewer))
        return outputs.commit(written, **set_info(scene, run))


def check_out(options) -> None:
    """A folder that is not isaac's stops the live run before it starts (as `isaac run`)."""
    OutputSet(options.out, "live").check()
