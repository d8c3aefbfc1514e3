"""
The join of the measurement and coefficient streams, sample by sample, without ROS.

Every sample ``n`` has a ``Measurement``; the filterbank publishes a ``WaveletCoefficients``
message exactly for odd ``n`` (its finest level completes every second sample). Sample ``n`` is
released once its measurement and, for odd ``n``, its coefficients are in, whatever order the
transport delivered them in, so that the controller's commands equal the in-process runner's
(``amb-sim``) bit for bit. If a coefficient message is lost (a later one arrived first: each
topic is delivered in order), the sample is released without it and the pipeline answers that
period with zero force.

Measurements are sequenced by the sequencer the node gives
(:class:`amb_tools.validation.SampleSequencer`: repeats, stray indices and impossible stamps are
dropped; a confirmed gap or restart first releases everything queued, without waiting for its
coefficients). Coefficient messages are refused if their wavelet
or ``samples_per_rev`` is not the controller's, their sample index lies before the stream or
more than :data:`COEFFICIENT_HORIZON_PERIODS` periods ahead of it, or their stamp differs from
their measurement's. The coefficients of an odd sample are given up on once no coefficient
message for an earlier sample has come for ``timeout`` wall seconds since the later of its
measurement's arrival and the last such message (a dead filterbank; ``wavelet_controller``'s
module notes say why the timeout counts from the stream's progress). A message for a later
sample is no progress towards this one (a filterbank restarted past it never sends it), but a
message within two periods after it means this one was lost.

The node (:mod:`amb_controller.node`) validates the messages' contents, owns the clocks and the
log, and hands each released ``(measurement, coefficients or None)`` to the pipeline. The join
holds only the streams' state (explicit, as scipy.signal's streaming filters hold theirs), so
it is tested without DDS (``test/controller/test_stream_join.py``).
"""

from __future__ import annotations

from collections import deque
from collections.abc import Callable
from typing import Any

__all__ = ["COEFFICIENT_HORIZON_PERIODS", "StreamJoin"]

#: Coefficient messages more than this many periods ahead of the measurements are refused.
COEFFICIENT_HORIZON_PERIODS = 8

#: A released sample: its measurement and its coefficients (None: not expected, or given up).
Released = tuple[Any, Any]


