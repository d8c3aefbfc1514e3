"""Realtime overload: the chain is stopped for several periods, then catches up within 2 periods.

The realtime plant (the rig: its samples leave on the wall clock, it never waits) with the real
filterbank and controller over DDS, as separate processes. Once commands arrive, both consumers
are stopped (SIGSTOP) for about 11 control periods, as a CPU hog or a stalled process would
stop them, and let go again. The samples of the stop then reach them, all too old for any
command to be in time: some queued, most resent by the reliable writer over the next wakes.
With ``max_backlog`` (amb_tools.backlog) each drops those more than ``max_backlog`` messages
behind, queued or by age, and catches up: every period that starts ``CATCH_UP`` = 2 to
``CATCH_UP + WINDOW`` periods after the release (issue 17) must run with a command. After that
the chain is judged as on any shared machine: a later stall of a consumer longer than its slack
(one period at delay 2) costs a command whatever the chain does, and the chain must catch up
from it too, so at most ``LATER_LOST`` of the later periods may be lost (one that stayed behind
loses nearly all). Processed in order instead, the
backlog of the stop takes several periods to work through and the commands stay late meanwhile.
Dropped by queue length alone (before the age rule), the period 3 after the release had no
command in one idle run of 2026-12-02, and periods 4-11 after it in one run with a core kept
busy (2026-12-03): the resent samples came in batches below the bound and were worked through
in order.

The stop's samples that did not fit the readers' shared-memory ports (512 messages) are lost in
the transport and resent when the readers answer the plant's heartbeat; every later sample
waits for them. With Fast DDS's 3 s default the filterbank caught up 47-337 ms after the
release (a CI run of 2026-12-05: periods 3 and 4 after it without their command); the nodes
run with a 20 ms heartbeat (``amb_tools.transport_profile``; ``docs/history.md``, "Repairs
after a stall").

Reference: the plant's own ``STATUS_COMMAND_MISSING`` flag on every sample (set on every sample
of a period that starts without its command) and the consumers' ``backlog_dropped`` counts on
``/diagnostics``. A period is judged by any of its samples the test's observer received (with
one core busy the observer itself lost samples once, 2026-12-02: a reliable reader gets only
what the writer still keeps).
Times are the plant's: each period starts at its first sample's stamp (the realtime plant's
clock, wall seconds from its start), and the release is put on that clock by the smallest
arrival-minus-stamp of the observed samples (a test process held by a loaded machine receives
samples late, never early).
"""

from __future__ import annotations

import os
import signal
import time

import numpy as np
import pytest
import yaml
from amb_msgs.msg import Measurement
from reliability_helpers import Diagnostics

from amb_tools.conversions import stamp_seconds
from amb_tools.streams import stream_qos

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 64
HZ = 11.0
PERIOD = 1.0 / HZ  # s, one revolution = one control period
STOP = 1.0  # s the consumers are stopped: 11 periods
BACKLOG = 2 * SPR  # samples kept behind the newest after an overload
CATCH_UP = 2  # periods after the release from which every period has its command ...
WINDOW = 10  # ... for this many periods (the in-order backlog lost periods 4-11 after it)
LATER_LOST = 0.25  # the largest share of the periods after the window that may be lost


