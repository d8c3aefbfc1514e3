"""
The commands a plant applies, period by period: which it admits, and how in time they came.

ROS-free bookkeeping of :mod:`amb_plant_sim.node` (the rules are in its docstring and in
ARCHITECTURE.md, "Time"). Control period ``k`` covers samples ``k N .. k N + N - 1``; the
command for it answers measured period ``k - i`` (thesis eq. 8.10, ``i = delay_periods``).
The node parses a ``ControlCommand`` (:func:`amb_tools.validation.check_command`) and offers
what it says as a :class:`CommandOffer`; :meth:`CommandBook.offer` admits it or names why not,
:meth:`CommandBook.take` hands a period its force when the period starts. In ``realtime`` the
book also keeps the wall times a rig is judged by: the latency from a period's last sample to
the command based on it, and each command's arrival minus its period's start.

Partial commands (``realtime``, ``partial=True``): a period that starts without its command
stays *open*; its command, if it arrives before the period ends, is still late (counted
``late``, its arrival offset kept) but is kept, and :meth:`CommandBook.take_rest` hands the
plant its force for the samples still ahead (counted ``partial``). The samples before it ran
with zero wavelet force, as a missing period's do. What this buys: a command a fraction of a
period late (a stall of the transport or a busy core) acts on the rest of its period instead of
leaving the whole period on PID (a force step of the command's size at both its ends, which
the rotor and the fault monitor then see: ``docs/history.md``, "Partial commands").
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

#: Commands may target at most this many periods beyond ``next period + delay_periods``.
COMMAND_HORIZON_PERIODS = 16
#: Counters of :attr:`CommandBook.counts`, in report order.
COUNTS = (
    "applied",
    "missing",
    "late",
    "rejected",
    "clipped",
    "saturated_samples",
    "watchdog_trips",
    "parameter_changes",
    "taken_at_start",  # realtime: commands found queued as their period started
    "partial",  # realtime: late commands applied to the rest of their period
)
#: Wall times kept per period (start, end of publication), periods back.
WALL_HISTORY = 64
#: Latencies and arrival offsets kept for the summaries.
SPREAD_HISTORY = 100_000


def spread(values) -> dict[str, float]:
    """``p50``, ``p99`` and ``max`` of a non-empty sequence of numbers."""
    a = np.asarray(values, dtype=float)
    return {"p50": float(np.median(a)), "p99": float(np.quantile(a, 0.99)), "max": float(a.max())}


@dataclass(frozen=True)
class CommandOffer:
    """
    What one ``ControlCommand`` says.

    Attributes
    ----------
    period_index : int
        The period it is for, ``k``.
    delay_periods : int
        The ``i`` it was made for (eq. 8.10).
    based_on_period : int
        The measured period it answers.
    stamp : float
        Its header stamp, s: the last measured sample it used.
    force : ndarray (N, 4) or None
        Wavelet force per sample and axis [b1x, b1y, b2x, b2y], N; None if the message was
        malformed, ``malformed`` then says how.
    malformed : str or None
        Why the message could not be read.
    """

    period_index: int
    delay_periods: int
    based_on_period: int
    stamp: float
    force: NDArray[np.float64] | None
    malformed: str | None = None


class CommandBook:
    """
    The admitted commands and the counts and wall times of a plant's control periods.

    Parameters
    ----------
    delay_periods : int
        The plant's ``i``.
    force_limit : float
        N per axis; an admitted force beyond it is clipped (counted ``clipped``).
    realtime : bool
        Keep the wall times of periods and arrivals (``realtime`` mode).
    partial : bool
        Realtime: keep a command that arrives while its period runs, for the samples still
        ahead (module docstring). Ignored in lock-step, where a period waits for its command.
    """

    def __init__(
        self, delay_periods: int, force_limit: float, realtime: bool, partial: bool = False
    ) -> None:
        self.delay = int(delay_periods)
        self.force_limit = float(force_limit)
        self.realtime = bool(realtime)
        self.partial = bool(partial) and self.realtime
        self.open_period: int | None = None  # partial: the running period with no command yet
        self._late_force: tuple[int, NDArray[np.float64]] | None = None  # its command, arrived
        self._partial_share = 0.0  # sum over partial periods of the share of samples commanded
        self.counts = dict.fromkeys(COUNTS, 0)
        self._commands: dict[int, NDArray[np.float64]] = {}
        self._arrived: dict[int, float] = {}  # realtime: wall time each command arrived
        self._start_wall: dict[int, float] = {}  # realtime: wall time each period started
        self._end_wall: dict[int, float] = {}  # wall time each period's last sample left
        self._latency: deque[float] = deque(maxlen=SPREAD_HISTORY)
        self._arrival_offset: deque[float] = deque(maxlen=SPREAD_HISTORY)

    def __contains__(self, period: int) -> bool:
        return period in self._commands

    def offer(
        self, offer: CommandOffer, next_period: int, last_stamp: float, now: float
    ) -> str | None:
        """
        Admit a command, or count and name why not.

        Parameters
        ----------
        offer : CommandOffer
            The command.
        next_period : int
            The first period not yet started (simulated) by the plant.
        last_stamp : float
            Stamp of the last sample published, s.
        now : float
            Monotonic wall time of the arrival, s.

        Returns
        -------
        str or None
            None if admitted; else the reason, counted ``late`` (its period has started) or
            ``rejected`` (malformed, made for another ``i``, a repeat, beyond the horizon of
            :data:`COMMAND_HORIZON_PERIODS`, or from the future). A late command for the
            open period (``partial``) is kept for :meth:`take_rest`; its reason says so.
        """
        k = offer.period_index
        if k < next_period:
            self.counts["late"] += 1
            started = self._start_wall.get(k)
            if started is not None:
                self._arrival_offset.append(now - started)
            reason = f"command for period {k} arrived after it started (now {next_period})"
            usable = offer.malformed is None and offer.delay_periods == self.delay
            if k == self.open_period and self._late_force is None and usable:
                self._late_force = (k, self._clipped(offer.force))
                return reason + ": applied to the rest of its period"
            return reason
        reason = offer.malformed or self._refusal(offer, next_period, last_stamp)
        if reason is not None:
            self.counts["rejected"] += 1
            return reason
        self._commands[k] = self._clipped(offer.force)
        if self.realtime:
            self._arrived[k] = now
        sent = self._end_wall.get(offer.based_on_period)
        if sent is not None:
            self._latency.append(now - sent)
        return None

    def _clipped(self, f: NDArray[np.float64]) -> NDArray[np.float64]:
        if np.any(np.abs(f) > self.force_limit):
            self.counts["clipped"] += 1
            return np.clip(f, -self.force_limit, self.force_limit)
        return f

    def _refusal(self, offer: CommandOffer, next_period: int, last_stamp: float) -> str | None:
        k = offer.period_index
        horizon = next_period + self.delay + COMMAND_HORIZON_PERIODS
        measured = next_period - 1  # the plant publishes whole periods
        if offer.delay_periods != self.delay:
            return (
                f"command for period {k} made with delay_periods {offer.delay_periods}, "
                f"the plant runs {self.delay}: controller and plant must agree"
            )
        if k in self._commands:
            return f"command for period {k} repeated: the first one is kept"
        if k > horizon:
            return f"command for period {k}: more than {horizon} is not plausible"
        if offer.based_on_period > measured:
            return (
                f"command for period {k} based on period {offer.based_on_period}, "
                f"only {measured} measured: from the future"
            )
        if offer.stamp > last_stamp + 1e-9:
            return (
                f"command for period {k} stamped {offer.stamp:.6f} s, after the last sample "
                f"({last_stamp:.6f} s): from the future"
            )
        return None

    def take(self, period: int, now: float | None = None) -> NDArray[np.float64] | None:
        """
        The force of a period that starts now (None: none admitted), forgetting older ones.

        Counts the period ``applied`` when it has a command. In realtime (``now`` given) the
        period's start is kept and, for a command, its arrival minus that start. With
        ``partial``, a period from ``delay_periods`` on that starts without a command becomes
        the open one (:meth:`take_rest`).
        """
        k = int(period)
        force = self._commands.pop(k, None)
        self._late_force = None
        self.open_period = k if self.partial and force is None and k >= self.delay else None
        if now is not None:
            self._start_wall[k] = now
            self._start_wall.pop(k - WALL_HISTORY, None)
            arrived = self._arrived.pop(k, None)
            if arrived is not None:
                self._arrival_offset.append(arrived - now)
        if force is not None:
            self.counts["applied"] += 1
        for old in [c for c in self._commands if c < k]:
            del self._commands[old]
        return force

    def take_rest(self, period: int, position: int) -> NDArray[np.float64] | None:
        """
        The force for the rest of the open period, if its command has arrived (else None).

        Parameters
        ----------
        period : int
            The period running without its command (:attr:`open_period`).
        position : int
            Its next sample, ``0 < position < N``.

        Returns
        -------
        ndarray (N - position, 4) or None
            The command's force from ``position`` on, N; counted ``partial`` and the period
            closed. None if no command for it has arrived (or ``period`` is not the open one).
        """
        if self._late_force is None or self._late_force[0] != period:
            return None
        force = self._late_force[1]
        self._late_force = None
        self.open_period = None
        self.counts["partial"] += 1
        self._partial_share += (len(force) - position) / len(force)
        return force[position:]

    def period_sent(self, period: int, now: float) -> None:
        """The last sample of ``period`` left the plant at wall time ``now`` (s)."""
        self._end_wall[period] = now
        self._end_wall.pop(period - WALL_HISTORY, None)

    def latency_summary(self) -> dict[str, float]:
        """Wall latency from a period's last sample to the command based on it (s).

        Returns
        -------
        dict
            ``p50``, ``p99``, ``max`` in s and ``n`` commands; empty before any command.
        """
        if not self._latency:
            return {}
        return {"n": float(len(self._latency)), **spread(self._latency)}

    def control_summary(self, periods: int) -> dict[str, float]:
        """The effective control delay: periods controlled, command arrival - period start.

        Parameters
        ----------
        periods : int
            Periods started so far.

        Returns
        -------
        dict
            ``controlled``: fraction of the periods from ``delay_periods`` on that ran with a
            command (those before cannot have one); ``controlled_samples``: the same in
            samples, partial periods counted by the share of their samples that ran with their
            command (equal to ``controlled`` without partial commands); realtime only, when
            commands arrived:
            ``arrival_p50``, ``arrival_p99``, ``arrival_max``, s, of each command's arrival
            minus its period's start (negative: before it, applied; positive: late by that).
        """
        eligible = periods - self.delay
        applied = self.counts["applied"]
        out = {
            "controlled": applied / eligible if eligible > 0 else math.nan,
            "controlled_samples": (
                (applied + self._partial_share) / eligible if eligible > 0 else math.nan
            ),
        }
        if self._arrival_offset:
            out |= {f"arrival_{k}": v for k, v in spread(self._arrival_offset).items()}
        return out

    def report(self, periods: int, period_s: float) -> str:
        """The latency and control summaries as the plant's final log line words them.

        Parameters
        ----------
        periods : int
            Periods started so far.
        period_s : float
            The control period, s.

        Returns
        -------
        str
            ``"; command latency ... ; periods controlled ..."`` (the latency part only once
            commands came; the arrival part in realtime; the samples controlled only with
            partial commands), times in ms.
        """
        lat = self.latency_summary()
        text = (
            f"; command latency p50 {lat['p50'] * 1e3:.2f} ms, p99 {lat['p99'] * 1e3:.2f} ms "
            f"({lat['p99'] / period_s:.1%} of the {period_s * 1e3:.1f} ms period)"
            if lat
            else ""
        )
        ctl = self.control_summary(periods)
        text += f"; periods controlled {ctl['controlled']:.1%}"
        if "arrival_p50" in ctl:
            text += (
                f", command arrival - period start p50 {ctl['arrival_p50'] * 1e3:+.2f} ms, "
                f"p99 {ctl['arrival_p99'] * 1e3:+.2f} ms, max {ctl['arrival_max'] * 1e3:+.2f} ms"
            )
        if self.counts["partial"]:  # late commands applied to the rest of their period
            text += f"; samples controlled {ctl['controlled_samples']:.1%}"
        return text
