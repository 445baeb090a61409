"""`isaac sweep`: the command line's options -> variants -> `sweep` -> a summary and the exit code.

Exit codes: 0 every variant ran clean; 2 some variant had a problem of its own (a scene error for its values,
a numerical blow-up), each listed on stderr and in the table; 3 every run finished but some broke a tolerance
(report.json's `checks`, as `isaac run` exits 3); 1 some variant met a bug in isaac.
"""
from __future__ import annotations

import os
import sys
from pathlib import Path

from isaac.sweep.grid import draws, parse_axis, product, usage
from isaac.sweep.task import FAILED
from isaac.writable import check_output_folder

EXIT_OK, EXIT_BUG, EXIT_SCENE, EXIT_TOLERANCE = 0, 1, 2, 3


def run_command(args, verbosity: int = 0) -> int:
    """The body of `isaac sweep` (args from isaac.cli's parser; verbosity -1 quiet: no progress bar and
    no summary, the failures still said)."""
    from isaac.sweep.driver import sweep

    scene = Path(args.scene)
    if not scene.is_file():
        raise usage(f"no such scene file: {scene}")
    variants = command_variants(args.set, args.random, args.seed)
    if args.workers is not None and args.scheduler:
        raise usage("--workers N is the size of the local cluster: not with --scheduler",
                    "the cluster's own workers run the variants: start as many as you want with `dask worker`")
    check_workers(args.workers)
    if args.scheduler:
        check_scheduler_address(args.scheduler)
    out = Path(args.out) if args.out else Path("out") / f"{scene.stem}-sweep"
    check_output_folder(out, "--out")  # before the first variant runs, not after the last
    table = sweep(scene, variants, out=out, keep=args.keep, until=args.until, solver=args.solver,
                  step=args.step, scheduler=args.scheduler, workers=args.workers,
                  progress=verbosity >= 0 and sys.stderr.isatty())
    return summarize(table, scene.stem, out, args.keep, verbosity)


# the most processes of a local cluster: more than the cores only share them, and each holds file handles
MAX_WORKERS_PER_CORE = 4
# the schemes of a Dask scheduler's address (distributed.comm's registry)
SCHEDULER_SCHEMES = ("tcp", "tls", "inproc", "ucx", "ws", "wss")


def check_workers(workers: int | None) -> None:
    limit = MAX_WORKERS_PER_CORE * (os.cpu_count() or 1)
    if workers is not None and workers > limit:
        raise usage(f"--workers {workers}: more than the {limit} processes this machine can use "
                    f"({MAX_WORKERS_PER_CORE} per core)",
                    "leave --workers out for one per core, or start a cluster of your own and give --scheduler")


def check_scheduler_address(address: str) -> None:
    """--scheduler: SCHEME://HOST:PORT (or HOST:PORT, tcp) with a known scheme and a port, read before
    anything connects."""
    from urllib.parse import urlsplit

    example = "e.g. tcp://10.0.0.5:8786 (what `dask scheduler` prints)"
    text = address if "://" in address else f"tcp://{address}"
    try:
        parts = urlsplit(text)
        port = parts.port
    except ValueError as error:
        raise usage(f"--scheduler `{address}`: not an address ({error})", example) from None
    if parts.scheme not in SCHEDULER_SCHEMES:
        raise usage(f"--scheduler `{address}`: unknown scheme `{parts.scheme}`",
                    f"the schemes: {', '.join(SCHEDULER_SCHEMES)}; {example}")
    if parts.scheme != "inproc" and (not parts.hostname or port is None or port == 0):
        raise usage(f"--scheduler `{address}`: an address needs a host and a port", example)


def command_variants(specs: list, random: int | None, seed: int) -> list:
    """The variants of the `--set`s: their product, or `random` draws with `seed`."""
    axes = [parse_axis(item) for item in specs]
    names = [axis.name for axis in axes]
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise usage(f"--set {repeated[0]} given more than once", "list all its values in one --set: NAME=V1,V2,...")
    if random is not None:
        return draws(axes, random, seed)
    return product(axes)


def summarize(table, name: str, out: Path, keep: str, verbosity: int = 0) -> int:
    """Print what happened (failures to stderr, one line each) and return the exit code."""
    failed = table[table["status"].isin(FAILED)]
    for _, row in failed.iterrows():
        values = ", ".join(f"{column[:-4]}={row[column]}" for column in table.columns if column.endswith("_set"))
        text = row["diagnostic"] if isinstance(row["diagnostic"], str) and row["diagnostic"].strip() else row["status"]
        first = text.strip().splitlines()[0]
        print(f"{name} [{values}] ({row['id']}): {row['status']}: {first}", file=sys.stderr)
    skipped = table.attrs.get("skipped", 0)
    kept = f"; outputs in {out / 'variants'}/" if keep == "outputs" else ""
    if verbosity >= 0:
        print(f"{name}: {len(table)} variants ({len(table) - skipped} run, {skipped} done before): "
              f"{len(table) - len(failed)} ok, {len(failed)} failed; table in {out / 'sweep.parquet'} "
              f"and {out / 'sweep.csv'}{kept}")
    statuses = set(failed["status"])
    if "error" in statuses:
        return EXIT_BUG
    if statuses - {"tolerance"}:
        return EXIT_SCENE
    return EXIT_TOLERANCE if statuses else EXIT_OK
