"""Sweep driver: grid -> bundle -> tasks on Dask -> journal and kept outputs -> table.

Each variant is one Dask task (`distributed`): on a local cluster of processes (one per core, one thread each:
the step loop holds the GIL) unless a client or a scheduler address is given. The bundle (the scene and its
files) is scattered to the workers once; each task returns its record and files to this process, which alone
writes DIR. Rows come out in the sweep's order whatever finishes first, so the table is the same for any
number of workers (only the wall times differ).
"""
from __future__ import annotations

import logging
import os
import sys
from contextlib import contextmanager
from pathlib import Path

from isaac.sweep.bundle import collect, variant_id
from isaac.sweep.grid import usage, variants_of
from isaac.sweep.table import Journal, build_table, store_outputs, write_table
from isaac.sweep.task import FAILED, Task, run_variant

KEEP = ("outputs", "table")
CONNECT_TIMEOUT = "10s"  # how long to wait for a --scheduler to answer


def sweep(scene, grid, client=None, *, out=None, keep: str = "outputs", until: float | None = None,
          solver: str | None = None, step: float | None = None, scheduler: str | None = None,
          workers: int | None = None, progress: bool = False):
    """Run every variant of the scene file `scene` that `grid` describes; returns the table (a pandas
    DataFrame, one row per variant in order).

    grid: {name: [values]} (their product; values as text of the language, "10 deg", or bare numbers), a
    {name: "10deg..120deg/30"} spec, or a list of {name: value} dicts. client: a `distributed.Client` to run
    on (else `scheduler`'s cluster, else a local cluster of `workers` processes, default one per core).
    out: the folder of the table, journal and kept outputs (None: nothing written, nothing resumed);
    keep="outputs" keeps each variant's files in out/variants/<id>/, "table" only the table.
    """
    if keep not in KEEP:
        raise ValueError(f"keep must be one of {KEEP}, got {keep!r}")
    variants = variants_of(grid)
    if not variants:
        raise ValueError("grid: no variants")
    bundle = collect(scene)
    check_names(scene, variants[0])
    tasks = make_tasks(bundle, variants, keep == "outputs" and out is not None, solver, step, until)
    journal = Journal(out) if out is not None else None
    records = journal.done(tasks) if journal else {}
    todo = [task for task in tasks if task.id not in records]
    with _bar(len(tasks), len(records), Path(scene).stem, progress) as bar:
        if todo:
            with connect(client, scheduler, workers) as live:
                for task, result in execute(live, bundle, todo):
                    records[task.id] = _finish(task, result, out, journal)
                    bar.done(records[task.id]["status"])
    table = build_table(tasks, records)
    table.attrs["skipped"] = len(tasks) - len(todo)
    if out is not None:
        table.attrs["files"] = [p.as_posix() for p in write_table(table, out)]
    return table


def make_tasks(bundle, variants: list, keep: bool, solver, step, until) -> list:
    """One Task per distinct variant (a value repeated in a list runs once), ids from the bundle and values."""
    step, until = (None if v is None else float(v) for v in (step, until))  # 12 and 12.0: one variant, one id
    tasks, seen = [], set()
    for values in variants:
        options = {"solver": solver, "step": step, "until": until}
        task_id = variant_id(bundle, values, options)
        if task_id not in seen:
            seen.add(task_id)
            tasks.append(Task(task_id, len(tasks), dict(values), solver, step, until, keep))
    return tasks


def check_names(scene, values: dict) -> None:
    """Load the first variant here: a `--set` of a name the scene does not have is a mistake on the command
    line (every variant would fail the same way), reported before any cluster starts. Any other problem of
    that variant is its own, recorded in its row."""
    from isaac_ir.diagnostics import SceneError
    from isaac_lang.load import load_scene

    try:
        load_scene(scene, values)
    except SceneError as error:
        about_names = [d for d in error.diagnostics if "the scene has no parameter" in d.message]
        if about_names:
            raise SceneError(about_names) from None


@contextmanager
def connect(client=None, scheduler: str | None = None, workers: int | None = None):
    """The client to submit to: the one given, one of the cluster at `scheduler`, or a local cluster of
    processes started here (and closed after)."""
    if client is not None:
        yield client
        return
    from distributed import Client, LocalCluster

    if scheduler:
        try:
            remote = Client(scheduler, timeout=CONNECT_TIMEOUT)
        except (OSError, TimeoutError) as error:
            raise usage(f"--scheduler {scheduler}: cannot reach it ({error})",
                        "start one with `dask scheduler` and workers with `dask worker ADDRESS`") from None
        with remote:
            yield remote
        return
    count = workers or os.cpu_count() or 1
    with LocalCluster(n_workers=count, threads_per_worker=1, processes=True, dashboard_address=":0",
                      silence_logs=logging.ERROR) as cluster, Client(cluster) as local:
        yield local


def execute(client, bundle, tasks: list):
    """Submit every task and yield (task, result) as they finish; a task that fails on its worker (a worker
    lost three times, a result that cannot travel) becomes an `error` record, and the others go on."""
    from distributed import as_completed

    shared = client.scatter(bundle, broadcast=True)
    futures = {client.submit(run_variant, shared, task, key=f"isaac-variant-{task.id}"): task for task in tasks}
    for future in as_completed(list(futures)):
        task = futures.pop(future)
        try:
            result = future.result()
        except Exception as error:
            result = {"record": {"status": "error",
                                 "diagnostic": f"the task failed on its worker ({type(error).__name__}: {error})"},
                      "files": {}}
        future.release()
        yield task, result


def _finish(task: Task, result: dict, out, journal) -> dict:
    """The record of a finished task, its files written and its journal line appended (files first: a line
    in the journal means the files are there)."""
    record = {"id": task.id, "values": task.values, "options": task.options(), **result["record"]}
    record["outputs"] = store_outputs(out, task, result["files"]) if out is not None else None
    if journal is not None:
        journal.append(record)
    return record


class _Bar:
    """tqdm with the counts of variants ok and failed (and skipped, done by an earlier run)."""

    def __init__(self, total: int, skipped: int, name: str, enabled: bool):
        from tqdm import tqdm

        self.counts = {"ok": 0, "failed": 0, "skipped": skipped}
        self.tqdm = tqdm(total=total, initial=skipped, desc=f"sweep {name}", unit="variant", disable=not enabled,
                         file=sys.stderr, dynamic_ncols=True)
        self.tqdm.set_postfix(self.counts, refresh=False)

    def done(self, status: str) -> None:
        self.counts["failed" if status in FAILED else "ok"] += 1
        self.tqdm.set_postfix(self.counts, refresh=False)
        self.tqdm.update(1)


@contextmanager
def _bar(total: int, skipped: int, name: str, enabled: bool):
    bar = _Bar(total, skipped, name, enabled)
    try:
        yield bar
    finally:
        bar.tqdm.close()
