"""The benchmark suite (`isaac bench`): work-precision, peers, scaling, stress, plan specialization, audio.

Modules: suite (the driver), cases (scenes with a known answer and their errors), common (running, timing,
CSV, plots), work_precision, peers (MuJoCo, PyBullet), scaling, stress, specialization. The bench_*.py scripts
beside them are standalone micro-benchmarks of one stage each.
"""
