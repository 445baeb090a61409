"""Sweep stage 5, the results: the journal (resumable sweeps), the kept outputs, the table.

DIR/journal.jsonl    one line per finished variant, appended as it finishes (so an interrupted sweep loses
                     nothing; a re-run skips what is in it)
DIR/variants/<id>/   trajectory.npz, events.json, audio.wav, ir.json, report.json (with --keep outputs)
DIR/sweep.parquet    the table, one row per variant in the sweep's order; DIR/sweep.csv the same
"""
from __future__ import annotations

import json
import os
import re
from functools import lru_cache
from pathlib import Path

from isaac.sweep.task import Task

JOURNAL, TABLE = "journal.jsonl", "sweep"
# a table being written: `.sweep.parquet.PID.tmp`, `.sweep.csv.PID.tmp`
TEMPORARY = re.compile(r"^\.sweep\.(parquet|csv)\.(?P<pid>\d+)\.tmp$")
# columns of our own, before the report's scalars (a report key named like one of these gets `report.`)
OWN = ("variant", "id", "status", "diagnostic", "variant_wall_time", "outputs")
RETRIED = ("error",)  # a bug or a lost worker is tried again on a re-run; a scene's own failure is not


class Journal:
    """The finished variants of the sweeps written into one folder: id -> record (the last line of an id wins)."""

    def __init__(self, folder: Path):
        self.folder = Path(folder)
        self.path = self.folder / JOURNAL

    def read(self) -> dict:
        records = {}
        if not self.path.is_file():
            return records
        for line in self.path.read_text(encoding="utf-8").splitlines():
            try:
                record = json.loads(line)
            except json.JSONDecodeError:  # the half-written last line of an interrupted sweep
                continue
            records[record["id"]] = record
        return records

    def done(self, tasks: list) -> dict:
        """The records of these tasks that need no new run: finished, not a bug, their files there if wanted."""
        records = self.read()
        out = {}
        for task in tasks:
            record = records.get(task.id)
            if record is None or record["status"] in RETRIED:
                continue
            kept = outputs_folder(self.folder, task)
            has_files = (kept / "report.json").is_file()
            if task.keep and record["status"] != "scene-error" and not has_files:
                continue
            out[task.id] = dict(record, outputs=kept.as_posix() if has_files else None)
        return out

    def append(self, record: dict) -> None:
        self.path.parent.mkdir(parents=True, exist_ok=True)
        with open(self.path, "a", encoding="utf-8") as handle:
            handle.write(json.dumps(record) + "\n")
            handle.flush()


def store_outputs(folder: Path, task: Task, files: dict) -> str | None:
    """Write a variant's files into folder/variants/<id>/ as one set that replaces an earlier one whole
    (runtime/outputs/outputset.py: written beside it, then swapped in; a kill leaves the old set or the new one)."""
    from isaac_runtime.outputs.outputset import OutputSet

    if not files:
        return None
    target = outputs_folder(folder, task)
    with OutputSet(target, "sweep") as staging:
        for name, data in files.items():
            (staging.path / name).write_bytes(data)
        staging.commit([staging.path / name for name in files], variant=task.id)
    return target.as_posix()


def outputs_folder(folder: Path, task: Task) -> Path:
    return Path(folder) / "variants" / task.id


def build_table(tasks: list, records: dict):
    """One row per task, in order: the values (SI numbers when they are numbers, and as written), our
    columns, then every report scalar."""
    import pandas as pd

    names = list(dict.fromkeys(name for task in tasks for name in task.values))  # in order, each once
    rows = [_row(task, records[task.id], names) for task in tasks if task.id in records]
    table = pd.DataFrame(rows)
    for name in names:  # a parameter whose values are not all numbers keeps its text only
        given = table[f"{name}_set"].notna()
        if table.loc[given, name].isna().any():
            table[name] = table[f"{name}_set"]
    return table


def _row(task: Task, record: dict, names: list) -> dict:
    row = {"variant": task.index, "id": task.id}
    for name in names:  # a parameter this variant does not set keeps the scene's own value: empty here
        text = task.values.get(name)
        row[name] = None if text is None else _si(text, name)
        row[f"{name}_set"] = text
    for key in OWN[2:]:
        row[key] = record.get(key)
    for key, value in record.items():
        if key in OWN or key in ("values", "options"):
            continue
        row[f"report.{key}" if key in row else key] = value
    return row


@lru_cache(maxsize=4096)
def _si(text: str, name: str):
    from isaac.sweep.grid import si_value

    return si_value(text, name)


def write_table(table, folder: Path) -> tuple:
    """DIR/sweep.parquet and DIR/sweep.csv: both written to temporaries (`.sweep.parquet.PID.tmp`), then renamed
    one right after the other; what a killed sweep left of those temporaries is removed first."""
    folder = Path(folder)
    folder.mkdir(parents=True, exist_ok=True)
    _remove_abandoned_temporaries(folder)
    parquet, csv = folder / f"{TABLE}.parquet", folder / f"{TABLE}.csv"
    temporary = {path: folder / f".{path.name}.{os.getpid()}.tmp" for path in (parquet, csv)}
    try:
        table.to_parquet(temporary[parquet], index=False)
        table.to_csv(temporary[csv], index=False)
        for path, written in temporary.items():
            os.replace(written, path)
    finally:
        for written in temporary.values():
            if written.exists():
                written.unlink()
    return parquet, csv


def _remove_abandoned_temporaries(folder: Path) -> None:
    """The table temporaries of sweeps whose process is gone (runtime/outputs/outputset.py's test of a process)."""
    from isaac_runtime.outputs.outputset import abandoned

    for entry in os.scandir(folder):
        match = TEMPORARY.match(entry.name)
        if match and entry.is_file() and abandoned(Path(entry.path), int(match["pid"])):
            try:
                os.unlink(entry.path)
            except FileNotFoundError:
                pass
