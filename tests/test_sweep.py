"""Sweeps (isaac/sweep, `isaac sweep`): the grid, the bundle, the table, resuming; on a local cluster, and on
a scheduler and a worker started here on loopback. The pendulum's period of every variant against the elliptic
integral for that variant's own amplitude."""
from __future__ import annotations

import json
import math
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest
from scipy.special import ellipk

from isaac.cli import main
from isaac_ir.diagnostics import SceneError
from isaac.sweep import sweep
from isaac.sweep.bundle import collect, variant_id
from isaac.sweep.command import command_variants
from isaac.sweep.grid import parse_axis, si_value, variants_of

from .runtime.test_scenes import measured_period

ROOT = Path(__file__).resolve().parents[1]
PENDULUM = ROOT / "scenes" / "pendulum.isaac"
AMPLITUDES = ("10deg", "45deg", "90deg", "120deg")
# scenes/pendulum.isaac: m = 1 kg, L = 1 m, r = 5 cm; I_p = m L^2 + 2/5 m r^2
INERTIA, MASS, LENGTH, G = 1.0 + 0.4 * 0.05**2, 1.0, 1.0, 9.81
# compared without the columns that measure time or name this run's folder
VARYING = ["wall_time", "variant_wall_time", "outputs"]
# a pendulum whose stabilization decides between a clean run and a numerical blow-up (tests/runtime/test_run.py)
UNSTABLE = """let stabilization = 2 Hz
scene unstable {
  time 0 s .. 1 s
  solver dynamics { step 20 ms  stabilize stabilization  tolerance 0 }
  body bob sphere { radius 5 cm  mass 1 kg  at (1, 0, 0) }
  constraint hang nail(bob @ (-0.9, 0, 0), (0, 0, 0))
}
"""


def exact_period(theta0: float) -> float:
    """T = 4 sqrt(I_p / (m g L)) K(sin^2(theta0 / 2)) (scipy's K takes the parameter m = k^2)."""
    return 4 * math.sqrt(INERTIA / (MASS * G * LENGTH)) * ellipk(math.sin(theta0 / 2) ** 2)


def assert_periods_match(table) -> None:
    """Every variant's period, from the zero crossings of x in its own kept trajectory, to 1e-6."""
    assert list(table["status"]) == ["ok"] * len(table)
    for _, row in table.iterrows():
        with np.load(Path(row["outputs"]) / "trajectory.npz", allow_pickle=False) as data:
            period = measured_period(dict(data), 0)
        assert row["theta0"] == pytest.approx(si_value(row["theta0_set"]))
        assert abs(period / exact_period(row["theta0"]) - 1) < 1e-6, (row["theta0_set"], period)


def read_table(folder: Path):
    import pandas as pd

    return pd.read_parquet(folder / "sweep.parquet")


# ---- the grid ---------------------------------------------------------------------------------------------

def test_lists_and_counted_ranges_make_a_product_in_order():
    variants = command_variants(["theta0=10deg,20 deg", "length=1m..2m/3"], None, 0)
    assert [v["theta0"] for v in variants] == ["10deg"] * 3 + ["20 deg"] * 3
    assert [si_value(v["length"]) for v in variants[:3]] == [1.0, 1.5, 2.0]  # both ends, evenly spaced
    assert parse_axis("p=(0, 1, 0),(1, 0, 0)").values == ("(0, 1, 0)", "(1, 0, 0)")  # vectors stay whole
    values = parse_axis("theta0=5deg..175deg/30").values
    assert len(values) == 30 and si_value(values[-1]) == math.radians(175)


def test_random_draws_stay_in_their_ranges_and_repeat_with_the_seed():
    first = command_variants(["theta0=10deg..120deg", "length=1m,2m"], 20, 7)
    assert first == command_variants(["theta0=10deg..120deg", "length=1m,2m"], 20, 7)
    assert first != command_variants(["theta0=10deg..120deg", "length=1m,2m"], 20, 8)
    assert all(math.radians(10) <= si_value(v["theta0"]) <= math.radians(120) for v in first)
    assert {v["length"] for v in first} == {"1m", "2m"}


@pytest.mark.parametrize("spec", ["theta0", "theta0=", "theta0=10deg,,20deg", "theta0=10deg..(", "=1",
                                  "theta0=10deg..20deg", "theta0=1..2/0", "theta0=1,2..3", "theta0=1m..2s/3"])
def test_bad_specifications_are_usage_errors(spec):
    with pytest.raises(SceneError):
        command_variants([spec], None, 0)