class StreamJoin:
    """
    Measurements and coefficient messages in, samples in index order out (module notes).

    Parameters
    ----------
    wavelet : str
        The controller's wavelet; coefficient messages of another are refused.
    samples_per_period : int
        Samples per control period (the horizon and the search for a later message).
    max_backlog : int
        Measurements allowed to wait for their coefficients; the oldest beyond it are dropped
        (realtime catch-up; 0: keep every one, as in lock-step).
    sequencer : amb_tools.validation.SampleSequencer
        Orders the measurements (``push``, ``counts``, ``last_reason``, ``pending_index``);
        given, not made here, so that this module imports nothing of the transport. Its
        ``samples_per_rev`` is the stream's: coefficient messages of another are refused.
    report : callable
        ``report(key, text)``: a rejection, a sequencing event or a drop, of kind ``key``
        (the node makes it its status's reason and logs it, throttled per key).

    Attributes
    ----------
    counts : dict
        ``coefficients_rejected``, ``coefficients_missing`` (odd samples released without
        them), ``pending_dropped`` (measurements dropped beyond ``max_backlog``).
    sequencer : amb_tools.validation.SampleSequencer
        The measurements' sequencer (its own counts: repeats, strays, gaps, restarts).
    last_processed : int or None
        Index of the last released sample.
    last_coefficient : tuple of (int, float) or None
        Index and arrival (wall s) of the last accepted coefficient message.
    """

    def __init__(
        self,
        wavelet: str,
        samples_per_period: int,
        max_backlog: int,
        sequencer: Any,
        report: Callable[[str, str], None],
    ) -> None:
        self.wavelet = wavelet
        self.samples_per_rev = int(sequencer.samples_per_rev)
        self.samples_per_period = int(samples_per_period)
        self.max_backlog = int(max_backlog)
        self._report = report
        self.sequencer = sequencer
        self.counts = dict.fromkeys(
            ("coefficients_rejected", "coefficients_missing", "pending_dropped"), 0
        )
        self.last_processed: int | None = None
        self.last_coefficient: tuple[int, float] | None = None
        self._pending: deque[tuple[Any, float]] = deque()  # (measurement, arrival wall s)
        self._coefficients: dict[int, Any] = {}

    @property
    def waiting(self) -> int:
        """Measurements queued, waiting for their coefficients or for their turn."""
        return len(self._pending)

    @property
    def horizon(self) -> int:
        """Samples a coefficient message may run ahead of the measurements."""
        return COEFFICIENT_HORIZON_PERIODS * self.samples_per_period

    def newest(self) -> int | None:
        """Index of the newest measurement queued or released (None before the first)."""
        return self._pending[-1][0].sample_index if self._pending else self.last_processed

    def beyond_horizon(self, index: int) -> bool:
        """Whether coefficients of sample ``index`` run more than the horizon ahead."""
        newest = self.newest()
        return newest is not None and index > newest + self.horizon

    def measurement(
        self, msg: Any, stamp_s: float, now: float, timeout: float, gap_known: bool = False
    ) -> list[Released]:
        """
        Offer a valid measurement; return the samples released by it, in order.

        Parameters
        ----------
        msg : object
            The measurement (``sample_index``, ``rotor_speed`` rad/s, ``header.stamp``).
        stamp_s : float
            s, its ``header.stamp``.
        now : float
            s, wall time of its arrival (monotonic).
        timeout : float
            s, the coefficient timeout (module notes).
        gap_known : bool
            The reader dropped messages just before this one (``SampleSequencer.push``).
        """
        seq = self.sequencer
        before = dict(seq.counts)
        accepted = seq.push(int(msg.sample_index), stamp_s, msg.rotor_speed, msg, gap_known)
        if seq.counts != before:
            self._report("sequence", seq.last_reason)
        out: list[Released] = []
        for reset, m in accepted:
            if reset and self.last_processed is not None:
                # restart or gap: everything queued belongs to the old stream's tail
                out += self.release(now, timeout, force=True)
            self._pending.append((m, now))
        excess = len(self._pending) - self.max_backlog
        if self.max_backlog and excess > 0:
            # realtime and behind: the filterbank's coefficients trail the measurements, so the
            # backlog sits here, not in the transport's queue; the oldest go (a gap downstream)
            for _ in range(excess):
                self._pending.popleft()
            self.counts["pending_dropped"] += excess
            self._report(
                "pending",
                f"{excess + self.max_backlog} measurements waiting for their coefficients, more "
                f"than max_backlog = {self.max_backlog}: the oldest {excess} dropped",
            )
        return out + self.release(now, timeout)

    def coefficients(self, msg: Any, now: float, timeout: float) -> list[Released]:
        """
        Offer a coefficient message; return the samples released by it, in order.

        A refused message is counted and reported (module notes) and releases nothing.

        Parameters
        ----------
        msg : object
            The message (``sample_index``, ``wavelet``, ``samples_per_rev``, ``header.stamp``).
        now : float
            s, wall time of its arrival (monotonic).
        timeout : float
            s, the coefficient timeout.
        """
        n = int(msg.sample_index)
        seq = self.sequencer
        reason = None
        if msg.wavelet != self.wavelet or msg.samples_per_rev != self.samples_per_rev:
            reason = (
                f"coefficients of sample {n}: {msg.wavelet!r} at {msg.samples_per_rev} "
                f"samples/rev, expected {self.wavelet!r} at {self.samples_per_rev}"
            )
        elif self.beyond_horizon(n):
            reason = (
                f"coefficients of sample {n}: measurements only reach {self.newest()}, from the "
                "future"
            )
        elif n in self._coefficients:
            reason = f"coefficients of sample {n} repeated"
        elif (
            self.last_processed is not None
            and n <= self.last_processed
            and not (seq.pending_index is not None and n >= seq.pending_index)
        ):
            reason = f"coefficients of sample {n}: sample {self.last_processed} already processed"
        if reason is not None:
            self.reject(reason + "; dropped")
            return []
        self._coefficients[n] = msg
        self.last_coefficient = (n, now)
        while len(self._coefficients) > 2 * self.horizon:  # bounded, whatever arrives
            del self._coefficients[min(self._coefficients)]
        return self.release(now, timeout)

    def release(self, now: float, timeout: float, force: bool = False) -> list[Released]:
        """
        The queued samples that may go now, in order (module notes).

        Parameters
        ----------
        now : float
            s, wall time (monotonic).
        timeout : float
            s, the coefficient timeout.
        force : bool
            Stop waiting for coefficients: release every queued sample.
        """
        out: list[Released] = []
        while self._pending:
            m, received = self._pending[0]
            n = int(m.sample_index)
            coeffs = self._coefficients.pop(n, None)
            if coeffs is None and n % 2 == 1:
                later = any(n < k <= n + 2 * self.samples_per_period for k in self._coefficients)
                # the timeout is a silence of the coefficient stream on its way to n, not the
                # age of the measurement: a loaded filterbank working through a period; a
                # message beyond n is no progress (a filterbank restarted past n)
                since = received
                if self.last_coefficient is not None and self.last_coefficient[0] < n:
                    since = max(since, self.last_coefficient[1])
                if not (force or later or now - since > timeout):
                    break  # wait for the coefficients of this sample
                self.counts["coefficients_missing"] += 1
            self._pending.popleft()
            for old in [k for k in self._coefficients if k <= n]:
                del self._coefficients[old]  # belong to samples before a restart, or lost
            if coeffs is not None and coeffs.header.stamp != m.header.stamp:
                self.reject(
                    f"coefficients of sample {n}: stamp differs from the measurement's; dropped"
                )
                coeffs = None
            out.append((m, coeffs))
            self.last_processed = n
        return out

    def reject(self, reason: str) -> None:
        """Count and report a refused coefficient message (also one the node cannot read)."""
        self.counts["coefficients_rejected"] += 1
        self._report("coefficients_rejected", reason)
