"""How an ``amb-run`` ends: the nodes drained to the plant's last sample, then the bag complete.

Draining: a node that is behind the plant when the plant exits still has the end of the run in
its subscription queues (the fault monitor, off the lock-step chain, may be many revolutions
behind on a loaded machine, with a fault decision among them). Before they are stopped, the
filterbank, the controller and the fault monitor are therefore waited for until the sample
indices they report as processed on ``/diagnostics`` (:data:`DRAINED`) reach the plant's last
sample (:func:`drain`).

Recording: a drained node has published everything it will, but the recorder may not have it
yet (a reliable message lost on the way is resent only after the writer's next heartbeat: 3 s
with Fast DDS's defaults, 20 ms with the nodes' profile, :mod:`amb_tools.transport_profile`).
Before the recorder is stopped, the messages it reports as written (its ``/diagnostics``
counts per topic) are therefore waited for until they reach what each publisher reports as
published (:data:`PUBLISHED`; :func:`settle_recording`). A fixed 0.5 s
grace before this lost the controller's last command in a loaded suite run (77 of 78 in the
bag; ``test/system/test_composed.py``).

Both waits are bounded (``--drain-timeout``); a node or recorder still short is named with its
counts and the run's exit status is 1: what it had not processed or written is missing from the
bag.
"""

from __future__ import annotations

import math
import re
import sys
import time
from pathlib import Path
from typing import Protocol

from amb_common import topics

__all__ = [
    "DRAINED",
    "DRAIN_TIMEOUT",
    "PLANT_COMPLETE",
    "PUBLISHED",
    "drain",
    "plant_samples",
    "settle_recording",
]

#: /diagnostics keys (sample indices processed) of the nodes drained before they are stopped.
#: The filterbank publishes coefficients for odd samples only (its finest level completes every
#: second sample), so ``last_coefficient_sample`` ends at the last odd sample.
DRAINED = {
    "wavelet_filterbank": ("last_sample",),
    "wavelet_controller": ("last_sample",),
    "fault_monitor": ("last_sample", "last_coefficient_sample"),
}
#: Default ``--drain-timeout``, wall s: well above the time a fault monitor niced to 19 on a
#: loaded machine takes to catch up (docs/results.md#drain; the first measurement:
#: docs/history.md, "amb-run"), so that only a stuck node reaches it.
DRAIN_TIMEOUT = 300.0
#: The plant's completion line in its log (read when its final /diagnostics report was missed).
PLANT_COMPLETE = re.compile(r"complete at t = [\d.]+ s \((?P<samples>\d+) samples\)")
#: Stream topic -> (its publisher, the /diagnostics key of the messages it has published). The
#: plant's count is its ``sample_index`` at the end (:func:`plant_samples`).
PUBLISHED = {
    topics.MEASUREMENT: ("plant_sim", "sample_index"),
    topics.COEFFICIENTS: ("wavelet_filterbank", "messages_published"),
    topics.COMMAND: ("wavelet_controller", "commands_published"),
    topics.STATUS: ("wavelet_controller", "statuses_published"),
    topics.FAULT_EVENTS: ("fault_monitor", "events_published"),
}


class Reports(Protocol):
    """What the waits read: the run's ``/diagnostics`` (``amb_apps.run_cli._Progress``)."""

    namespace: str

    @property
    def values(self) -> dict[str, str]:
        """The plant's last report (empty before the first)."""

    def report(self, name: str) -> dict[str, str]:
        """Node ``name``'s last report, key -> value (empty before the first)."""

    def processed(self, name: str, key: str) -> int | None:
        """Sample index ``key`` last reported by node ``name`` (None before its first report)."""

    def spin(self, seconds: float) -> None:
        """Take the reports that arrive within ``seconds``."""


class Process(Protocol):
    """One process of the run (``amb_apps.run_processes.NodeRun``): name, nodes, process."""

    name: str
    hosts: tuple[str, ...]
    log_path: Path
    proc: object


def plant_samples(progress: Reports, runs: list[Process]) -> int | None:
    """Samples the plant produced: its final report's ``sample_index``, else its log's line.

    ``/diagnostics`` is volatile: a short run can end before the reader is matched to the
    plant's writer (seen once in ``make demo``); the plant logs the same count when it
    completes. None when neither is there.
    """
    progress.spin(0.2)  # the plant's last report, sent just before it exited
    plant = progress.values
    if plant.get("done") == "True" and plant.get("sample_index", "").isdigit():
        return int(plant["sample_index"])
    plant_run = next(r for r in runs if r.name == "plant_sim")
    found = PLANT_COMPLETE.search(plant_run.log_path.read_text(errors="replace"))
    return None if found is None else int(found.group("samples"))


