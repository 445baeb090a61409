"""Smoke test of the benchmark suite (benchmarks/, `isaac bench`): its cheapest pieces, in a few seconds.

The suite itself (minutes to an hour) runs with `isaac bench [--quick]`, or here with -m bench.
"""
from __future__ import annotations

import math

import pytest

from benchmarks import cases, common, report, stress, work_precision
from isaac.cli import build_parser


def test_the_command_has_bench():
    args = build_parser().parse_args(["bench", "--quick", "--only", "stress", "--out", "x"])
    assert (args.command, args.quick, args.only, args.out) == ("bench", True, ["stress"], "x")


def test_pendulum_period_measured_against_the_elliptic_integral():
    case = cases.BY_NAME["pendulum10"]
    row = work_precision.run_ours(case, "dynamics", "rk4", 1e-2)
    assert row["status"] == "ok" and row["steps"] == round(case.until / 1e-2)
    assert 0 < row["period_error"] < 1e-6  # RK4 at 10 ms: ~3e-8
    assert row["joint_drift"] < 1e-6 and row["energy_drift"] < 1e-6


def test_a_stress_case_ends_within_its_bounds():
    case = next(c for c in stress.cases(1000) if c.name == "large step pendulum 1/30 s")
    row = stress.run_case(case, "dynamics", quick=True)
    assert row["outcome"] == "within bounds", row
    assert row["step"] == pytest.approx(1 / 30) and row["reached"] == pytest.approx(case.until)


def test_a_silent_nan_is_reported_as_such():
    case = stress.Stress("nan", "x", stress.two_links(1.0, 1.0), plans=("dynamics",), until=0.01, error=1.0)

    class Broken(stress.Watch):
        def look(self, sim):
            sim.state.q[0, 0] = math.nan  # the runtime's own check looks at x, v, w: q is ours to watch
            super().look(sim)

    original = stress.Watch
    stress.Watch = Broken
    try:
        row = stress.run_case(case, "dynamics", quick=True)
    finally:
        stress.Watch = original
    assert row["outcome"] in ("SILENT NaN", "numerical error")


def test_summary_from_csvs(tmp_path):
    case = cases.BY_NAME["pendulum10"]
    result = {"rows": [work_precision.run_ours(case, "dynamics", "rk4", 1e-2)], "ratios": [], "floors": {}}
    work_precision.write(result, [case], tmp_path)
    text, checks = report.summarize(tmp_path)
    assert "pendulum10" in text and (tmp_path / "work_precision.png").is_file()
    assert {c["what"] for c in checks} >= {"peer ratios present for mujoco", "work_precision.csv written"}


def test_mujoco_pendulum_matches_the_same_measure():
    pytest.importorskip("mujoco")
    from benchmarks import mechanisms, peers

    case = cases.BY_NAME["pendulum10"]
    outcome = peers.run_peer(mechanisms.mechanism(case), "mujoco", "reduced", "rk4", 1e-2, case.until)
    assert outcome.ok and case.measure(outcome.trajectory)["period_error"] < 1e-6


@pytest.mark.bench
def test_quick_suite(tmp_path):
    from benchmarks import suite

    assert suite.run(quick=True, out=tmp_path, docs=False) == 0
    assert (tmp_path / "summary.md").is_file()


def test_common_probe_keeps_the_start():
    p = common.Probe(1, 4, 1)
    p.record(0.0, [[1, 2, 3]], [[1, 0, 0, 0]], [[0, 0, 0]], [[0, 0, 0]])
    assert p.trajectory()["position"].shape == (1, 1, 3)


def test_every_benchmark_script_imports():
    """The bench_*.py scripts run outside `isaac bench`: an import that went stale must still fail here."""
    import importlib
    from pathlib import Path

    folder = Path(cases.__file__).parent
    for path in sorted(folder.glob("*.py")):
        importlib.import_module(f"benchmarks.{path.stem}")


def test_the_command_line_offers_every_section_of_the_suite():
    from benchmarks import suite
    from isaac.cli import BENCH_SECTIONS

    assert tuple(BENCH_SECTIONS) == tuple(suite.SECTIONS)
