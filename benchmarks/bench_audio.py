"""Benchmark of the audio stage (runtime/audio): real-time factor, and modes x seconds per CPU second.

    python benchmarks/bench_audio.py [--seconds 20] [--csv out.csv] [--no-chimes] [--figure docs/figures/...png]

1. "impacts + scrape" (docs/design/sound.md#section-7, how to test 3): a fixed synthetic scene rendered without simulating:
   eight aluminium bars and plates (about 20 modes each) hit 400 times in --seconds, a steel block scraping a
   plank with explicit modes the whole time, and a gusty wind noise. Reports audio seconds per CPU second
   (the real-time factor) and modes x seconds per CPU second (every bank's modes times the audio length).
2. "chimes": scenes/chimes.isaac run as `isaac run` runs it (simulation, recording, rendering), the real-time
   factor including the simulation, and of the audio alone.
Times are process CPU times (a loaded machine slows wall time, not CPU time, much less).
--figure also draws the chimes' spectrogram (docs/figures/chimes_spectrogram.png, matplotlib).
"""
import argparse
import sys
import time
from pathlib import Path

import numpy as np

from isaac_lang.load import load_scene, load_text
from isaac_runtime.audio import compile_audio

SCENES = Path(__file__).resolve().parents[1] / "scenes"

SYNTHETIC = """
scene impacts {{
  time 0 s .. {seconds} s
  audio {{ rate 44100 Hz  channels 2 }}
  listener {{ at (0, 1, 3) }}
  material al {{ density 2700 kg/m3  young 69 GPa  poisson 0.33  loss 0.0003 }}
  material steel {{ density 7800 kg/m3  young 200 GPa  poisson 0.29  roughness 20 um }}
  body floor plane {{ }}
  for i in 0 .. 4 {{ body bar{{i}} box {{ size (0.3 + 0.05 * i, 0.01, 0.03) m  material al  at (i - 2, 0.1, 0) }} }}
  for i in 0 .. 4 {{ body plate{{i}} box {{ size (0.4, 0.3 + 0.02 * i, 0.004) m  material al  at (i - 2, 0.1, 1) }} }}
  body block box {{ size (0.1, 0.1, 0.1) m  mass 1 kg  material steel  at (0, 0.05, -1)
                   modes ((820, 12, 1), (1370, 15, 0.7), (2210, 20, 0.5), (3390, 25, 0.4)) }}
  body plank static box {{ size (2, 0.05, 0.3) m  material steel  at (0, -0.025, -1)
                          modes ((95, 4, 1), (260, 6, 0.8), (510, 9, 0.6), (840, 12, 0.5), (1250, 15, 0.4)) }}
  wind gusts {{ direction (1, 0, 0)  speed 6 m/s  turbulence 0.5  gust 0.4 s }}
  sound hits on collide() {{ play impact() * impulse }}
  sound scraping on contact(block, plank) {{ play scrape() * 0.05 }}
  sound air on wind(gusts) {{ play wind_noise() * 0.05 }}
}}
"""


def synthetic(seconds: float):
    """(plan, record) of the fixed synthetic scene: 400 impacts on ten bodies, a scrape all along, wind."""
    plan = compile_audio(load_text(SYNTHETIC.format(seconds=seconds), name="impacts.isaac").scene)
    rng = np.random.default_rng(0)
    bodies = [f"bar{i}" for i in range(4)] + [f"plate{i}" for i in range(4)]
    events = [{"time": float(t), "bodies": [str(rng.choice(bodies)), "floor"], "point": [0.0, 0.1, 0.0],
               "normal": [0.0, 1.0, 0.0], "impulse": float(rng.uniform(0.05, 0.5)), "tangential_speed": 0.0,
               "normal_speed": float(rng.uniform(0.3, 2.0)), "kind": "impact"}
              for t in np.sort(rng.uniform(0.0, seconds, 400))]
    times = np.arange(0.0, seconds + 1e-9, 0.01)
    speed = 1.5 + np.sin(2 * np.pi * times / 5.0)
    record = plan.synthetic_record(events, contacts={("block", "plank"): (times, speed, np.full(len(times), 9.8))},
                                   wind={("listener", "gusts"): ([0.0, seconds], [6.0, 6.0])})
    return plan, record


