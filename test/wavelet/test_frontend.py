"""Even/odd (quadrature) channels with a quarter-period delay (section 4.3)."""

from __future__ import annotations

import numpy as np
import pytest
import pywt

from amb_wavelet.analysis import AnalysisFilterbank, analyze_block
from amb_wavelet.frames import to_rotating_frame
from amb_wavelet.frontend import ChannelFrontEnd, QuarterPeriodDelay


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4", "sym4"])
def test_quadrature_magnitude_is_phase_independent(wavelet: str) -> None:
    spr, level = 32, 5  # level 5 = 1 x running speed (p = 1)
    n = np.arange(30 * spr)
    amplitude = 40e-6
    fe = ChannelFrontEnd(spr, frames=("fixed",), quadrature=("even", "odd"), n_sensor_channels=2)
    assert fe.quarter_delay == 8
    magnitudes, evens = [], []
    for phi in np.linspace(0, 2 * np.pi, 25, endpoint=False):
        x = amplitude * np.cos(2 * np.pi * n / spr + phi)
        xy = np.stack([x, np.zeros_like(x)], axis=1)
        fe.reset()
        ch = fe.process_block(xy, np.zeros(n.size))
        d = analyze_block(ch, wavelet, level).details[level - 1][-5:]  # steady coefficients
        even, odd = d[:, 0], d[:, 2]
        magnitudes.append(np.hypot(even, odd))
        evens.append(even)
    magnitudes = np.array(magnitudes)
    # reference |A Psi(omega)| from PyWavelets' own level-5 wavelet (pywt.upcoef)
    psi = pywt.upcoef("d", [1.0], wavelet, level=level)
    k = np.arange(psi.size)
    expected = amplitude * abs(np.sum(psi * np.exp(2j * np.pi * k / spr)))
    np.testing.assert_allclose(magnitudes, expected, rtol=1e-9, atol=0)
    assert expected > 0.5 * amplitude
    # the even channel alone goes through zero for some phase (figure 4.6)
    evens = np.abs(np.array(evens))
    assert evens.min() < 0.15 * evens.max()


def test_block_equals_step_and_labels(rng: np.random.Generator) -> None:
    spr = 16
    fe_a = ChannelFrontEnd(spr)
    fe_b = ChannelFrontEnd(spr)
    assert fe_a.n_channels == 32
    labels = fe_a.labels
    assert labels[:2] == ["fixed/even/x1", "fixed/even/y1"]
    assert labels[8] == "fixed/odd/x1"
    assert labels[16] == "rotating/even/u1" and labels[31] == "rotating/odd/v4"
    xy = rng.standard_normal((100, 8))
    th = rng.uniform(0, 6, 100)
    stepped = np.array([fe_a.step(xy[i], th[i]) for i in range(100)])
    block = np.concatenate(
        [fe_b.process_block(xy[:37], th[:37]), fe_b.process_block(xy[37:], th[37:])]
    )
    np.testing.assert_allclose(stepped, block, rtol=0, atol=1e-15)
    # independent references: even fixed = input; odd rotating = rotating frame delayed
    np.testing.assert_array_equal(stepped[:, :8], xy)
    uv = to_rotating_frame(xy, th)
    np.testing.assert_allclose(stepped[4:, 24:32], uv[:-4], atol=1e-15)
    np.testing.assert_array_equal(stepped[:4, 24:32], 0.0)


def test_frontend_feeds_filterbank_streaming(rng: np.random.Generator) -> None:
    fe = ChannelFrontEnd(32)
    bank = AnalysisFilterbank("haar", 6, fe.n_channels)
    recs = [r for i in range(64) for r in bank.step(fe.step(rng.standard_normal(8), 0.1 * i))]
    assert {r.values.shape for r in recs} == {(32,)}


def test_delay_line() -> None:
    d = QuarterPeriodDelay(3, 1)
    out = [d.step(np.array([float(i)]))[0] for i in range(1, 8)]
    assert out == [0.0, 0.0, 0.0, 1.0, 2.0, 3.0, 4.0]
    d.reset()
    np.testing.assert_array_equal(d.process_block(np.arange(1.0, 3.0)[:, None])[:, 0], [0, 0])
    np.testing.assert_array_equal(d.process_block(np.arange(3.0, 6.0)[:, None])[:, 0], [0, 1, 2])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"frames": ("fixed", "body")}, "frames"),
        ({"quadrature": ()}, "quadrature"),
        ({"n_sensor_channels": 7}, "even number"),
        ({"samples_per_rev": 2}, ">= 4"),
        ({"samples_per_rev": 24}, "power of two"),
    ],
)
def test_bad_configuration(kwargs: dict, match: str) -> None:
    args = {"samples_per_rev": 32} | kwargs
    with pytest.raises(ValueError, match=match):
        ChannelFrontEnd(**args)
