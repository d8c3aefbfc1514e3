"""The contact rise test of an episode's ring-down (amb_fault_monitor.bursts).

Inputs are built by hand: a ring-down at a steady finest-level ratio with small coefficient
changes, then one coefficient; what the rule must answer follows from its statement
(MonitorConfig: ``confirm_ratio`` 3, ``weak_burst_ratio`` 1.5, ``tail_rise`` 1.7 over the
preceding revolution's largest ratio, ``tail_rise_median`` 3 over the medians).
"""

from __future__ import annotations

import numpy as np
import pytest

from amb_fault_monitor.bursts import ContactBursts
from amb_fault_monitor.config import MonitorConfig

SPR = 32
CFG = MonitorConfig(SPR)
RING = 0.3  # the ring-down's finest-level ratio, a tenth of confirm_ratio
WIGGLE = 1e-8  # m, the ring-down's coefficient change from one coefficient to the next


def _ring(bursts: ContactBursts, revs: float, frame: str) -> int:
    """Feed ``revs`` revolutions of a steady ring-down (a finest-level coefficient every
    2 samples); return the next sample index."""
    n = 0
    for k in range(int(revs * SPR) // 2):
        n = 2 * k
        ratio = np.full(4, RING * (1.0 + 0.1 * (k % 3)))
        fine = None
        if frame == "fixed":
            fine = np.zeros(8)
            fine[0] = 1e-7 + WIGGLE * (k % 2)
        assert not bursts.rises(n, ratio, fine, CFG)
    return n + 2


def _coefficient(r: float, jump: float) -> tuple[np.ndarray, np.ndarray]:
    ratio = np.array([r, RING, RING, RING])
    fine = np.zeros(8)
    fine[0] = 1e-7 + jump
    return ratio, fine


@pytest.mark.parametrize(
    ("r", "jump", "frame", "expected", "why"),
    [
        (2.0, 50 * WIGGLE, "fixed", True, "weak, but a spike above every envelope"),
        (2.0, 50 * WIGGLE, "rotating", False, "weak, and no median or change to agree"),
        (2.0, 0.0, "fixed", False, "weak, and the coefficient did not jump"),
        (1.2, 50 * WIGGLE, "fixed", False, "below weak_burst_ratio"),
        (3.5, 0.0, "fixed", True, "strong: its ratio over the envelopes suffices"),
        (3.5, 0.0, "rotating", True, "strong, above the ring-down's envelope"),
    ],
)
def test_a_burst_needs_a_strong_ratio_or_every_envelope(r, jump, frame, expected, why):
    bursts = ContactBursts(start=0)
    n = _ring(bursts, 1.5, frame)
    ratio, fine = _coefficient(r, jump)
    assert bursts.rises(n, ratio, fine if frame == "fixed" else None, CFG) is expected, why


def test_no_burst_in_the_episodes_first_quarter_revolution():
    """Before a quarter revolution into the episode no envelope exists: nothing rises."""
    bursts = ContactBursts(start=0)
    ratio, fine = _coefficient(10.0, 50 * WIGGLE)
    assert not bursts.rises(2, ratio, fine, CFG)
