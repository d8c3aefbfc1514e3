"""The early action (:mod:`amb_controller.early_action`) on the pipeline's sample stream."""

from __future__ import annotations

from collections import OrderedDict

import numpy as np

from amb_controller.early_action import Detection, EarlyAction, EarlyActionConfig
from amb_controller.early_model import EarlyActionModel, EarlyModelBank
from amb_controller.errors import ControllerValueError

__all__ = ["EarlyStage"]

#: Early actions kept built (a switch back to a recent speed costs no construction: 44 ms at
#: 32 samples per revolution, 168 ms at 64, on the development machine).
_KEPT = 3


def _as_bank(models: EarlyModelBank | EarlyActionModel) -> EarlyModelBank:
    """A bank as it is, one model as a bank of one."""
    return EarlyModelBank((models,)) if isinstance(models, EarlyActionModel) else models


class EarlyStage:
    """
    :class:`EarlyAction` on a sample stream, as the controller pipeline feeds it.

    It keeps the period's displacements of the model's sensors, its measured speeds and the
    force of every command it passed on, so that :meth:`EarlyAction.end_period` gets the force
    the plant applied (zero for a command the plant did not apply). At each period's end it
    picks the bank's model for the period's mean measured speed
    (:meth:`EarlyModelBank.select`, within ``config.speed_tolerance``): a change of model
    starts that model's test afresh (its history, plan and arming; a plan of the previous one
    is dropped), and with no model near the speed the stage tests nothing and adds nothing.

    Parameters
    ----------
    bank : EarlyModelBank or EarlyActionModel
        The models (one model: a bank of one).
    config : EarlyActionConfig
    delay : int
        The controller's delay ``i``, periods.

    Attributes
    ----------
    early : EarlyAction or None
        The early action of the model in use (None: no model near the speed).
    detections : list of Detection
        Every decision of the run, whichever model made it.
    speed_idle_periods : int
        Periods with no model within the tolerance of the measured speed.
    """

    @classmethod
    def from_model(
        cls,
        bank: EarlyModelBank | EarlyActionModel,
        delay: int,
        samples_per_period: int,
        config: EarlyActionConfig | None = None,
    ) -> EarlyStage:
        """The stage of ``bank`` with ``config`` (default: the default :class:`EarlyActionConfig`).

        The force limit comes with each period (:meth:`end_period`: a run-time change).
        """
        bank = _as_bank(bank)
        if bank.models[0].samples_per_rev != samples_per_period:
            raise ControllerValueError(
                f"early-action model for {bank.models[0].samples_per_rev} samples per period, "
                f"the controller runs {samples_per_period}"
            )
        return cls(bank, config or EarlyActionConfig(), delay)

    def __init__(
        self, bank: EarlyModelBank | EarlyActionModel, config: EarlyActionConfig, delay: int
    ) -> None:
        bank = _as_bank(bank)
        self.bank, self.config, self.delay = bank, config, int(delay)
        first = bank.models[0]
        self.N = N = first.samples_per_rev
        self._sensors = np.asarray(first.sensors, dtype=int)
        self._y = np.zeros((N, len(self._sensors)))
        self._omega = np.zeros(N)
        self._seen = np.zeros(N, dtype=bool)
        self._sent: dict[int, np.ndarray] = {}
        self._missing: dict[int, int] = {}  # period -> its first sample run with the command
        self._built: OrderedDict[int, EarlyAction] = OrderedDict()
        self._index: int | None = None
        self.early: EarlyAction | None = None
        self.detections: list[Detection] = []
        self.speed_idle_periods = 0
        # before any speed is measured: the bank's rule (a single model of unrecorded speed
        # is in use at once, a bank of speeds waits for the first period's speed)
        self._use(bank.select(0.0, config.speed_tolerance))

    @property
    def model_omega(self) -> float | None:
        """Speed of the model in use, rad/s (None: none)."""
        return None if self.early is None else self.early.model.omega

    def _use(self, index: int | None) -> None:
        """Make model ``index`` the one in use, its test started afresh (None: none)."""
        self._index = index
        if index is None:
            self.early = None
            return
        early = self._built.pop(index, None)
        if early is None:
            early = EarlyAction(self.bank.models[index], self.config, self.delay)
        else:
            early.reset()
        self._built[index] = early
        while len(self._built) > _KEPT:
            self._built.popitem(last=False)
        self.early = early

    def sample(self, position: int, displacement, omega: float = 0.0) -> None:
        """Keep sample ``position`` of the current period (all 8 sensors, m; speed, rad/s)."""
        self._y[position] = np.asarray(displacement, dtype=float)[self._sensors]
        self._omega[position] = omega
        self._seen[position] = True

    def command_missing(self, period: int) -> None:
        """Period ``period`` ran without its command (zero wavelet force applied)."""
        self._missing[int(period)] = self.N

    def command_resumed(self, period: int, position: int) -> None:
        """Period ``period``, reported missing, ran with its command from sample ``position`` on.

        A realtime plant's partial command (``plant_sim``'s ``partial_commands``): the period's
        test then takes the command's force with its first ``position`` samples at zero, what
        the rotor felt; taken as zero, the rest would look like a change of the rotor.
        """
        if int(period) in self._missing:
            self._missing[int(period)] = int(position)

    def end_period(
        self,
        period: int,
        target: int,
        force: np.ndarray,
        active: bool,
        complete: bool,
        force_limit,
    ) -> tuple[np.ndarray, Detection | None, np.ndarray]:
        """
        Test period ``period`` and return the command force for ``target`` with the plan added.

        :meth:`test`, then :meth:`compose` (the controller pipeline calls the two itself, to
        hold the feedback law between them).

        Parameters
        ----------
        period, target : int
            The measured period and the period the command is for.
        force : numpy.ndarray
            The feedback law's command force, shape ``(4, N)``, N.
        active : bool
            Whether the controller acts (the plan is added only then; it is kept otherwise).
        complete : bool
            Whether every sample of the period was seen in order (else the history restarts).
        force_limit : array_like
            Per-axis limit of the total wavelet force now, N (the added force never lifts a
            command past it).

        Returns
        -------
        force : numpy.ndarray
            ``(4, N)``, limited per axis to ``force_limit``.
        detection : Detection or None
        clipped : numpy.ndarray of bool
            ``(4,)``: the axes whose command the limit cut once the plan was added (the
            command's ``saturated`` flag must say so too).
        """
        detection = self.test(period, complete, force_limit)
        out, clipped = self.compose(target, force, active, force_limit)
        return out, detection, clipped

    def test(self, period: int, complete: bool, force_limit) -> Detection | None:
        """
        Test period ``period`` (its samples given to :meth:`sample`) with the model of its speed.

        ``complete`` and ``force_limit`` as in :meth:`end_period`. Returns the decision, if any.
        """
        N = self.N
        limit = np.broadcast_to(np.asarray(force_limit, dtype=float), (4,))
        applied = self._sent.pop(period, None)
        start = self._missing.pop(period, 0)  # the first sample that ran with the command
        if applied is None or start >= N:
            applied = np.zeros((4, N))
        elif start:
            applied = applied.copy()
            applied[:, :start] = 0.0
        for old in [p for p in self._sent if p < period]:
            del self._sent[old]
        if self._seen.any():
            omega = float(self._omega[self._seen].mean())
            index = self.bank.select(omega, self.config.speed_tolerance, self._index)
            if index != self._index:
                self._use(index)
        detection = None
        early = self.early
        if early is None:
            self.speed_idle_periods += 1
        elif complete and self._seen.all():
            early.force_limit = float(np.max(limit))
            detection = early.end_period(period, self._y, applied.T)
            if detection is not None:
                self.detections.append(detection)
        else:
            early.reset()
        self._seen[:] = False
        return detection

    def compose(
        self, target: int, force: np.ndarray, active: bool, force_limit
    ) -> tuple[np.ndarray, np.ndarray]:
        """
        The command force for ``target``: the law's ``force`` with the plan added.

        Kept as the force the plant applies over ``target`` (what :meth:`test` of that period
        removes from its measurements). Returns the force ``(4, N)``, limited per axis to
        ``force_limit``, and the axes the limit cut (``(4,)`` bool); a command the plan adds
        nothing to passes untouched.
        """
        limit = np.broadcast_to(np.asarray(force_limit, dtype=float), (4,))
        out = np.asarray(force, dtype=float)
        early = self.early
        added = early.force(target).T if (active and early is not None) else None
        clipped = np.zeros(4, dtype=bool)
        if added is not None and added.any():
            total = out + added
            clipped = (np.abs(total) > limit[:, None]).any(axis=1)
            out = np.clip(total, -limit[:, None], limit[:, None])
        self._sent[target] = out
        return out, clipped
