"""Period-sampled coefficients x_{p,q}(kT) and averages x^0(kT) (eq. 6.1-6.4)."""

from __future__ import annotations

import numpy as np
import pytest
import pywt

from amb_wavelet.errors import LevelError
from amb_wavelet.levels import (
    harmonic_of_level,
    level_from_thesis_p,
    pseudo_frequency,
    revolution_level,
    synthesis_delay,
    thesis_p,
)
from amb_wavelet.period import PeriodSampler, period_coefficients, period_position


def test_level_map_of_chapters_5_to_8() -> None:
    spr = 32  # thesis section 5.2: 0.46 ms sampling at 67 Hz, synchronous at the 5th octave
    assert revolution_level(spr) == 5
    # section 5.3: five levels at 8, 4, 2, 1, 0.5 x running speed
    assert [harmonic_of_level(j, spr) for j in (2, 3, 4, 5, 6)] == [8, 4, 2, 1, 0.5]
    # chapters 7-8: x_{1,1} at 1 x, x_{2,1} at 2 x, x_{3,1} at 4 x
    assert [thesis_p(j, spr) for j in (5, 4, 3)] == [1, 2, 3]
    assert [level_from_thesis_p(p, spr) for p in (1, 2, 3)] == [5, 4, 3]
    fs = spr * 67.0
    assert pseudo_frequency(5, fs) == pytest.approx(67.0)
    # "0.46 ms" printed to two digits for a rounded 67 Hz
    assert 1 / (spr * 67.0) == pytest.approx(0.46e-3, rel=0.02)
    assert synthesis_delay(5, 2) == 31


@pytest.mark.parametrize("bad", [0, 6])
def test_p_out_of_range(bad: int) -> None:
    with pytest.raises(LevelError, match="p"):
        level_from_thesis_p(bad, 32)
    with pytest.raises(LevelError, match="period average"):
        period_position(6, 0, 32)


def test_haar_expansion_of_eq_6_2_is_exact(rng: np.random.Generator) -> None:
    """x[n] = x0 + sum_{p,q} x_{p,q} psi_{p,q}[n] inside every period (closed-form Haar)."""
    spr = 16
    R = 4
    x = rng.standard_normal((5 * spr + 7, 2))
    pc = period_coefficients(x, "haar", spr)
    assert pc.average.shape == (5, 2) and pc.period_index.tolist() == [0, 1, 2, 3, 4]
    assert pc.settled.all()
    for k in range(5):
        rebuilt = np.tile(pc.average[k], (spr, 1))
        for p in range(1, R + 1):
            width = spr // 2 ** (p - 1)  # 2**j samples, j = R - p + 1
            for q in range(1, 2 ** (p - 1) + 1):
                psi = np.zeros(spr)  # eq. 4.3 dilated, unit energy (eq. 4.4 scaling)
                psi[(q - 1) * width : (q - 1) * width + width // 2] = 1.0
                psi[(q - 1) * width + width // 2 : q * width] = -1.0
                rebuilt += np.outer(psi / np.sqrt(width), pc.coefficients[p][k, q - 1])
        np.testing.assert_allclose(rebuilt, x[k * spr : (k + 1) * spr], rtol=0, atol=1e-13)
        np.testing.assert_allclose(pc.average[k], x[k * spr : (k + 1) * spr].mean(axis=0))


def test_haar_equals_pywt_per_period(rng: np.random.Generator) -> None:
    spr, R = 32, 5
    x = rng.standard_normal(4 * spr)
    pc = period_coefficients(x, "haar", spr)
    for k in range(4):
        ref = pywt.wavedec(x[k * spr : (k + 1) * spr], "haar", mode="periodization", level=R)
        for p in range(1, R + 1):
            np.testing.assert_allclose(pc.coefficients[p][k], ref[p], rtol=0, atol=1e-13)
        assert pc.average[k] == pytest.approx(ref[0][0] / 2 ** (R / 2), abs=1e-13)


@pytest.mark.parametrize("wavelet", ["db4", "coif2"])
def test_general_wavelet_mapping_and_streaming(
    rng: np.random.Generator, wavedec_zero, wavelet: str
) -> None:
    spr, R = 16, 4
    x = rng.standard_normal((12 * spr, 3))
    pc = period_coefficients(x, wavelet, spr, p_max=3)
    assert set(pc.coefficients) == {1, 2, 3}
    ref = wavedec_zero(x, wavelet, R)
    for p in (1, 2, 3):
        j = R - p + 1
        for k in range(12):
            for q in range(1, 2 ** (p - 1) + 1):
                m = k * 2 ** (p - 1) + q - 1
                assert period_position(j, m, spr) == (k, p, q)
                np.testing.assert_allclose(
                    pc.coefficients[p][k, q - 1], ref[R - j + 1][m], atol=1e-13
                )
    sampler = PeriodSampler(wavelet, spr, 3, p_max=3)
    outs = [o for i, row in enumerate(x) if (o := sampler.step(row, sample_index=i)) is not None]
    assert [int(o.period_index[0]) for o in outs] == list(range(12))
    for k, o in enumerate(outs):
        np.testing.assert_allclose(
            o.average[0], x[k * spr : (k + 1) * spr].mean(axis=0), atol=1e-14 * np.abs(x).max()
        )
        assert bool(o.settled[0]) == bool(pc.settled[k])
        for p in (1, 2, 3):
            np.testing.assert_allclose(o.coefficients[p][0], pc.coefficients[p][k], atol=1e-13)
    # level-4 supports (db4: 106 samples) reach back: early periods carry start-up zeros
    assert not pc.settled[0] and pc.settled[-1]


def test_sampler_reset_mid_period_flags_partial_period(rng: np.random.Generator) -> None:
    sampler = PeriodSampler("haar", 8, 1, start_sample_index=5)
    outs = [sampler.step([1.0], sample_index=i) for i in range(5, 24)]
    done = [o for o in outs if o is not None]
    assert [int(o.period_index[0]) for o in done] == [0, 1, 2]
    assert [bool(o.settled[0]) for o in done] == [False, True, True]
    assert done[1].average[0, 0] == pytest.approx(1.0)


def test_level_validation_and_timing_helpers() -> None:
    from amb_wavelet.levels import (
        check_level,
        completion_sample_index,
        support_first_sample_index,
        support_length,
    )

    assert check_level(6, samples_per_rev=32, extra_octaves=1) == 6
    with pytest.raises(LevelError, match=r"level <= log2\(samples_per_rev\) \+ extra_octaves"):
        check_level(7, samples_per_rev=32, extra_octaves=1)
    with pytest.raises(LevelError, match="power of two"):
        check_level(3, samples_per_rev=48)
    # db2 (L = 4), level 3: support 7 * 3 + 1 = 22 samples ending at 8 (m + 1) - 1
    assert support_length(3, 4) == 22
    assert completion_sample_index(3, 5) == 47
    assert support_first_sample_index(3, 5, 4) == 26
