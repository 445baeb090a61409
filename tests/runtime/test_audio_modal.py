"""Modal sound (runtime/audio/modal.py, resonator.py, excitation.py) against closed forms and references:
the free-free bar (docs/design/sound.md's oracle), Leissa's plates, Lamb's sphere, the two-pole recursion, decay
slopes."""
from __future__ import annotations

import math

import numpy as np
import pytest

from isaac_lang.load import load_text
from isaac_runtime.audio import compile_audio, modal as M
from isaac_runtime.audio.excitation import contact_duration, half_sine, hertz_duration, rule_duration
from isaac_runtime.audio.resonator import ResonatorBank, two_pole_reference

FS = 44100
BAR = [577.0, 1592.0, 3120.0, 5158.0, 7705.0]  # docs/design/sound.md: aluminium, L 0.30 m, h 10 mm

BAR_SCENE = """
scene bar {
  time 0 s .. 1.5 s
  material aluminium { density 2700 kg/m3  young 69 GPa  poisson 0.33  loss 0.0005 }
  body floor plane { }
  body bar box { size (30 cm, 1 cm, 3 cm)  material aluminium  at (0, 0.2, 0) }
  sound ring on collide(bar, floor) { play modal(bar) * impulse }
}
"""


def hit(time, bodies=("bar", "floor"), point=(0.15, 0.195, 0.0), impulse=0.5, speed=2.0):
    return {"time": time, "bodies": list(bodies), "point": list(point), "normal": [0.0, 1.0, 0.0],
            "impulse": impulse, "tangential_speed": 0.0, "normal_speed": speed, "kind": "impact"}


def bar_plan(text=BAR_SCENE, **kw):
    return compile_audio(load_text(text, name="bar.isaac").scene, **kw)


def spectrum_peak(x, f0, fs=FS, pad=8):
    """Frequency of the largest Hann-windowed, zero-padded FFT bin within 3 % of f0 (parabolic refinement)."""
    window = np.hanning(len(x))
    size = pad * len(x)
    mag = np.abs(np.fft.rfft(x * window, size))
    freqs = np.fft.rfftfreq(size, 1.0 / fs)
    band = np.flatnonzero((freqs > 0.97 * f0) & (freqs < 1.03 * f0))
    i = band[np.argmax(mag[band])]
    a, b, c = np.log(mag[i - 1:i + 2])
    return freqs[i] + 0.5 * (a - c) / (a - 2 * b + c) * (freqs[1] - freqs[0])


# ---- mode models ----------------------------------------------------------------------------------------

def test_free_free_roots_are_sounds_md_values():
    assert M.free_free_roots(5) == pytest.approx([4.7300, 7.8532, 10.9956, 14.1372, 17.2788], abs=1e-4)
    for root in M.free_free_roots(12):
        # cos x cosh x = 1, written as cos x = 1 / cosh x (the product form is ill-conditioned for large x)
        assert math.cos(root) == pytest.approx(1.0 / math.cosh(root), abs=1e-12)


def test_bar_modes_are_euler_bernoulli():
    modes = M.bar_modes(0.30, 0.01 / math.sqrt(12.0), 69e9, 2700.0, count=5)
    # f_n = (beta_n L)^2 h / (2 pi L^2) sqrt(E / (12 rho))
    expected = [r**2 * 0.01 / (2 * math.pi * 0.09) * math.sqrt(69e9 / (12 * 2700)) for r in M.free_free_roots(5)]
    assert modes.freq == pytest.approx(expected, rel=1e-12)
    assert modes.freq == pytest.approx(BAR, rel=2e-3)


def test_beam_function_stable_form_is_the_textbook_one():
    L = 0.3
    x = np.linspace(0.0, L, 41)
    for root in M.free_free_roots(4):
        b = root / L
        s = (math.cosh(root) - math.cos(root)) / (math.sinh(root) - math.sin(root))
        textbook = np.cosh(b * x) + np.cos(b * x) - s * (np.sinh(b * x) + np.sin(b * x))
        assert M.beam_function(x, L, root) == pytest.approx(textbook, abs=1e-8)
    high = M.free_free_roots(20)[-1]
    ends = M.beam_function(np.array([0.0, L]), L, high)
    assert np.abs(ends) == pytest.approx([2.0, 2.0], abs=1e-6)  # no cancellation blow-up for high modes


