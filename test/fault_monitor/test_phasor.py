"""The synchronous level's decision (amb_fault_monitor.phasor): a new level is a coherent change.

Synthetic 1 x phasors with a known change after an onset: a step to a new level (the phasor
change is the same complex number every revolution) is "settled"; a change of the same size
whose phase jumps from one revolution to the next (a ringing mode, not a new level) is not.
"""

from types import SimpleNamespace

import numpy as np
import pytest

from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.phasor import SynchronousLevel

SPR = 32
LEVEL = 5  # the 1 x level at 32 samples per revolution
ONSET = 10 * SPR
MASK = np.ones(8, dtype=bool)


def _level(changes: list[complex]) -> tuple[SynchronousLevel, np.ndarray]:
    """A level with a threshold of 1 um per plane, 4 revolutions before the onset at a 20 um
    x1 phasor, then ``changes`` (m) of x1 after it, one per revolution."""
    sync = SynchronousLevel(MonitorConfig(SPR), LEVEL)
    sync.threshold = np.full(4, 1e-6)
    scale = 2.0 ** (LEVEL / 2)  # the coefficient of a phasor p: p * scale (normalise)
    ref = np.zeros(8, dtype=complex)
    ref[0] = 20e-6
    phasors = [ref] * 4 + [ref + np.eye(8)[0] * c for c in changes]
    first = ONSET - 4 * SPR
    for k, p in enumerate(phasors):
        span = dict(first_sample_index=first + k * SPR, last_sample_index=first + (k + 1) * SPR - 1)
        even = SimpleNamespace(values=p.real * scale, **span)
        odd = SimpleNamespace(values=p.imag * scale, **span)
        sync.add(even, odd, MASK, calibrating=False)
    return sync, sync.reference(ONSET)


def test_a_step_to_a_new_level_is_settled():
    # 3 thresholds of change (3 um, sync_change 1.5), the same every revolution
    sync, ref = _level([3e-6 * np.exp(0.7j)] * 10)
    status, ratio, change = sync.series(ref, ONSET, MASK)
    assert status == "settled"
    assert ratio[0] == pytest.approx(3.0, rel=1e-9) and change[0] == pytest.approx(3e-6)
    assert sync.series(ref, ONSET, MASK, final=True)[0] == "settled"


@pytest.mark.parametrize("final", [False, True])
def test_a_change_whose_phase_jumps_is_not_a_new_level(final):
    # the same 3 um every revolution, its phase jumping by the golden angle (137.5 deg): the
    # magnitude test alone calls it settled (no spread, sustained); its mean over the latest 4
    # revolutions is 0.57 um, under the 1.5 um of sync_change
    jumps = [3e-6 * np.exp(1j * np.radians(137.5) * k) for k in range(10)]
    mean = abs(np.mean(jumps[-4:]))
    assert mean < 1.5e-6 < 3e-6
    sync, ref = _level(jumps)
    status = sync.series(ref, ONSET, MASK, final=final)[0]
    assert status == ("returned" if final else None)


def test_a_decayed_change_has_returned():
    sync, ref = _level([3e-6 * 0.5**k for k in range(10)])
    assert sync.series(ref, ONSET, MASK)[0] == "returned"
