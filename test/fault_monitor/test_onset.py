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


def _episode_of(crossings: list[Crossing]):
    """An episode that was given ``crossings`` one coefficient set at a time, in this order."""
    from types import SimpleNamespace

    from amb_fault_monitor.episodes import Episode

    config = SimpleNamespace(
        samples_per_rev=32, burst_gap_revs=1.0, confirm_ratio=1e9, confirm_features=99
    )
    ep = Episode(start=crossings[0].last)
    for c in crossings:
        ratio = np.zeros(4)
        ratio[c.plane - 1] = c.ratio
        s = SimpleNamespace(first_sample_index=c.first, last_sample_index=c.last)
        ep.add_crossings(
            c.last, c.level, c.frame, s, ratio, np.zeros(8), np.ones(4), c.centre,
            revolution_level=5, mask=np.ones(8, bool), config=config, finest=1,
        )  # fmt: skip
    return ep


def test_an_episode_keeps_the_onset_of_its_crossings_as_they_come():
    # the cases above, given to an episode in the same order
    fine = Crossing(1, "fixed", 2, 102, 103, 1.1, 102.5)
    coarse = Crossing(3, "fixed", 2, 96, 103, 3.9, 99.5)
    assert _episode_of([fine, coarse]).onset() == 99
    first = Crossing(1, "fixed", 1, 100, 101, 2.0, 100.5)
    later = Crossing(1, "fixed", 1, 120, 121, 9.0, 120.5)
    overlapping = Crossing(2, "fixed", 1, 98, 105, 9.0, 101.5)
    assert _episode_of([later, overlapping, first]).onset() == 100
    # equal ratios at the earliest completion: the first given decides, as max() does
    a = Crossing(2, "fixed", 1, 96, 103, 2.0, 99.5)
    b = Crossing(3, "fixed", 3, 88, 103, 2.0, 95.5)
    assert _episode_of([a, b]).onset() == 99
    assert _episode_of([b, a]).onset() == 95


def test_the_kept_onset_follows_the_rule_over_long_random_episodes():
    # hundreds of crossings, completions out of order and repeated: the rule of estimate_onset
    # (the strongest of the earliest completed, its atom centre, the earlier sample at .5),
    # written out here
    rng = np.random.default_rng(7)
    for _ in range(20):
        crossings = []
        for _ in range(int(rng.integers(1, 400))):
            last = int(rng.integers(100, 140))
            size = int(2 ** rng.integers(1, 5))
            ratio = float(rng.choice([1.5, 2.0, 3.0, rng.uniform(1.0, 9.0)]))
            crossings.append(
                Crossing(int(rng.integers(1, 5)), "fixed", int(rng.integers(1, 5)),
                         last - size + 1, last, ratio, last - size / 2 + 0.5)
            )  # fmt: skip
        earliest = min(c.last for c in crossings)
        best = None
        for c in crossings:
            if c.last == earliest and (best is None or c.ratio > best.ratio):
                best = c
        expected = int(np.ceil(best.centre - 0.5))
        ep = _episode_of(crossings)
        assert ep.onset() == expected == estimate_onset(crossings)


def test_an_episode_without_crossings_has_no_onset():
    from amb_fault_monitor.episodes import Episode

    with pytest.raises(FaultMonitorError, match="no onset"):
        Episode(start=0).onset()
