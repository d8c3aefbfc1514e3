"""The harmonic ratio of the probe readings' change (amb_fault_monitor.revolution_change).

References are closed forms: a change made of sinusoids at whole multiples of running speed
has, over one revolution of synchronous samples, exactly those sinusoids' amplitudes as its
DFT bins, so ``h`` is the root of the summed squared harmonic amplitudes over the summed
squared 1 x amplitudes.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from amb_fault_monitor.revolution_change import RevolutionChange

SPR = 32
CONFIG = SimpleNamespace(samples_per_rev=SPR, provisional_revs=1.5)
A = 100e-6  # m, the healthy 1 x vibration
ONSET = 10 * SPR + 7  # a fault inside a revolution
NOW = ONSET + 3 * SPR // 2  # 1.5 revolutions later, as the monitor asks
PHASE = np.arange(8) * 0.7


def _readings(change, n_samples=NOW + 1):
    """Healthy 1 x vibration of the eight probes, plus ``change(theta)`` from ONSET on."""
    n = np.arange(n_samples)
    theta = 2 * np.pi * n[:, None] / SPR + PHASE
    x = A * np.sin(theta)
    after = n >= ONSET
    x[after] += change(theta[after])
    return x


def _ratio(x, onset=ONSET, now=NOW, mask=None, skip=()):
    change = RevolutionChange(CONFIG)
    for n, row in enumerate(x):
        if n not in skip:
            change.add(n, row)
    mask = np.ones(8, dtype=bool) if mask is None else mask
    return change.harmonic_ratio(onset, now, mask)


def test_a_synchronous_change_has_no_harmonics():
    """A mass loss's steady change, a new sinusoid at 1 x switched on inside a revolution: the
    reference readings lie before the onset, so nothing of the switch is left."""
    h = _ratio(_readings(lambda th: 30e-6 * np.cos(th + 1.1)))
    assert h == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(
    ("b1", "harmonics", "expected"),
    [
        (20e-6, {2: 5e-6}, 0.25),
        (20e-6, {3: 8e-6, 5: 6e-6}, 0.5),
        (10e-6, {2: 6e-6, 4: 8e-6}, 1.0),
    ],
)
def test_the_ratio_is_the_harmonics_amplitude_over_the_fundamental(b1, harmonics, expected):
    """Every probe changes by ``b1`` at 1 x and the given amplitudes at k x: ``h`` is
    sqrt(sum of the harmonics' squares) / b1 (the same on every channel)."""

    def change(th):
        out = b1 * np.sin(th)
        for k, b in harmonics.items():
            out = out + b * np.sin(k * th + 0.3 * k)
        return out

    assert _ratio(_readings(change)) == pytest.approx(expected, rel=1e-9)


def test_channels_are_pooled_and_masked_ones_left_out():
    """Channel 0 changes at 1 x only (20 um), channel 3 at 1 x (10 um) and 3 x (10 um), the
    others not at all: h = sqrt(10**2 / (20**2 + 10**2)); without channel 3, 0."""

    def change(th):
        out = np.zeros_like(th)
        out[:, 0] = 20e-6 * np.sin(th[:, 0])
        out[:, 3] = 10e-6 * (np.sin(th[:, 3]) + np.sin(3 * th[:, 3]))
        return out

    x = _readings(change)
    assert _ratio(x) == pytest.approx(np.sqrt(100 / 500), rel=1e-9)
    mask = np.ones(8, dtype=bool)
    mask[3] = False
    assert _ratio(x, mask=mask) == pytest.approx(0.0, abs=1e-9)


def test_readings_it_lacks_give_no_ratio():
    x = _readings(lambda th: 30e-6 * np.sin(th))
    assert _ratio(x, now=ONSET + SPR // 2) is None  # the revolution starts before the onset
    assert _ratio(x, skip={ONSET - 3}) is None  # a gap among the references
    assert _ratio(x, skip={NOW}) is None  # a gap in the revolution examined
    # an onset too long ago: its references have left the kept readings
    long = _readings(lambda th: 30e-6 * np.sin(th), n_samples=NOW + 8 * SPR + 1)
    assert _ratio(long, now=NOW + 8 * SPR) is None
    assert _ratio(x, mask=np.zeros(8, dtype=bool)) is None  # no channel in use


def test_reset_forgets_the_readings_and_a_new_config_resizes():
    x = _readings(lambda th: 30e-6 * np.sin(th))
    change = RevolutionChange(CONFIG)
    for n, row in enumerate(x):
        change.add(n, row)
    mask = np.ones(8, dtype=bool)
    assert change.harmonic_ratio(ONSET, NOW, mask) is not None
    change.reset()
    assert change.harmonic_ratio(ONSET, NOW, mask) is None
    for n, row in enumerate(x):
        change.add(n, row)
    change.config = SimpleNamespace(samples_per_rev=SPR, provisional_revs=6.0)
    assert change.harmonic_ratio(ONSET, NOW, mask) is None  # resized: readings forgotten
