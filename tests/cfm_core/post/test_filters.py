"""SAE J211/1 CFC filter against independent truth: the standard's formulas, scipy's Butterworth
design, the frequency-response corridor, an explicit loop of equation (C1), and scipy's filtfilt."""

import math

import numpy as np
import pytest
from scipy import signal

from cfm_core.errors import InputError
from cfm_core.post.filters import cfc_coefficients, cfc_filter, pad_length


def standard_coefficients(cfc, fs):
    """J211/1 Appendix C, written out here independently (tan instead of sin/cos)."""
    wd = 2 * math.pi * cfc * 2.0775
    wa = math.tan(wd / fs / 2)
    d = 1 + math.sqrt(2) * wa + wa**2
    return wa**2 / d, 2 * wa**2 / d, wa**2 / d, -2 * (wa**2 - 1) / d, (-1 + math.sqrt(2) * wa - wa**2) / d


def loop_c1(x, coeffs):
    """Equation (C1) as a plain loop, zero initial state."""
    a0, a1, a2, b1, b2 = coeffs
    y = np.zeros_like(x)
    for i in range(len(x)):
        xm1 = x[i - 1] if i >= 1 else 0.0
        xm2 = x[i - 2] if i >= 2 else 0.0
        ym1 = y[i - 1] if i >= 1 else 0.0
        ym2 = y[i - 2] if i >= 2 else 0.0
        y[i] = a0 * x[i] + a1 * xm1 + a2 * xm2 + b1 * ym1 + b2 * ym2
    return y


def half_sine(fs, tau=4e-3, t0=2e-3, total=12e-3):
    t = np.arange(int(round(total * fs)) + 1) / fs
    x = np.where((t >= t0) & (t <= t0 + tau), np.sin(np.pi * (t - t0) / tau), 0.0)
    return t, x


@pytest.mark.parametrize("fs", [10_000.0, 50_000.0])
def test_coefficients_match_standard_and_butterworth(fs):
    c = cfc_coefficients(600, fs)
    assert c == pytest.approx(standard_coefficients(600, fs), rel=1e-13, abs=1e-15)
    # Same stage from scipy's bilinear Butterworth design at fd = 2.0775 CFC.
    b, a = signal.butter(2, 2.0775 * 600, fs=fs)
    np.testing.assert_allclose(c[:3], b, rtol=1e-12)
    np.testing.assert_allclose([1.0, -c[3], -c[4]], a, rtol=1e-12, atol=1e-15)
    # Unit DC gain: (a0 + a1 + a2) / (1 - b1 - b2) = 1.
    assert sum(c[:3]) / (1 - c[3] - c[4]) == pytest.approx(1.0, abs=1e-12)


@pytest.mark.parametrize("fs", [10_000.0, 50_000.0])
def test_frequency_response_in_j211_corridor(fs):
    a0, a1, a2, b1, b2 = cfc_coefficients(600, fs)
    f = np.array([0.1, 10, 100, 300, 600, 1000])
    _, h = signal.freqz([a0, a1, a2], [1, -b1, -b2], worN=f, fs=fs)
    db = 20 * np.log10(np.abs(h) ** 2)  # forward-backward magnitude is |H|^2
    assert np.all(db[:5] <= 0.5) and np.all(db[:5] >= -1.0)  # passband 0.1 .. 600 Hz
    assert -4.0 <= db[5] <= 0.5  # corridor at FN = 1000 Hz
    assert db[5] == pytest.approx(-3.0, abs=0.3)  # the -3 dB point is ~1000 Hz
    # Above FN the response keeps falling.
    _, h2 = signal.freqz([a0, a1, a2], [1, -b1, -b2], worN=[2000, 4000], fs=fs)
    assert 20 * np.log10(abs(h2[0]) ** 2) < -15 and abs(h2[1]) < abs(h2[0])


