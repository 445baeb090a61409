"""Energy and constraint error of the chain scene over time (docs/solver.md). Run: python docs/figures/make_chain_figure.py"""
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from isaac_lang.load import load_scene
from isaac_runtime.run import RunOptions, simulate

ROOT = Path(__file__).resolve().parents[2]


def main() -> None:
    result = simulate(load_scene(ROOT / "scenes" / "chain.isaac").scene, RunOptions(folder=ROOT / "scenes"))
    frames = result.recorder.arrays()
    t, energy = frames["time"], frames["energy"]
    scale = result.report["energy_scale"]
    figure, (top, bottom) = plt.subplots(2, 1, figsize=(7, 5), sharex=True)
    top.plot(t, (energy - energy[0]) / scale)
    top.set_ylabel("(E - E0) / (m g L)")
    top.set_title("chain: 10 links, RK4, h = 0.5 ms, default stabilization")
    bottom.semilogy(t, np.maximum(frames["constraint_error"], 1e-16))
    bottom.set_ylabel("max |C| over joints (m)")
    bottom.set_xlabel("time (s)")
    figure.tight_layout()
    figure.savefig(Path(__file__).with_name("chain_energy.png"), dpi=110)


if __name__ == "__main__":
    main()