def bench_synthetic(seconds: float) -> dict:
    plan, record = synthetic(seconds)
    started = time.process_time()
    samples = plan.render(record)
    cpu = time.process_time() - started
    audio = len(samples) / plan.fs
    modes = plan.mode_count
    return {"case": "impacts + scrape", "audio_s": audio, "cpu_s": cpu, "rtf": audio / cpu, "modes": modes,
            "mode_s_per_cpu_s": modes * audio / cpu, "rtf_with_simulation": float("nan")}


def bench_chimes(figure: str | None = None) -> dict:
    from isaac_runtime.run import RunOptions, simulate

    scene = load_scene(SCENES / "chimes.isaac").scene
    started = time.process_time()
    result = simulate(scene, RunOptions())
    simulated = time.process_time() - started
    started = time.process_time()
    samples = result.audio.render()
    rendered = time.process_time() - started
    audio = len(samples) / result.audio.plan.fs
    modes = result.audio.plan.mode_count
    if figure:
        spectrogram(samples, result.audio.plan.fs, result.simulation.events, figure)
    return {"case": "chimes", "audio_s": audio, "cpu_s": rendered, "rtf": audio / rendered, "modes": modes,
            "mode_s_per_cpu_s": modes * audio / rendered, "rtf_with_simulation": audio / (simulated + rendered)}


def spectrogram(samples: np.ndarray, fs: float, events: list, path: str) -> None:
    """The chimes' sound as a spectrogram, with its strikes marked (ticks at the top)."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    mono = samples.mean(axis=1)
    fig, ax = plt.subplots(figsize=(9, 3.8), dpi=90)
    ax.specgram(mono, NFFT=4096, Fs=fs, noverlap=2048, cmap="magma", vmin=-150, vmax=-20, scale="dB")
    ax.set_ylim(0, 6000)
    strikes = [e["time"] for e in events if e["kind"] == "impact"]
    ax.plot(strikes, [5850] * len(strikes), "v", color="cyan", markersize=5, label="strikes (events.json)")
    ax.set_xlabel("time (s)")
    ax.set_ylabel("frequency (Hz)")
    ax.set_title("scenes/chimes.isaac: tube modes (523, 588, 659, 784, 881 Hz and overtones), wind, whistles")
    ax.legend(loc="upper right", fontsize=8)
    fig.tight_layout()
    fig.savefig(path)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seconds", type=float, default=20.0, help="length of the synthetic scene (default 20)")
    parser.add_argument("--no-chimes", action="store_true", help="skip the chimes scene")
    parser.add_argument("--csv", help="also write the table as CSV to this file")
    parser.add_argument("--figure", help="draw the chimes' spectrogram into this PNG")
    args = parser.parse_args(argv)
    rows = [bench_synthetic(args.seconds)]
    if not args.no_chimes and (SCENES / "chimes.isaac").is_file():
        rows.append(bench_chimes(args.figure))
    keys = ["case", "audio_s", "cpu_s", "rtf", "modes", "mode_s_per_cpu_s", "rtf_with_simulation"]
    print(f"{'case':<18}{'audio s':>9}{'cpu s':>8}{'RTF':>8}{'modes':>7}{'mode*s/cpu s':>14}{'RTF incl. sim':>15}")
    for r in rows:
        print(f"{r['case']:<18}{r['audio_s']:>9.1f}{r['cpu_s']:>8.2f}{r['rtf']:>8.1f}{r['modes']:>7}"
              f"{r['mode_s_per_cpu_s']:>14.0f}{r['rtf_with_simulation']:>15.1f}")
    if args.csv:
        lines = [",".join(keys)] + [",".join(f"{r[k]:.4g}" if isinstance(r[k], float) else str(r[k]) for k in keys)
                                    for r in rows]
        Path(args.csv).write_text("\n".join(lines) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
