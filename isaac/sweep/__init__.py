"""Sweeps: many variants of a scene, each one Dask task, on every core here or on a cluster.

    from isaac.sweep import sweep

    table = sweep("scenes/pendulum.isaac", {"theta0": ["10 deg", "45 deg", "90 deg"]}, out="out/sweep")

The stages, one module each: grid (the variants), bundle (the scene and its files, and the variants' ids),
task (one variant on a worker), table (journal, kept outputs, the table), driver (`sweep`). dask, distributed
and pandas are imported only when a sweep runs: `isaac run` never loads them.
"""
from isaac.sweep.driver import sweep

__all__ = ["sweep"]