def test_the_api_takes_lists_specs_numbers_and_explicit_variants():
    assert variants_of({"theta0": ["10 deg", 0.5]}) == [{"theta0": "10 deg"}, {"theta0": "0.5"}]
    assert len(variants_of({"theta0": "10deg..20deg/4"})) == 4
    assert variants_of([{"theta0": "1 deg", "length": 2}]) == [{"theta0": "1 deg", "length": "2.0"}]


# ---- the bundle -------------------------------------------------------------------------------------------

def test_the_bundle_carries_includes_and_assets():
    included = collect(ROOT / "tests" / "lang" / "data" / "includes.isaac")
    assert sorted(included.files) == ["includes.isaac", "lib/materials.isaac", "lib/shapes.isaac"]
    mobile = collect(ROOT / "scenes" / "mobile.isaac")
    assert sorted(mobile.files) == ["assets/breath.wav", "mobile.isaac"]
    assert mobile.files["assets/breath.wav"] == (ROOT / "scenes" / "assets" / "breath.wav").read_bytes()


def test_variant_ids_depend_on_the_scene_the_values_and_the_options(tmp_path):
    bundle = collect(PENDULUM)
    base = variant_id(bundle, {"theta0": "10deg"}, {"until": 12.0})
    assert base == variant_id(collect(PENDULUM), {"theta0": "10deg"}, {"until": 12.0})
    assert base != variant_id(bundle, {"theta0": "11deg"}, {"until": 12.0})
    assert base != variant_id(bundle, {"theta0": "10deg"}, {"until": 11.0})
    edited = tmp_path / "pendulum.isaac"
    edited.write_text(PENDULUM.read_text() + "\n# edited\n")
    assert base != variant_id(collect(edited), {"theta0": "10deg"}, {"until": 12.0})


# ---- on a local cluster -----------------------------------------------------------------------------------

@pytest.fixture(scope="module")
def client():
    """An in-process cluster (one worker thread): the sweep's Dask path without starting processes."""
    from distributed import Client

    with Client(processes=False, n_workers=1, threads_per_worker=1, dashboard_address=":0") as local:
        yield local


def test_each_variant_has_the_period_of_its_own_amplitude(client, tmp_path):
    table = sweep(PENDULUM, {"theta0": list(AMPLITUDES)}, client, out=tmp_path, until=12)
    assert list(table["theta0_set"]) == list(AMPLITUDES) and list(table["variant"]) == [0, 1, 2, 3]
    assert_periods_match(table)
    assert read_table(tmp_path).drop(columns=VARYING).equals(table.drop(columns=VARYING))
    assert (tmp_path / "sweep.csv").is_file()
    for _, row in table.iterrows():  # the files of `isaac run`, and the table holds report.json's scalars
        kept = Path(row["outputs"])
        assert kept == tmp_path / "variants" / row["id"]
        report = json.loads((kept / "report.json").read_text())
        assert {p.name for p in kept.iterdir()} >= {"trajectory.npz", "events.json", "ir.json", "report.json"}
        assert row["steps"] == report["steps"] and row["max_constraint_error"] == report["max_constraint_error"]


def test_failing_variants_record_their_diagnostic_and_the_others_go_on(client, tmp_path):
    scene = tmp_path / "unstable.isaac"
    scene.write_text(UNSTABLE)
    table = sweep(scene, {"stabilization": ["2 Hz", "200 Hz", "1 kg"]}, client, out=tmp_path / "out")
    assert list(table["status"]) == ["ok", "blow-up", "scene-error"]
    assert table["diagnostic"].isna()[0]
    assert "numerical blow-up" in table["diagnostic"][1]
    # a value of the wrong dimension is the `--set`'s mistake (docs/language.md), said with the let it sets
    assert "`--set stabilization=1 kg` gives a mass" in table["diagnostic"][2]
    assert "frequency" in table["diagnostic"][2] and "unstable.isaac:1:" in table["diagnostic"][2]
    assert (Path(table["outputs"][1]) / "trajectory.npz").is_file()  # kept up to the blow-up, as `isaac run` does
    assert table["outputs"].isna()[2]


def test_assets_travel_with_the_tasks(client, tmp_path):
    table = sweep(ROOT / "scenes" / "mobile.isaac", {"breath": ["1 m/s", "3 m/s"]}, client, keep="table",
                  until=0.2)
    assert list(table["status"]) == ["ok", "ok"] and table["outputs"].isna().all()
    table = sweep(ROOT / "tests" / "lang" / "data" / "includes.isaac", [{}], client, until=0.1)
    assert list(table["status"]) == ["ok"]


