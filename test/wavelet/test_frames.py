"""Rotating frame (eq. 2.26, 5.1-5.2) and the circular-orbit property of eq. 5.4."""

from __future__ import annotations

import numpy as np
import pytest

from amb_wavelet.analysis import analyze_block
from amb_wavelet.frames import to_fixed_frame, to_rotating_frame


def test_matches_complex_form_of_eq_5_2(rng: np.random.Generator) -> None:
    xy = rng.standard_normal((50, 8))
    theta = rng.uniform(-10, 10, 50)
    uv = to_rotating_frame(xy, theta)
    z = (xy[:, 0::2] + 1j * xy[:, 1::2]) * np.exp(-1j * theta)[:, None]
    np.testing.assert_allclose(uv[:, 0::2], z.real, rtol=0, atol=1e-14)
    np.testing.assert_allclose(uv[:, 1::2], z.imag, rtol=0, atol=1e-14)


def test_unbalance_force_is_constant_in_rotating_frame() -> None:
    """Eq. 5.1 -> 5.2: f_x + i f_y = m e Omega^2 exp(i Omega t) gives constant (f_u, f_v)."""
    me, omega = 516e-5 * 1e-2, 2 * np.pi * 19.0  # 516 g cm (section 5.3) in kg m, 19 Hz
    t = np.linspace(0, 0.5, 101)
    f = me * omega**2 * np.exp(1j * omega * t)
    fuv = to_rotating_frame(np.stack([f.real, f.imag], axis=1), omega * t)
    np.testing.assert_allclose(fuv[:, 0], me * omega**2, rtol=1e-12)
    np.testing.assert_allclose(fuv[:, 1], 0.0, atol=1e-12 * me * omega**2)


def test_round_trip_and_single_sample(rng: np.random.Generator) -> None:
    xy = rng.standard_normal(8)
    uv = to_rotating_frame(xy, 0.3)
    # two rotations of values up to ~3: a few ulps of the largest (8.9e-16 seen on 2000 draws)
    np.testing.assert_allclose(to_fixed_frame(uv, 0.3), xy, rtol=0, atol=1e-14 * np.abs(xy).max())
    np.testing.assert_allclose(to_rotating_frame(xy, 0.0), xy, rtol=0, atol=0)
    # quarter turn: u = y, v = -x
    np.testing.assert_allclose(to_rotating_frame([1.0, 2.0], np.pi / 2), [2.0, -1.0], atol=1e-15)


@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_circular_orbit_gives_zero_rotating_details(wavelet: str) -> None:
    """Steady forward circular orbit: u, v constant, so every settled detail is ~0 (eq. 5.4)."""
    spr, level = 32, 6
    n = np.arange(40 * spr)
    theta = 2 * np.pi * n / spr + 0.4
    radius = 25e-6  # m
    phase = np.array([0.3, 1.1, -2.0, 2.9])
    orbit = np.empty((n.size, 8))
    orbit[:, 0::2] = radius * np.cos(theta[:, None] + phase)
    orbit[:, 1::2] = radius * np.sin(theta[:, None] + phase)
    fixed = analyze_block(orbit, wavelet, level)
    rotating = analyze_block(to_rotating_frame(orbit, theta), wavelet, level)
    L = 2 * int(wavelet[2:]) if wavelet != "haar" else 2
    for j in range(1, level + 1):
        skip = -(-((2**j - 1) * (L - 1)) // 2**j) + 1  # start-up coefficients
        d_rot = rotating.details[j - 1][skip:]
        # rounding of angles up to 250 rad (ulp 3e-14) scaled by 2^(j/2): ~5e-13 radius at most
        assert np.max(np.abs(d_rot)) < 1e-10 * radius
    # the same orbit is clearly visible at 1 x running speed in the fixed frame
    assert np.max(np.abs(fixed.details[4][4:])) > 0.5 * radius


def test_bad_shapes() -> None:
    with pytest.raises(ValueError, match="even length"):
        to_rotating_frame(np.zeros(3), 0.0)
    with pytest.raises(ValueError, match="one rotor angle per sample"):
        to_rotating_frame(np.zeros((4, 8)), np.zeros(5))
