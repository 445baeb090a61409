"""`isaac bench`: the benchmark suite's driver. Each section writes its CSV (and plot) into the output folder;
the summary is then rebuilt from every CSV there (benchmarks/report.py), so a section rerun alone (`--only`)
updates its part of the summary and keeps the others.

    isaac bench                      the full suite into benchmarks/results/ (and docs/performance.md's tables)
    isaac bench --quick              a few minutes: fewer steps and sizes, into benchmarks/results/quick/
    isaac bench --only stress        one section (work_precision, scaling, stress, specialization, audio, profile,
                                     contact, commands)
    isaac bench --out DIR            elsewhere (docs/performance.md is only rewritten for the default folder)

Also `python -m benchmarks.suite ...` with the same options. Exit 0 when every checked property holds (peer
ratios present, 1000-link chain within 12 times the 100-link chain, every stress case finite or stopped by the
runtime's numerical error), 1 otherwise.
"""
from __future__ import annotations

import os

# timing single-threaded, as the peers run: BLAS threads on a 2-core machine only add noise
for _name in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_name, "1")
# the plan's budgets (docs/budgets.md) bound what a scene may ask of one command; the suite's big cases (a
# 1000-link chain for 10 s, the stress runs) ask for more on purpose, and say so here
os.environ.setdefault("ISAAC_BUDGET", "steps=1e8,work=1e10,substeps=1e9,iterations=1e10")

import argparse  # noqa: E402
import importlib  # noqa: E402
import sys  # noqa: E402
import time  # noqa: E402
from pathlib import Path  # noqa: E402

from . import common  # noqa: E402

# the sections in running order, and the module of each (with run(quick, out) -> dict)
SECTION_MODULES = {"work_precision": "work_precision", "scaling": "scaling", "stress": "stress",
                   "specialization": "specialization", "audio": "audio_rtf", "profile": "profiling", "contact": "contact",
                   "commands": "commands"}
SECTIONS = tuple(SECTION_MODULES)
DOC = common.REPO / "docs" / "performance.md"


def run_section(name: str, quick: bool, out: Path) -> dict:
    """Run one section (its module is imported only now: a section's peers and plots cost nothing otherwise)."""
    if name not in SECTION_MODULES:
        raise ValueError(f"unknown section {name}; choose from {', '.join(SECTIONS)}")
    module = importlib.import_module(f"{__package__}.{SECTION_MODULES[name]}")
    return module.run(quick=quick, out=out)


def run(quick: bool = False, only: list | None = None, out: Path | None = None, docs: bool | None = None) -> int:
    from . import report

    out = Path(out) if out else (common.RESULTS / "quick" if quick else common.RESULTS)
    out.mkdir(parents=True, exist_ok=True)
    sections = only or list(SECTIONS)
    begin = time.perf_counter()
    machine = common.machine()
    common.log(f"isaac bench{' --quick' if quick else ''}: {', '.join(sections)} -> {out}  "
               f"({machine['cpus']} cpus, load {machine['load_1min']:.1f})")
    timings = {}
    for name in sections:
        started = time.perf_counter()
        common.log(f"[{name}]")
        run_section(name, quick, out)
        timings[name] = time.perf_counter() - started
        common.log(f"[{name}] {timings[name]:.0f} s")
    total = time.perf_counter() - begin
    report.write_run_info(out, quick, sections, timings, total, machine)
    summary, checks = report.summarize(out)
    (out / "summary.md").write_text(summary)
    if docs if docs is not None else (out.resolve() == common.RESULTS.resolve() and not quick):
        report.update_doc(DOC, summary)
    common.log(f"\nwrote {out}/ (summary.md) in {total / 60:.1f} min")
    for check in checks:
        common.log(f"  [{'ok' if check['ok'] else 'FAILED'}] {check['what']}: {check['measured']}")
    return 0 if all(c["ok"] for c in checks) else 1


def add_arguments(parser: argparse.ArgumentParser) -> None:
    parser.add_argument("--quick", action="store_true",
                        help="a few minutes: fewer steps, sizes and repeats, into benchmarks/results/quick/")
    parser.add_argument("--only", action="append", choices=SECTIONS, metavar="NAME",
                        help=f"run one section (repeatable): {', '.join(SECTIONS)}")
    parser.add_argument("--out", default=None, help="output folder (default benchmarks/results[/quick])")
    parser.add_argument("--docs", action=argparse.BooleanOptionalAction, default=None,
                        help="rewrite docs/performance.md's generated tables (default: for a full run into "
                             "benchmarks/results)")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(prog="python -m benchmarks.suite", description=__doc__.splitlines()[0])
    add_arguments(parser)
    args = parser.parse_args(argv)
    return run(args.quick, args.only, args.out, args.docs)


if __name__ == "__main__":
    sys.exit(main())