def test_an_unknown_parameter_stops_the_sweep_before_it_starts(tmp_path):
    with pytest.raises(SceneError, match="no parameter `theta`"):
        sweep(PENDULUM, {"theta": ["10deg"]}, client=object(), out=tmp_path)  # the client is never used
    assert not tmp_path.joinpath("journal.jsonl").exists()


# ---- the command, on local clusters of processes ----------------------------------------------------------

def test_cli_resumes_and_gives_the_same_table_for_any_number_of_workers(tmp_path, capsys):
    args = ["sweep", str(PENDULUM), "--set", "theta0=10deg,120deg,1kg", "--until", "3"]
    assert main(args + ["--out", str(tmp_path / "two"), "--workers", "2"]) == 2  # one variant fails
    out, err = capsys.readouterr()
    assert "3 variants (3 run, 0 done before): 2 ok, 1 failed" in out and "theta0=1kg" in err
    first = read_table(tmp_path / "two")
    journal = (tmp_path / "two" / "journal.jsonl").read_text()
    assert main(args + ["--out", str(tmp_path / "two"), "--workers", "2"]) == 2
    assert "(0 run, 3 done before)" in capsys.readouterr().out
    assert (tmp_path / "two" / "journal.jsonl").read_text() == journal  # nothing ran again
    assert read_table(tmp_path / "two").equals(first)
    assert main(args + ["--out", str(tmp_path / "one"), "--workers", "1", "--keep", "table"]) == 2
    one = read_table(tmp_path / "one")
    assert one.drop(columns=VARYING).equals(first.drop(columns=VARYING))
    assert list(one["id"]) == list(first["id"]) and not (tmp_path / "one" / "variants").exists()


def test_cli_usage_errors_exit_2(tmp_path, capsys):
    assert main(["sweep", str(PENDULUM), "--set", "theta0=10deg..20deg"]) == 2
    assert "needs a count" in capsys.readouterr().err
    assert main(["sweep", str(PENDULUM), "--set", "theta0=1deg", "--scheduler", "tcp://127.0.0.1:9",
                 "--workers", "2"]) == 2
    assert main(["sweep", str(tmp_path / "none.isaac"), "--set", "theta0=1deg"]) == 2


# ---- on a scheduler and a worker started here -------------------------------------------------------------

@pytest.fixture
def scheduler(tmp_path):
    """`dask scheduler` and `dask worker` (two processes, one thread each) on loopback; yields the address."""
    file = tmp_path / "scheduler.json"
    quiet = {"stdout": subprocess.DEVNULL, "stderr": subprocess.DEVNULL}
    processes = [subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_scheduler", "--host", "127.0.0.1",
                                   "--port", "0", "--no-dashboard", "--scheduler-file", str(file)], **quiet)]
    try:
        deadline = time.monotonic() + 30
        while not file.is_file() and time.monotonic() < deadline:
            time.sleep(0.1)
        address = json.loads(file.read_text())["address"]
        processes.append(subprocess.Popen([sys.executable, "-m", "distributed.cli.dask_worker", address,
                                           "--nworkers", "2", "--nthreads", "1", "--no-dashboard"],
                                          cwd=tmp_path, **quiet))
        from distributed import Client

        with Client(address, timeout="30s") as probe:
            probe.wait_for_workers(2, timeout=60)
        yield address
        with Client(address, timeout="30s") as last:
            last.shutdown()  # the scheduler closes its workers: quicker than a signal to each
    finally:
        for process in reversed(processes):
            try:
                process.wait(timeout=15)
            except subprocess.TimeoutExpired:
                process.terminate()
                process.wait(timeout=30)


def test_cli_on_a_scheduler_and_workers_started_on_loopback(scheduler, tmp_path, capsys):
    out = tmp_path / "out"
    assert main(["sweep", str(PENDULUM), "--set", f"theta0={','.join(AMPLITUDES)}", "--until", "12",
                 "--out", str(out), "--scheduler", scheduler]) == 0
    assert "4 variants (4 run, 0 done before): 4 ok, 0 failed" in capsys.readouterr().out
    assert_periods_match(read_table(out))


# ---- what `isaac run` does not pay for --------------------------------------------------------------------

def test_run_and_the_sweep_package_import_neither_dask_nor_pandas():
    code = ("import sys, isaac.cli, isaac_runtime.run, isaac.sweep, isaac.sweep.command; "
            "isaac.cli.build_parser(); "
            "print(sorted(m for m in ('dask', 'distributed', 'pandas', 'pyarrow') if m in sys.modules))")
    result = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert result.stdout.strip() == "[]"