def test_the_chain_catches_up_within_two_periods_after_an_overload(
    ros, node_process, tmp_path
) -> None:
    scenario = tmp_path / "overload.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "name": "overload",
                "speed": {"hz": HZ},
                "duration": 6.0,
                "samples_per_rev": SPR,
                "measurement_noise": 1.0e-7,
                "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3}],
            }
        )
    )
    node = ros.node("amb_test_overload_observer")
    diagnostics = Diagnostics(node)
    samples: list[tuple[int, int, float, float]] = []  # (index, status, stamp s, arrival s)
    qos = stream_qos(SPR)
    qos.depth = 1 << 16  # the observer keeps every sample even if the test process lags
    node.create_subscription(
        Measurement,
        "/amb/measurement",
        lambda m: samples.append(
            (m.sample_index, m.status, stamp_seconds(m.header.stamp), time.monotonic())
        ),
        qos,
    )
    common = {"samples_per_rev": SPR, "max_backlog": BACKLOG}
    filterbank = node_process("wavelet_filterbank", params=common)
    controller = node_process(
        "wavelet_controller", params={**common, "controller": "transient"}
    )  # OFF: a zero-force command for every period, in time or not
    plant = node_process(
        "plant_sim",
        params={"scenario_file": str(scenario), "samples_per_rev": SPR, "mode": "realtime",
                "wait_for_subscribers": 3, "startup_timeout": 60.0},
    )  # fmt: skip
    received = lambda: len(samples)  # noqa: E731
    logs = lambda: "\n".join(p.log()[-3000:] for p in (plant, filterbank, controller))  # noqa: E731

    def controlled_since(first: int) -> bool:
        flags = [s for i, s, _, _ in samples[first:] if i % SPR == 0]
        return bool(flags) and not flags[-1] & Measurement.STATUS_COMMAND_MISSING

    # commands arrive in time before the stop (the first periods cannot have one)
    assert ros.spin_until_progress(lambda: controlled_since(4 * SPR), received, 60.0), logs()
    stopped = [p.proc.pid for p in (filterbank, controller)]
    for pid in stopped:
        os.kill(pid, signal.SIGSTOP)
    try:
        ros.spin_for(STOP)
    finally:
        for pid in stopped:
            os.kill(pid, signal.SIGCONT)
    released = time.monotonic()
    assert ros.spin_until_progress(lambda: plant.returncode is not None, received, 60.0), logs()
    assert plant.returncode == 0, logs()
    ros.spin_for(0.5)  # the last diagnostics

    index, status, stamp, arrival = (np.array(c) for c in zip(*samples, strict=True))
    assert np.all(np.diff(index) > 0), "the observer received samples out of order"
    # a period is judged by any of its samples the observer received: the plant flags every
    # sample of a period that started without its command, and stamps sample n at n / fs
    # from its start; so a test process held by a loaded machine, whose reliable reader loses
    # samples the plant's writer no longer keeps, still judges every period it saw a sample of
    periods, first = np.unique(index // SPR, return_index=True)
    assert np.array_equal(periods, np.arange(periods[0], periods[-1] + 1)), (
        "the observer received no sample of periods "
        f"{sorted(set(range(periods[0], periods[-1] + 1)) - set(periods.tolist()))}"
    )
    missing = status[first] & Measurement.STATUS_COMMAND_MISSING != 0
    period_start = stamp[first] - (index[first] % SPR) * PERIOD / SPR  # s, the plant's clock
    released -= np.min(arrival - stamp)  # on the plant's clock (late by the transport, < 1 ms)
    during = (period_start > released - STOP + PERIOD) & (period_start < released)
    assert missing[during].all(), "the stop cost the commands of its periods"
    after = period_start >= released + CATCH_UP * PERIOD
    assert after.sum() >= 20, "enough periods after the release to judge"
    release_period = int(np.searchsorted(period_start, released)) - 1
    window = after & (period_start < released + (CATCH_UP + WINDOW) * PERIOD)
    late = np.flatnonzero(window & missing)
    assert late.size == 0, (
        f"periods without a command {CATCH_UP} to {CATCH_UP + WINDOW} periods after the "
        f"release: {late.tolist()} (release in period {release_period})\n{logs()}"
    )
    # later, the chain keeps up: a period lost there is a new overload (a CI run of 2026-12-04:
    # periods 28-29, 13 after a release in period 15, the controller's coefficient reader then
    # 117 messages behind and dropping 55 older than max_backlog; period 30 controlled again)
    later = np.flatnonzero(after & ~window)
    lost = later[missing[later]]
    assert lost.size <= LATER_LOST * later.size, (
        f"periods without a command after the first {CATCH_UP + WINDOW} following the release: "
        f"{lost.tolist()} of {later.size} (release in period {release_period})\n{logs()}"
    )
    # the stop queued ~STOP * fs samples, too old to keep: the filterbank dropped some, counted
    # and logged. How many depends on how the resent ones arrive (idle, 2026-12-04: 344 of 704
    # dropped; one core busy, 2026-12-05: 204, with every period from 2 after the release
    # controlled all the same): the periods above are the claim, this only that it dropped
    assert diagnostics.number("wavelet_filterbank", "backlog_dropped") > 0, logs()
    assert diagnostics.number("wavelet_filterbank", "backlog_overloads") >= 1, logs()
    assert "dropped to catch up" in filterbank.log(), logs()
    # the controller drops from its DDS queues or, while the coefficients trail, its own
    dropped = diagnostics.number("wavelet_controller", "backlog_dropped")
    assert dropped + diagnostics.number("wavelet_controller", "pending_dropped") > 0, logs()
