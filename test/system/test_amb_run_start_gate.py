"""amb-run starts the plant only once each publisher has matched its readers.

A fresh-clone run under a CPU hog recorded none of the filterbank's 304 coefficient messages:
the recorder discovered the filterbank's process 3 s after amb-run's own participant had
seen every subscription, and by then the 2 s scenario was over. The count that says a message
will reach a reader is the writer's own (``amb_tools.streams.matched_subscribers``); each
stream publisher reports it on /diagnostics and amb-run waits for it. Here the gate runs on its
own, with a real filterbank process and real subscriptions.
"""

from __future__ import annotations

import pytest
from amb_msgs.msg import WaveletCoefficients

from amb_apps.run_cli import _Progress
from amb_common import topics
from amb_tools.streams import stream_qos

pytestmark = pytest.mark.ros

EXPECTED = {topics.COEFFICIENTS: 2}
STARTED = {"wavelet_filterbank"}


@pytest.fixture
def progress(ros_domain_id):
    p = _Progress()
    yield p
    p.close()


def test_plant_waits_for_the_filterbanks_own_matches(ros, node_process, progress) -> None:
    node = ros.node("readers")
    for _ in range(EXPECTED[topics.COEFFICIENTS]):
        node.create_subscription(
            WaveletCoefficients, topics.COEFFICIENTS, lambda m: None, stream_qos(32)
        )
    # no publisher has reported: the graph may be complete, the gate stays shut
    assert not progress.wait_for_graph(EXPECTED, STARTED, timeout=1.0)
    assert progress.matched(EXPECTED, STARTED) == {topics.COEFFICIENTS: None}
    filterbank = node_process(
        "wavelet_filterbank", params={"samples_per_rev": 32, "status_period": 0.2}
    )
    opened = progress.wait_for_graph(EXPECTED, STARTED, timeout=60.0)
    assert opened, f"matched {progress.matched(EXPECTED, STARTED)}; log:\n{filterbank.log()}"
    assert progress.matched(EXPECTED, STARTED)[topics.COEFFICIENTS] == 2
    # the plant, started after the gate, is not asked for a report
    assert progress.matched({topics.MEASUREMENT: 1}, STARTED) == {}


def test_without_a_reader_the_gate_stays_shut(node_process, progress) -> None:
    filterbank = node_process(
        "wavelet_filterbank", params={"samples_per_rev": 32, "status_period": 0.2}
    )
    reported = progress.wait_for_graph({topics.COEFFICIENTS: 0}, STARTED, timeout=60.0)
    assert reported, f"no report from the filterbank; log:\n{filterbank.log()}"
    assert progress.matched(EXPECTED, STARTED) == {topics.COEFFICIENTS: 0}
    assert not progress.wait_for_graph({topics.COEFFICIENTS: 1}, STARTED, timeout=1.0)
