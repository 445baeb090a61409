"""Scraping and rolling (runtime/audio/scrape.py) and wind (wind_sound.py): the level follows the sliding
speed, contacts fade in without a click, textures load, wind noise rises with the wind, whistles sit at
f = St U / d."""
from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from isaac_ir.diagnostics import SceneError
from isaac_lang.load import load_scene, load_text
from isaac_runtime.audio import compile_audio

FS = 22050
SCENES = Path(__file__).resolve().parents[2] / "scenes"

SCRAPE = """
scene s {{
  time 0 s .. 3 s
  audio {{ rate 22050 Hz }}
  material steel {{ density 7800 kg/m3  roughness 20 um  {texture} }}
  body slope plane {{ material steel }}
  body block box {{ size (0.1, 0.1, 0.1) m  mass 1 kg  material steel }}
  sound scraping on contact(block, slope) {{ play {play} }}
}}
"""


def scrape_plan(play="scrape()", texture="", folder="."):
    return compile_audio(load_text(SCRAPE.format(play=play, texture=texture), name="s.isaac", folder=folder).scene)


def windowed_rms(x, fs=FS, window=0.05):
    n = int(window * fs)
    frames = x[: len(x) // n * n].reshape(-1, n)
    return np.sqrt(np.mean(frames**2, axis=1)), (np.arange(len(frames)) + 0.5) * window


def spearman(a, b) -> float:
    ra, rb = np.argsort(np.argsort(a)), np.argsort(np.argsort(b))
    return float(np.corrcoef(ra, rb)[0, 1])


def ramp_contact(plan, speeds=(0.0, 6.0), force=8.5, start=0.0):
    times = np.arange(start, plan.end + 1e-9, 0.01)  # one contact event per 10 ms frame
    speed = np.interp(times, [start, plan.end], speeds)
    return {("block", "slope"): (times, speed, np.full(len(times), force))}


@pytest.mark.parametrize("play, window, rank", [("scrape()", 0.05, 0.95), ("roll()", 0.25, 0.9)])
def test_scraping_level_follows_the_speed(play, window, rank):
    # rolling reads a smoother profile (beta 3): its level wanders more from window to window
    plan = scrape_plan(play)
    x = plan.render(plan.synthetic_record([], contacts=ramp_contact(plan)))[:, 0]
    rms, times = windowed_rms(x, window=window)
    speed = np.interp(times, [0, 3], [0, 6])
    keep = times > 0.1
    assert spearman(rms[keep], speed[keep]) > rank
    fast, slow = rms[(times > 2.5)].mean(), rms[(times > 0.6) & (times < 0.9)].mean()  # ~6 against ~1.5 m/s
    assert 2.5 < fast / slow < 6.0  # the level rises about linearly with the speed


def test_a_contact_fades_in_without_a_click():
    plan = scrape_plan()
    contacts = {("block", "slope"): ([0.0, 0.49, 0.5, 3.0], [0.0, 0.0, 3.0, 3.0], [0.0, 0.0, 8.5, 8.5])}
    x = plan.render(plan.synthetic_record([], contacts=contacts))[:, 0]
    k = round(0.49 * FS)
    assert np.abs(x[:k]).max() < 1e-12
    first = np.sqrt(np.mean(x[k:k + FS // 1000] ** 2))  # the first millisecond of contact
    steady = np.sqrt(np.mean(x[k + FS // 20:k + FS // 10] ** 2))  # 50-100 ms later
    assert first < 0.3 * steady


def test_a_texture_file_is_the_profile(tmp_path):
    heights = np.cumsum(np.random.default_rng(3).standard_normal(20000)) * 1e-6
    np.save(tmp_path / "grooves.npy", heights)
    plan = scrape_plan(texture=f'texture "{tmp_path / "grooves.npy"}"', folder=tmp_path)
    source = plan.sounds[0].root
    assert "texture grooves.npy" in [n.profile.source for n in source.walk() if hasattr(n, "profile")]
    x = plan.render(plan.synthetic_record([], contacts=ramp_contact(plan)))[:, 0]
    rms, times = windowed_rms(x)
    assert spearman(rms[times > 0.1], times[times > 0.1]) > 0.9
    with pytest.raises(SceneError, match="texture"):
        scrape_plan(texture=f'texture "{tmp_path / "missing.npy"}"', folder=tmp_path)
    # a texture outside the scene's folder is refused, not read (docs/language.md, includes and assets)
    with pytest.raises(SceneError, match="outside"):
        scrape_plan(texture=f'texture "{tmp_path / "grooves.npy"}"', folder=tmp_path / "elsewhere")


WIND = """
scene w {
  time 0 s .. 2 s
  audio { rate 22050 Hz }
  body pole static cylinder { radius 2.5 mm  length 1 m }
  wind breeze { direction (1, 0, 0)  speed 5 m/s }
  sound air on wind(breeze) { play wind_noise() }
  sound tone on wind(breeze) { play whistle(pole) }
}
"""


def wind_render(speed: float, sound: int):
    plan = compile_audio(load_text(WIND, name="w.isaac").scene)
    plan.sounds = [plan.sounds[sound]]
    given = ([0.0, 2.0], [speed, speed])
    return plan.render(plan.synthetic_record([], wind={("listener", "breeze"): given, "pole": given}))[:, 0]


def test_wind_noise_rises_with_the_wind():
    quiet, strong = (np.sqrt(np.mean(wind_render(u, 0) ** 2)) for u in (2.0, 8.0))
    assert strong > 6.0 * quiet  # level ~ U^2 (gusts aside): 16 times


def test_whistle_sits_at_the_strouhal_frequency():
    x = wind_render(10.0, 1)
    f_expected = 0.2 * 10.0 / 0.005  # f = St U / d = 400 Hz
    spectrum = np.abs(np.fft.rfft(x * np.hanning(len(x))))
    freqs = np.fft.rfftfreq(len(x), 1.0 / FS)
    assert freqs[np.argmax(spectrum)] == pytest.approx(f_expected, rel=0.03)
    # narrow: Q about 30, most of the energy within f / Q of the tone
    band = np.abs(freqs - f_expected) < f_expected / 30
    assert np.sum(spectrum[band] ** 2) > 0.5 * np.sum(spectrum**2)


WHISTLES = """
scene w {
  time 0 s .. 1 s
  audio { rate 22050 Hz }
  body pole static cylinder { radius 2.5 mm  length 1 m }
  body rod static cylinder { radius 4 mm  length 1 m  at (1, 0, 0) }
  wind breeze { direction (1, 0, 0)  speed 5 m/s }
  sound tones on wind(breeze) { play mix(whistle(pole), whistle(rod, q = 10)) }
}
"""


def whistles_render(block: int = 2048, stream: bool = False):
    from isaac_runtime.audio.render import Renderer

    plan = compile_audio(load_text(WHISTLES, name="w.isaac").scene, block=block)
    times = np.linspace(0.0, 1.0, 101)
    record = plan.synthetic_record([], wind={"pole": (times, 4.0 + 6.0 * times), "rod": (times, 9.0 - 5.0 * times)})
    if not stream:
        return plan.render(record)[:, 0]
    renderer = Renderer(plan, record, plan.block)
    return np.concatenate([renderer.next_block(final=True)[0] for _ in range(-(-plan.samples // block))])


def test_a_mix_of_whistles_renders_them_as_one_node_with_the_same_samples(monkeypatch):
    """mix(whistle(a), whistle(b)) renders the two as one node (arrays over the whistles); each alone, the
    same samples to rounding."""
    from isaac_runtime.audio import graph

    together = whistles_render()
    monkeypatch.setattr(graph, "merge_whistles", lambda nodes: nodes)
    apart = whistles_render()
    assert np.abs(apart).max() > 0.01
    assert together == pytest.approx(apart, abs=1e-12 * np.abs(apart).max())


def test_whistles_do_not_depend_on_the_block_size():
    """A whistle reads its envelope on a grid fixed in the samples (nodes.FRAME): blocks of whole frames, offline
    or streamed, give the same samples."""
    reference = whistles_render(2048, stream=True)
    for block, stream in ((2048, False), (4096, True), (8192, False)):
        assert whistles_render(block, stream) == pytest.approx(reference, abs=1e-11 * np.abs(reference).max())


def test_reading_a_periodic_profile_over_a_stretch_equals_reading_it_sample_by_sample():
    from isaac_runtime.audio.noise import read_periodic

    profile = np.random.default_rng(5).standard_normal(1000)
    for position in (np.linspace(990.3, 1012.7, 300), np.linspace(-20.5, 3000.25, 400), np.array([999.5])):
        i = np.floor(position).astype(int)
        frac = position - i
        expected = profile[i % 1000] * (1.0 - frac) + profile[(i + 1) % 1000] * frac
        assert read_periodic(profile, position) == pytest.approx(expected, abs=1e-14)


@pytest.mark.slow
def test_scrape_scene_level_follows_the_block(tmp_path):
    """scenes/scrape.isaac: the sound's level follows the block's sliding speed (from its own run)."""
    from isaac_runtime.run import RunOptions, simulate

    result = simulate(load_scene(SCENES / "scrape.isaac").scene, RunOptions())
    x = result.audio.render()[:, 0]
    rms, times = windowed_rms(x, result.audio.plan.fs, 0.1)
    arrays = result.recorder.arrays()
    speed = np.linalg.norm(arrays["linear_velocity"][:, 1], axis=1)
    speed_at = np.interp(times, arrays["time"], speed)
    keep = times > 0.2
    assert spearman(rms[keep], speed_at[keep]) > 0.9


def test_a_wind_that_moves_no_body_is_still_heard():
    """No body feels the wind, so the run has no wind stage: the sound builds the wind's fields itself."""
    from isaac_runtime.run import RunOptions, simulate

    scene = load_text("""scene breeze {
      time 0 s .. 0.3 s
      audio { rate 22050 Hz }
      body bob sphere { radius 5 cm  mass 1 kg }
      wind gale { direction (1, 0, 0)  speed 8 m/s }
      sound air on wind(gale) { play wind_noise() }
    }""", name="breeze.isaac").scene
    result = simulate(scene, RunOptions())
    assert result.simulation.plan.forces.wind is None
    assert result.audio.record.wind[("listener", "gale")].view() == pytest.approx(8.0)
    x = result.audio.render()[:, 0]
    assert np.sqrt(np.mean(x[FS // 10:] ** 2)) > 0.05


@pytest.mark.parametrize("winds", [
    "wind gale { direction (1, 0, 0.3)  speed 6 m/s + 1 m/s * sin(t / 1 s)  turbulence 0.5  gust 0.3 s }",
    "wind gale { direction (1, 0, 0)  speed 6 m/s  turbulence 0.5 }  "
    "wind puff { from (0, 1, 0)  toward (0, 0, 1)  speed 3 m/s  spread 60 deg  turbulence 0.2 }",
])
def test_recorded_wind_speeds_are_the_fields_at_each_probe(winds):
    """The recorder samples every wind series of a step in one evaluation of the field (one wind) or per
    listener wind (several): the same speeds as asking the field point by point."""
    from types import SimpleNamespace

    from isaac_runtime.audio.record import WindField, WindProbes
    from isaac_runtime.run import RunOptions, simulate

    scene = load_text(f"""scene breeze {{
      time 0 s .. 0.2 s
      audio {{ rate 22050 Hz }}
      listener {{ at (0.3, 1, 2) }}
      body pole static cylinder {{ radius 2 mm  length 1 m  at (0.5, 1, 0) }}
      body bob sphere {{ radius 5 cm  mass 10 g  wind on }}
      {winds}
      sound air on wind(gale) {{ play wind_noise() + whistle(pole) + whistle(bob) }}
    }}""", name="breeze.isaac").scene
    result = simulate(scene, RunOptions())
    field = WindField(scene, result.simulation.plan)
    index = {name: i for i, name in enumerate(result.simulation.plan.names)}
    probes = WindProbes.of(result.audio.record.wind, index)
    assert set(probes.keys) == {"pole", "bob", ("listener", "gale")}
    rng = np.random.default_rng(4)
    for t in (0.0, 0.37, 1.5):
        state = SimpleNamespace(x=rng.normal(size=(2, 3)), v=rng.normal(size=(2, 3)))
        speeds = field.speeds(probes, state, t)
        for key, value in zip(probes.keys, speeds):
            if isinstance(key, tuple):
                expected = field.listener_speed(key[1], t)
            else:
                i = index[key]
                expected = np.linalg.norm(field.velocity(state.x[i][None, :], t)[0] - state.v[i])
            assert value == pytest.approx(expected, rel=1e-14, abs=1e-14), key