def test_bar_hit_at_the_centre_favours_symmetric_modes():
    modes = M.bar_modes(0.30, 0.01 / math.sqrt(12.0), 69e9, 2700.0, count=4)
    end, centre = modes.excitation((0.15, 0.0, 0.0)), modes.excitation((0.0, 0.0, 0.0))
    assert end == pytest.approx(np.ones(4))
    assert centre[1] == pytest.approx(M.EXCITATION_UNIFORM, abs=1e-6)  # mode 2 has a node at the centre
    assert centre[0] > centre[1] and centre[2] > centre[1]


def test_free_square_plate_matches_leissa():
    E, nu, rho, h, a = 70e9, 0.3, 2700.0, 0.005, 0.5
    modes = M.plate_modes(a, a, h, E, nu, rho, count=4)
    D = E * h**3 / (12 * (1 - nu**2))
    lam = 2 * np.pi * modes.freq * a**2 * np.sqrt(rho * h / D)
    # Leissa (1973), completely free square plate, nu = 0.3: 13.468, 19.596, 24.270, 34.801
    assert lam[:4] == pytest.approx([13.468, 19.596, 24.270, 34.801], rel=0.01)


def test_free_disc_matches_leissa():
    E, nu, rho, h, r = 70e9, 0.33, 2700.0, 0.002, 0.1
    modes = M.disc_modes(r, h, E, nu, rho, count=4)
    D = E * h**3 / (12 * (1 - nu**2))
    lam2 = 2 * np.pi * modes.freq * r**2 * np.sqrt(rho * h / D)
    # Leissa (1969), free circular plate, nu = 0.33 (Itao and Crandall): 5.253, 9.084, 12.23, 20.52
    assert lam2 == pytest.approx([5.253, 9.084, 12.23, 20.52], rel=5e-3)


def test_sphere_matches_lamb():
    nu, E, rho, a = 0.25, 200e9, 7800.0, 0.05
    modes = M.sphere_modes(a, E, nu, rho, count=3)
    c_t = math.sqrt(E / (2 * (1 + nu)) / rho)
    eta = 2 * np.pi * modes.freq * a / c_t
    # the lowest spheroidal mode (n = 2) of a free sphere, nu = 1/4: eta = 2.6399 (Lamb 1882)
    assert eta[0] == pytest.approx(2.6399, abs=2e-4)


def test_damping_models():
    f = np.array([100.0, 1000.0])
    assert M.rayleigh_decay(f, 2.0, 1e-7) == pytest.approx((2.0 + 1e-7 * (2 * np.pi * f) ** 2) / 2)
    assert M.loss_decay(f, 1e-3) == pytest.approx(np.pi * f * 1e-3)
    assert M.rt60_decay(2.0) == pytest.approx(6.9078 / 2.0, rel=1e-4)


def test_modes_near_nyquist_are_switched_off():
    modes = M.Modes(np.array([100.0, 9000.0, 10000.0, 30000.0]), np.zeros(4), np.ones(4), "test")
    kept = modes.audible(22050.0)
    assert list(kept.freq) == [100.0, 9000.0]  # 10 kHz is above 0.9 x 11025 Hz
    assert kept.gain.sum() == pytest.approx(1.0)


def test_auto_model_choice():
    scene = load_text("""scene s {
      material al { density 2700 kg/m3  young 69 GPa }
      body rod cylinder { radius 1 cm  length 50 cm  material al }
      body disc cylinder { radius 10 cm  length 5 mm  material al }
      body plate box { size (0.4, 0.3, 0.004) m  material al }
      body ball sphere { radius 10 cm  material al }
      body floor plane { }
    }""").scene
    models = {b.name: M.body_modes(b, scene.materials[0]).model for b in scene.bodies if b.name != "floor"}
    assert models == {"rod": "free-free bar", "disc": "free circular plate", "plate": "free rectangular plate (Ritz)",
                      "ball": "free sphere (Lamb)"}
    with pytest.raises(M.ModalError, match="modes"):
        M.body_modes(scene.bodies[-1], None)


