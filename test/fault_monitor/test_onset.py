"""Onset back-dating: the strongest first crossing, at the time centre of its atom."""

import numpy as np
import pytest

from amb_fault_monitor.config import MonitorConfig
from amb_fault_monitor.errors import FaultMonitorError
from amb_fault_monitor.monitor import FaultMonitor
from amb_fault_monitor.onset import Crossing, estimate_onset
from amb_fault_monitor.records import CoefficientSet, SampleCoefficients


def test_single_crossing_is_backdated_to_its_atom_centre():
    # centre 99.5 (haar level 3: the middle of 96..103): the earlier sample
    assert estimate_onset([Crossing(3, "fixed", 1, 96, 103, 2.0, 99.5)]) == 99
    assert estimate_onset([Crossing(3, "fixed", 1, 96, 103, 2.0, 99.6)]) == 100


def test_without_a_centre_the_support_start_is_the_onset():
    assert estimate_onset([Crossing(3, "fixed", 1, 96, 103, 2.0)]) == 96


def test_the_strongest_of_the_first_completed_crossings_decides():
    # a growing response makes the fine level cross first but weakly; the coarse coefficient
    # completed by the same sample, whose support holds the onset, is the strongest
    fine = Crossing(1, "fixed", 2, 102, 103, 1.1, 102.5)
    coarse = Crossing(3, "fixed", 2, 96, 103, 3.9, 99.5)
    assert estimate_onset([fine, coarse]) == 99


def test_later_crossings_do_not_move_the_onset():
    first = Crossing(1, "fixed", 1, 100, 101, 2.0, 100.5)
    later = Crossing(1, "fixed", 1, 120, 121, 9.0, 120.5)  # response, not the onset
    overlapping = Crossing(2, "fixed", 1, 98, 105, 9.0, 101.5)  # completes later
    assert estimate_onset([later, overlapping, first]) == 100


def test_empty_raises():
    with pytest.raises(FaultMonitorError, match="at least one crossing"):
        estimate_onset([])


@pytest.mark.parametrize(("wavelet", "centre"), [("db4", 5.54), ("", 0.0), ("not_a_wavelet", 0.0)])
def test_monitor_takes_the_centre_from_the_stream_wavelet(wavelet, centre):
    # the centre used for a crossing comes from the record's wavelet (db4 level 1: 5.54 of the
    # 8-sample support, amb_wavelet.synthesis.atom_time_centre); unknown -> support start
    mon = FaultMonitor(MonitorConfig(samples_per_rev=32))
    mon.step(SampleCoefficients(7, 100.0, (), wavelet))
    s = CoefficientSet(1, "detail", "fixed", "even", 0, 0, 7, np.zeros(8), True)
    assert mon.atom_centre(s) == pytest.approx(centre, abs=0.01)