def drain(
    progress: Reports, runs: list[Process], samples: int | None, timeout: float, quiet: bool
) -> int:
    """Wait until the running nodes of :data:`DRAINED` have processed the plant's last sample.

    Parameters
    ----------
    progress : Reports
        The /diagnostics reader (the nodes' reports of what they processed).
    runs : list of Process
        The run's processes; the nodes still running and named in :data:`DRAINED` are waited
        for.
    samples : int or None
        Samples the plant produced (:func:`plant_samples`); None: unknown.
    timeout : float
        Wall s to wait at most.
    quiet : bool
        No progress lines (a failure to drain is printed either way).

    Returns
    -------
    int
        0 when every node has caught up; 1 if the bound was hit, a node exited meanwhile, or
        the plant's count is unknown (the nodes are then stopped as they are).
    """
    if samples is None:
        print(
            "[amb-run] the plant's final report was not received and its log has no "
            "completion line: cannot tell whether the other nodes processed its last "
            "sample; stopping them as they are",
            file=sys.stderr,
        )
        return 1
    last = samples - 1
    targets = {
        (n, key): last if key == "last_sample" or last % 2 else last - 1
        for r in runs
        for n in r.hosts
        if n in DRAINED
        for key in DRAINED[n]
    }
    procs = {n: r.proc for r in runs for n in r.hosts}
    start = time.monotonic()
    last_print = -math.inf
    first = True
    while True:
        gone = sorted({n for n, _ in targets if procs[n].poll() is not None})
        if gone:
            print(
                f"[amb-run] {', '.join(gone)} exited before processing sample {last}, the "
                "plant's last; see the logs",
                file=sys.stderr,
            )
            return 1
        at = {nk: progress.processed(*nk) for nk in targets}
        behind = {nk: v for nk, v in at.items() if v is None or v < targets[nk]}
        waited = time.monotonic() - start
        shown = ", ".join(
            f"{n} {k} {'-' if v is None else v}" for (n, k), v in (behind or at).items()
        )
        if first and not quiet:
            print(f"[amb-run] plant done at sample {last}; {shown}", flush=True)
            first = False
        if not behind:
            if not quiet:
                print(
                    f"[amb-run] drained in {waited:.1f} s: every node processed the plant's last "
                    f"sample {last} ({shown})",
                    flush=True,
                )
            return 0
        if waited > timeout:
            print(
                f"[amb-run] drain timeout ({timeout:g} s, --drain-timeout): still behind the "
                f"plant's last sample {last}: {shown}; stopped anyway, what they had not "
                "processed is missing from the bag",
                file=sys.stderr,
            )
            return 1
        if not quiet and waited - last_print >= 1.0:
            last_print = waited
            print(f"[amb-run] draining ({waited:5.1f} s): {shown} of {last}", flush=True)
        progress.spin(0.2)


def published(progress: Reports, runs: list[Process], samples: int) -> dict[str, int]:
    """Messages published per stream topic (absolute names), by the publishers that ran.

    Read after :func:`drain`: each drained node's last report then describes it after the
    plant's last sample, so its counts are final. A publisher that never reported its count is
    left out (it was not waited for).
    """
    running = {n for r in runs for n in r.hosts}
    out: dict[str, int] = {}
    for topic, (node, key) in PUBLISHED.items():
        if node not in running:
            continue
        value = samples if node == "plant_sim" else progress.report(node).get(key)
        if value is not None and str(value).isdigit():
            out[topics.absolute(topic, progress.namespace)] = int(value)
    return out


def settle_recording(
    progress: Reports, runs: list[Process], samples: int, timeout: float, quiet: bool
) -> int:
    """Wait until the recorder has written every message the publishers report as published.

    Parameters
    ----------
    progress : Reports
        The /diagnostics reader: the recorder reports its counts per topic every
        ``status_period`` (1 s by default).
    runs : list of Process
        The run's processes; nothing is waited for if none of them hosts a running recorder.
    samples : int
        Samples the plant produced (:func:`plant_samples`; known after a :func:`drain`).
    timeout : float
        Wall s to wait at most.
    quiet : bool
        No progress line (a recording left short is printed either way).

    Returns
    -------
    int
        0 when every count is reached (or there is no recorder); 1 if the bound was hit.
    """
    if not any("recorder" in r.hosts and r.proc.poll() is None for r in runs):
        return 0
    expected = published(progress, runs, samples)
    start = time.monotonic()
    while True:
        written = progress.report("recorder")
        have = {t: int(written.get(t, "0")) for t in expected}
        short = {t: (have[t], n) for t, n in expected.items() if have[t] < n}
        waited = time.monotonic() - start
        if not short and (written or not any(expected.values())):
            if not quiet:
                shown = ", ".join(f"{t} {n}" for t, n in expected.items())
                print(f"[amb-run] bag complete in {waited:.1f} s: {shown}", flush=True)
            return 0
        if waited > timeout:
            shown = ", ".join(f"{t} {h} of {n}" for t, (h, n) in short.items()) or "no report"
            print(
                f"[amb-run] recorder timeout ({timeout:g} s, --drain-timeout): the bag holds "
                f"fewer messages than were published: {shown}",
                file=sys.stderr,
            )
            return 1
        progress.spin(0.2)
