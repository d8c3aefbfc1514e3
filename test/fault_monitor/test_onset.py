"""Onset back-dating: first crossing's support, narrowed by overlapping crossings."""

import pytest

from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.monitor import Crossing, estimate_onset


def test_single_crossing_is_backdated_to_its_support_start():
    assert estimate_onset([Crossing(3, "fixed", 1, 96, 103, 2.0)]) == 96


def test_overlapping_finer_crossing_narrows_the_onset():
    coarse = Crossing(3, "fixed", 1, 96, 103, 2.0)  # 8-sample support
    fine = Crossing(1, "rotating", 2, 100, 101, 5.0)  # 2-sample support inside it
    assert estimate_onset([coarse, fine]) == 100


def test_later_disjoint_crossing_is_ignored():
    first = Crossing(1, "fixed", 1, 100, 101, 2.0)
    later = Crossing(1, "fixed", 1, 120, 121, 9.0)  # response, not the onset
    assert estimate_onset([later, first]) == 100


def test_empty_raises():
    with pytest.raises(FaultMonitorError, match="at least one crossing"):
        estimate_onset([])