@pytest.mark.parametrize("f0", [100.0, 600.0, 1000.0, 3000.0])
def test_sine_gain_and_zero_phase(f0):
    """Steady-state output of a sine equals |H(f0)|^2 times the input, with no phase shift."""
    fs = 50_000.0
    t = np.arange(10_000) / fs
    x = np.sin(2 * np.pi * f0 * t)
    y = cfc_filter(x, fs, 600, pad="zero")
    a0, a1, a2, b1, b2 = cfc_coefficients(600, fs)
    _, h = signal.freqz([a0, a1, a2], [1, -b1, -b2], worN=[f0], fs=fs)
    gain = abs(h[0]) ** 2
    mid = slice(2_000, 8_000)  # away from the zero-padded ends
    np.testing.assert_allclose(y[mid], gain * x[mid], atol=1e-9)


def test_symmetric_pulse_stays_symmetric_and_peak_not_shifted():
    fs = 50_000.0
    t, x = half_sine(fs)
    y = cfc_filter(x, fs)
    centre = int(np.argmax(x))
    assert int(np.argmax(y)) == centre
    k = np.arange(1, 150)
    np.testing.assert_allclose(y[centre + k], y[centre - k], atol=1e-12)
    assert 0.97 < y.max() < 1.0  # a 4 ms pulse is barely smoothed by CFC 600


@pytest.mark.parametrize("fs", [10_000.0, 50_000.0])
def test_matches_explicit_c1_loop(fs):
    """cfc_filter == (C1) looped forward then backward over the zero-padded signal."""
    _, x = half_sine(fs)
    x = x + 0.1 * np.sin(2 * np.pi * 3000 * np.arange(x.size) / fs) * (x > 0)
    n = pad_length(600, fs)
    xp = np.concatenate([np.zeros(n), x, np.zeros(n)])
    c = standard_coefficients(600, fs)
    ref = loop_c1(loop_c1(xp, c)[::-1], c)[::-1][n:n + x.size]
    np.testing.assert_allclose(cfc_filter(x, fs), ref, rtol=0, atol=1e-13)


def test_matches_scipy_filtfilt_with_zero_padding():
    fs = 50_000.0
    _, x = half_sine(fs)
    n = pad_length(600, fs)
    b, a = signal.butter(2, 2.0775 * 600, fs=fs)
    ref = signal.filtfilt(b, a, np.pad(x, n), padtype=None)[n:n + x.size]
    np.testing.assert_allclose(cfc_filter(x, fs), ref, atol=1e-12)


def test_padding_long_enough():
    """Doubling the pad changes nothing: the end transients have decayed inside it."""
    fs = 50_000.0
    _, x = half_sine(fs, t0=0.0, total=4e-3)  # the pulse touches both ends
    n = pad_length(600, fs)
    assert n == math.ceil(5 / 600 * fs)
    b, a = signal.butter(2, 2.0775 * 600, fs=fs)
    ref = signal.filtfilt(b, a, np.pad(x, 2 * n), padtype=None)[2 * n:2 * n + x.size]
    np.testing.assert_allclose(cfc_filter(x, fs), ref, atol=1e-13)


def test_edge_padding_keeps_a_constant():
    y = cfc_filter(np.full(500, 3.5), 50_000.0, pad="edge")
    np.testing.assert_allclose(y, 3.5, rtol=1e-12)
    z = cfc_filter(np.full(500, 3.5), 50_000.0, pad="zero")
    assert z[0] < 2.5  # zero padding means the signal steps up from zero


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_non_finite_input_rejected(bad):
    x = np.zeros(100)
    x[17] = bad
    with pytest.raises(InputError, match=r"x\[17\]"):
        cfc_filter(x, 50_000.0)


def test_parameter_validation():
    with pytest.raises(InputError, match="sample_rate"):
        cfc_filter(np.zeros(10), 5_000.0, cfc=600)  # < 10 x CFC
    with pytest.raises(InputError, match="sample_rate"):
        cfc_coefficients(600, float("nan"))
    with pytest.raises(InputError, match="cfc"):
        cfc_coefficients(-600, 50_000.0)
    with pytest.raises(InputError, match="pad"):
        cfc_filter(np.zeros(10), 50_000.0, pad="mirror")
    with pytest.raises(InputError, match="1-D"):
        cfc_filter(np.zeros((3, 3)), 50_000.0)
    cfc_filter(np.zeros(10), 6_000.0, cfc=600)  # exactly 10 x CFC is allowed
