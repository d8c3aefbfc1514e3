"""
The commands a supervisor sent, and what to do when the plant did not apply one.

:class:`CommandLedger` keeps, per target period, the control coefficients sent and the
controller step that made them, until the period has started. When the plant reports a period
run without its command (``STATUS_COMMAND_MISSING``) the ledger records zero as applied and
undoes the step (:meth:`CommandLedger.missing`); when a realtime plant applied the command from
a later sample on, it records the share that acted and takes the undo back if the command acted
on at least half of the period (:meth:`CommandLedger.resumed`). Why a lost command is undone:
:mod:`amb_controller.supervisor`, "Commands the plant did not apply" (the integrator of eq. 8.10
would otherwise wind up on a force that never acted).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.synthesis import BasisSet, synthesize

__all__ = ["MISSING", "RESUMED", "CommandLedger", "MissingFlags", "Step"]

#: :meth:`MissingFlags.observe`: the sample's period ran without its command (so far).
MISSING = "missing"
#: :meth:`MissingFlags.observe`: a flagged period's command acts from this sample on.
RESUMED = "resumed"


@dataclass
class Step:
    """A controller step, kept until its command is known to be applied (or not).

    For a controller that ``tracks_applied``, ``measured`` and ``state_before`` are None: only
    the fact that it ran (and must be told of a lost command) is kept.
    """

    period: int
    measured: np.ndarray | None
    state_before: object
    skipped: bool


@dataclass
class _Undone:
    """What :meth:`CommandLedger.missing` changed, for :meth:`CommandLedger.resumed`."""

    period: int
    controller: object  # the controller it concerned (replaced or reset: nothing to take back)
    sent: np.ndarray | None  # the command's coefficients (None: none was sent)
    state: object  # the controller's state before the undo (None: nothing was replayed)
    steps: dict | None  # target -> (step, its state_before) before the undo


class CommandLedger:
    """
    Commands sent per target period and the steps that made them.

    Parameters
    ----------
    basis : BasisSet
        The control basis (coefficient layout; the projection of a partly applied command).
    """

    def __init__(self, basis: BasisSet) -> None:
        self.basis = basis
        self._sent: dict[int, np.ndarray] = {}
        self.steps: dict[int, Step] = {}  # target period -> the step that made its command
        self._missing_reported: int | None = None
        self._undone: _Undone | None = None  # missing()'s last report

    @property
    def zeros(self) -> np.ndarray:
        """A zero command (coefficients)."""
        return np.zeros(self.basis.n_coefficients)

    def sent(self, target: int) -> np.ndarray | None:
        """The coefficients sent for period ``target`` (None: none kept for it)."""
        return self._sent.get(int(target))

    def applied(self, period_index: int) -> np.ndarray:
        """The control coefficients commanded for ``period_index`` (zeros if none)."""
        sent = self.sent(period_index)
        return self.zeros if sent is None else sent

    def record(self, target: int, coefficients: np.ndarray) -> None:
        """Record ``coefficients`` as the command sent for period ``target``."""
        self._sent[int(target)] = coefficients

    def clear(self) -> None:
        """Forget every command sent (a supervisor reset)."""
        self._sent.clear()

    def forget_steps(self) -> None:
        """Forget the steps and any undo (the controller was reset: nothing to take back)."""
        self.steps.clear()
        self._undone = None

    def prune(self, k: int, delay: int) -> None:
        """Drop what period ``k``'s step no longer needs.

        Commands older than ``k - delay - 1`` (the oldest a missing flag can still name), and
        the steps of periods that have started (their missing flag came before now).
        """
        for old in [p for p in self._sent if p < k - delay - 1]:
            del self._sent[old]
        for old in [p for p in self.steps if p <= k]:
            del self.steps[old]

    def missing(self, period_index: int, controller, tracks_applied: bool) -> bool:
        """
        Record that period ``period_index`` ran with zero wavelet force; undo its step.

        The command sent for it, if any, is undone: ``controller`` returns to its state before
        the step that made it, that step counts as skipped, and later steps are made again
        (their commands stand; only the state is corrected). A controller that
        ``tracks_applied`` is told zero was applied instead. Later calls for the same period
        are ignored.

        Parameters
        ----------
        period_index : int
            The period that ran without a command.
        controller : object or None
            The supervisor's controller (``get_state``, ``set_state``, ``skip``, ``step``;
            ``record_applied`` if it tracks the applied inputs).
        tracks_applied : bool
            Whether ``controller`` is told the applied inputs (no replay).

        Returns
        -------
        bool
            True if a command had been sent for the period and this is its first report.
        """
        p = int(period_index)
        if p == self._missing_reported:
            return False
        self._missing_reported = p
        sent = p in self._sent
        step = self.steps.get(p)
        replayed = step is not None and controller is not None and not tracks_applied
        # resumed(): what the command said and, for a replay, how to take it back
        self._undone = _Undone(
            p,
            controller,
            self._sent.get(p),
            controller.get_state() if replayed else None,
            {t: (s, s.state_before) for t, s in self.steps.items()} if replayed else None,
        )
        self._sent[p] = self.zeros
        self.steps.pop(p, None)
        if step is None or controller is None:
            return sent
        if tracks_applied:  # its estimate uses the applied inputs: tell it, no replay
            controller.record_applied(p, self._sent[p])
            return sent
        controller.set_state(step.state_before)
        controller.skip(step.period)
        for target in sorted(t for t in self.steps if t > p):
            later = self.steps[target]
            later.state_before = controller.get_state()
            if later.skipped:
                controller.skip(later.period)
            else:
                controller.step(later.period, later.measured)
        return sent

    def resumed(self, period_index: int, position: int, controller, tracks_applied: bool) -> bool:
        """
        Record that period ``period_index``, reported missing, ran with its command from a sample.

        What the period applied is the command's force with its first ``position`` samples
        zeroed; its coefficients, projected on the control basis (least squares), replace the
        zeros :meth:`missing` recorded. A replayed controller knows a step as made or not: the
        undo is taken back (its state and later steps as before the report) when the command
        acted on at least half of the period's samples, and kept otherwise, whichever is nearer
        what acted.

        Parameters
        ----------
        period_index : int
            The period, reported by :meth:`missing` at its first sample.
        position : int
            Its first sample without the flag, ``0 < position < N``.
        controller : object or None
            The supervisor's controller (the undo is taken back only if it is the one undone).
        tracks_applied : bool
            Whether ``controller`` is told the applied inputs.

        Returns
        -------
        bool
            True if a command had been sent for the period and this is the first such report;
            else nothing is changed.
        """
        p = int(period_index)
        undone = self._undone
        if undone is None or undone.period != p or undone.sent is None:
            return False
        self._undone = None
        basis = self.basis
        force = synthesize(undone.sent, basis)  # (axes, N), N
        length = force.shape[1]
        acted = length - min(length, max(0, int(position) - basis.offset))
        force[:, : length - acted] = 0.0  # columns from basis.offset
        W = basis.weights.reshape(basis.n_coefficients, -1)
        applied = np.linalg.lstsq(W.T, force.ravel(), rcond=None)[0]
        self._sent[p] = applied
        if controller is not None and tracks_applied:
            controller.record_applied(p, applied)
        elif (
            undone.state is not None and undone.controller is controller
            and 2 * acted >= length  # mostly applied: as if whole
        ):  # fmt: skip
            controller.set_state(undone.state)
            self.steps = {t: s for t, (s, _) in undone.steps.items()}
            for s, before in undone.steps.values():
                s.state_before = before
        return True


class MissingFlags:
    """
    Where a sample stream says a period ran without its command, and where the command resumed.

    The plant flags each sample of a period run without its command
    ``STATUS_COMMAND_MISSING``; a realtime plant with partial commands stops flagging from the
    sample on which a late command acts (:meth:`CommandLedger.resumed`). One reading of the
    flags for every controller (the pipeline and the sampled-harmonic baseline).
    """

    def __init__(self) -> None:
        self._flagged: int | None = None  # the period whose samples carry the flag

    def observe(self, period: int, position: int, missing: bool) -> str | None:
        """
        Read one sample's flag.

        Parameters
        ----------
        period, position : int
            The sample's period and its position in it.
        missing : bool
            The sample's ``STATUS_COMMAND_MISSING``.

        Returns
        -------
        str or None
            :data:`MISSING` at every flagged sample (a report the ledger takes once per
            period), :data:`RESUMED` at a flagged period's first unflagged sample (once), else
            None.
        """
        if missing:
            self._flagged = period
            return MISSING
        if position and self._flagged == period:
            self._flagged = None
            return RESUMED
        return None