# ---- the resonator bank ---------------------------------------------------------------------------------

def test_bank_equals_the_two_pole_recursion_across_blocks():
    fs, block, total = 8000.0, 64, 400
    f = np.array([100.0, 900.0, 2500.0, 3500.0])
    d = np.array([3.0, 20.0, 50.0, 5.0])
    a = np.array([0.4, 0.3, 0.2, 0.1])
    rng = np.random.default_rng(0)
    inputs = [(10, half_sine(0.002, fs), np.array([1.0, 0.5, 0.2, 1.0])),  # crosses a block edge
              (60, half_sine(0.0001, fs), np.array([0.3, 1.0, 1.0, 1.0])),
              (130, rng.standard_normal(150), np.ones(4))]  # a dense drive over three blocks
    X = np.zeros((total, 4))
    for s0, x, g in inputs:
        X[s0:s0 + len(x)] += np.outer(x, g)
    reference = two_pole_reference(f, d, a, fs, X)
    bank = ResonatorBank(f, d, a, fs, block)
    out = []
    for b0 in range(0, total, block):
        n = min(block, total - b0)
        parts = []
        for s0, x, g in inputs:
            lo, hi = max(s0, b0), min(s0 + len(x), b0 + n)
            if lo < hi:
                parts.append((g, lo - b0, x[lo - s0:hi - s0]))
        out.append(bank.render(n, parts))
    assert np.concatenate(out) == pytest.approx(reference, abs=1e-10 * np.abs(reference).max())


def bank_blocks(bank, total: int, block: int, inputs) -> np.ndarray:
    """A bank rendered in blocks of `block` samples; inputs (s0, x, gains) cut at the blocks' edges."""
    out = []
    for b0 in range(0, total, block):
        n = min(block, total - b0)
        parts = [(g, max(s0, b0) - b0, x[max(s0, b0) - s0:min(s0 + len(x), b0 + n) - s0])
                 for s0, x, g in inputs if max(s0, b0) < min(s0 + len(x), b0 + n)]
        out.append(bank.render(n, parts, b0))
    return np.concatenate(out)


def test_bank_does_not_depend_on_the_block_size_and_groups_fall_silent_apart():
    """Two bodies in one bank (groups) against each alone, in blocks of several sizes: the same samples, each
    body's silence tested at the same frame edges (one rings briefly, the other long, hit again later)."""
    fs, frame, total = 8000.0, 256, 6000
    f, d, a = np.array([300.0, 700.0, 450.0, 1200.0]), np.array([400.0, 500.0, 2.0, 3.0]), np.ones(4) / 4
    pulse = half_sine(0.001, fs)
    inputs = [(100, pulse, np.array([1.0, 1.0, 0.0, 0.0])), (300, pulse, np.array([0.0, 0.0, 1.0, 0.5])),
              (3000, pulse, np.array([1.0, 0.5, 0.0, 0.0]))]
    alone = sum(bank_blocks(ResonatorBank(f[part], d[part], a[part], fs, frame), total, frame,
                            [(s0, x, g[part]) for s0, x, g in inputs]) for part in (slice(0, 2), slice(2, 4)))
    for block in (frame, 100, 700, 4 * frame):
        together = bank_blocks(ResonatorBank(f, d, a, fs, frame, groups=[2, 2]), total, block, inputs)
        assert together == pytest.approx(alone, abs=1e-13)
    quiet = ResonatorBank(f, d, a, fs, frame, groups=[2, 2])
    bank_blocks(quiet, 2000, frame, inputs[:2])
    assert not np.any(quiet.state[:2]) and np.all(quiet.state[2:] != 0)  # the brief one has fallen silent


