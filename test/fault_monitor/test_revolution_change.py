"""The residual ratio of the probe readings' change (amb_fault_monitor.revolution_change).

References are closed forms over one revolution of ``N`` synchronous samples: a sinusoid at
1 x on an offset and a straight line is fitted exactly (nothing left); ``cos 3 theta - cos 5
theta`` is orthogonal to ``cos theta``, ``sin theta``, ``1`` and the centred ramp (``sum_j j
cos(2 pi k j / N) = -N/2`` for every ``k`` not a multiple of ``N``), so all of it is left and
the ratio is its norm over the 1 x part's.
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
    return change.residual_ratio(onset, now, mask)


WINDOW = NOW - SPR + 1  # the first sample of the revolution examined


def _window_angle(th):
    """The angle counted from the first sample of the revolution examined (from ``theta``)."""
    return th - PHASE - 2 * np.pi * WINDOW / SPR


def test_a_synchronous_change_on_a_drift_leaves_nothing():
    """A mass loss's change: a new sinusoid at 1 x switched on inside a revolution, on an
    offset and a slope (the slow free response); the reference readings lie before the
    onset, so nothing of the switch is left either."""

    def change(th):
        return 30e-6 * np.cos(th + 1.1) + 4e-6 + 2e-6 * _window_angle(th)

    assert _ratio(_readings(change)) == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("b1", "c"), [(20e-6, 2e-6), (20e-6, 10e-6), (5e-6, 10e-6)])
def test_what_is_left_is_the_part_no_sinusoid_or_line_describes(b1, c):
    """``b1 sin(theta) + c (cos 3 theta - cos 5 theta)`` on every probe, theta from the
    revolution's first sample: rho = sqrt(2) c / b1."""

    def change(th):
        a = _window_angle(th)
        return b1 * np.sin(a) + c * (np.cos(3 * a) - np.cos(5 * a))

    assert _ratio(_readings(change)) == pytest.approx(np.sqrt(2) * c / b1, rel=1e-9)


def test_channels_are_pooled_and_masked_ones_left_out():
    """Channel 0 changes at 1 x only (20 um), channel 3 at 1 x (10 um) and by 10 um of
    ``cos 3 theta - cos 5 theta``, the others not at all: rho = sqrt(2 * 10**2 / (20**2 +
    10**2)); without channel 3, 0."""

    def change(th):
        a = _window_angle(th)
        out = np.zeros_like(th)
        out[:, 0] = 20e-6 * np.sin(a[:, 0])
        out[:, 3] = 10e-6 * (np.sin(a[:, 3]) + np.cos(3 * a[:, 3]) - np.cos(5 * a[:, 3]))
        return out

    x = _readings(change)
    assert _ratio(x) == pytest.approx(np.sqrt(200 / 500), rel=1e-9)
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
    assert change.residual_ratio(ONSET, NOW, mask) is not None
    change.reset()
    assert change.residual_ratio(ONSET, NOW, mask) is None
    for n, row in enumerate(x):
        change.add(n, row)
    change.config = SimpleNamespace(samples_per_rev=SPR, provisional_revs=6.0)
    assert change.residual_ratio(ONSET, NOW, mask) is None  # resized: readings forgotten
