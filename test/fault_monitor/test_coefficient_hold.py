"""The node's hold of coefficient messages whose measurements are not in yet (ROS-free)."""

from types import SimpleNamespace

from amb_fault_monitor.coefficient_hold import CoefficientHold


def _item(n: int) -> tuple:
    return (SimpleNamespace(sample_index=n), b"", False)


def test_held_in_order_released_when_measured_and_bounded_by_count_and_time():
    hold = CoefficientHold(capacity=3, timeout=1.0)
    assert hold.wants(5, last_sample=3) and not hold.wants(3, last_sample=3)
    assert hold.hold(_item(5), now=0.0) == [] and hold.hold(_item(7), now=0.0) == []
    assert hold.wants(4, last_sample=9)  # behind a held message: kept in order
    # released up to the last measured sample, the rest kept
    assert [i[0].sample_index for i in hold.release(5, now=0.5)] == [5]
    # over capacity: the oldest given back unmatched
    for n in (9, 11, 13):
        over = hold.hold(_item(n), now=0.6)
    assert [i[0].sample_index for i in over] == [7] and hold.unmatched == 1
    # no measurement for longer than the timeout since the last one (at 0.5): all given back
    assert hold.expired(now=1.4) == []
    assert [i[0].sample_index for i in hold.expired(now=1.6)] == [9, 11, 13]
    assert hold.unmatched == 4 and not hold