def test_a_second_hit_adds_to_the_ringing():
    plan = bar_plan()
    both = plan.render(plan.synthetic_record([hit(0.2), hit(0.5, impulse=0.3)]))
    first = plan.render(plan.synthetic_record([hit(0.2)]))
    second = plan.render(plan.synthetic_record([hit(0.5, impulse=0.3)]))
    assert both == pytest.approx(first + second, abs=1e-9)  # linear: the first hit keeps ringing
    k = round(0.5 * FS)
    assert np.abs(first[k:k + 100]).max() > 0.05  # and it was still ringing when the second came


def test_bar_spectrum_peaks_at_euler_bernoulli_within_half_a_percent():
    plan = bar_plan()
    x = plan.render(plan.synthetic_record([hit(0.2)]))[:, 0]
    onset = round(0.2 * FS)
    for f0 in M.bar_modes(0.30, 0.01 / math.sqrt(12.0), 69e9, 2700.0, count=3).freq:
        assert spectrum_peak(x[onset:], f0) == pytest.approx(f0, rel=0.005)


def test_mode_decay_slopes_match_the_damping_model():
    plan = bar_plan()
    modes = plan.sounds[0].modes["bar"]
    x = plan.render(plan.synthetic_record([hit(0.1)]))[round(0.1 * FS):, 0]
    t = np.arange(len(x)) / FS
    for f, d in list(zip(modes.freq, modes.decay))[:4]:
        # heterodyne mode n to 0 Hz, low-pass with a 40 ms Hann window (the other modes are > 1 kHz away, where
        # its side lobes are below -100 dB), fit a line to log |envelope|
        base = x * np.exp(-2j * np.pi * f * t)
        window = np.hanning(int(0.04 * FS))
        envelope = np.abs(np.convolve(base, window / window.sum(), mode="valid"))
        times = t[:len(envelope)] + 0.02
        keep = (times > 0.05) & (times < 0.6)
        slope = np.polyfit(times[keep], np.log(envelope[keep]), 1)[0]
        assert -slope == pytest.approx(d, rel=0.05)


# ---- contact duration and pulse -------------------------------------------------------------------------

def test_contact_duration():
    steel = {"mass": 1.0, "radius": 0.05, "young": 200e9, "poisson": 0.29}
    tau = contact_duration(steel, dict(steel), 1.6, FS)
    e_eff = 1.0 / (2 * (1 - 0.29**2) / 200e9)
    assert tau == pytest.approx(hertz_duration(0.5, 0.025, e_eff, 1.6))
    assert 1e-4 < tau < 3e-4  # steel balls of a cradle: about 0.16 ms
    flat = {"mass": 0.243, "radius": math.inf, "young": 69e9, "poisson": 0.33}
    assert contact_duration(flat, None, 2.0, FS) == pytest.approx(rule_duration(0.243)) == pytest.approx(0.243e-3)
    assert contact_duration({**flat, "mass": 10.0}, None, 2.0, FS) == pytest.approx(2e-3)
    assert contact_duration({**flat, "mass": 1e-6}, None, 2.0, FS) == pytest.approx(1.0 / FS)


def test_half_sine_pulse():
    x = half_sine(1e-3, FS)
    assert len(x) == 44 and x.sum() == pytest.approx(1.0)
    assert x[0] > 0.01 * x.max()  # sampled at mid-points: sound from the first sample
    assert half_sine(1e-3, FS, area=False).max() == pytest.approx(1.0, abs=1e-3)
    assert list(half_sine(1e-9, FS)) == [1.0]


@pytest.mark.parametrize("nu", [0.0, 0.22, 0.3, 0.33, 0.49])
def test_sphere_root_table_is_the_solver(nu):
    from isaac_runtime.audio.sphere_roots import SPHERE_ROOTS

    assert SPHERE_ROOTS[nu] == M.solve_sphere_roots(nu)
    assert M._sphere_roots(nu, 5) == M.solve_sphere_roots(nu)[:5]
    assert M._sphere_roots(0.2537, 5) == M.solve_sphere_roots(0.2537)[:5]  # not in the table: solved
