"""The early action (:mod:`amb_controller.early_action`) on the pipeline's sample stream."""

from __future__ import annotations

import numpy as np

from amb_controller.early_action import Detection, EarlyAction, EarlyActionConfig
from amb_controller.early_model import EarlyActionModel
from amb_controller.errors import ControllerValueError

__all__ = ["EarlyStage"]


class EarlyStage:
    """
    :class:`EarlyAction` on a sample stream, as the controller pipeline feeds it.

    It keeps the period's displacements of the model's sensors and the force of every command
    it passed on, so that :meth:`EarlyAction.end_period` gets the force the plant applied
    (zero for a command the plant did not apply).

    Parameters
    ----------
    early : EarlyAction
    """

    @classmethod
    def from_model(cls, model: EarlyActionModel, delay: int, samples_per_period: int) -> EarlyStage:
        """The stage of ``model`` with the default :class:`EarlyActionConfig`.

        The force limit comes with each period (:meth:`end_period`: a run-time change).
        """
        if model.samples_per_rev != samples_per_period:
            raise ControllerValueError(
                f"early-action model for {model.samples_per_rev} samples per period, the "
                f"controller runs {samples_per_period}"
            )
        return cls(EarlyAction(model, EarlyActionConfig(), delay))

    def __init__(self, early: EarlyAction) -> None:
        self.early = early
        self._sensors = np.asarray(early.model.sensors, dtype=int)
        N = early.N
        self._y = np.zeros((N, len(self._sensors)))
        self._seen = np.zeros(N, dtype=bool)
        self._sent: dict[int, np.ndarray] = {}
        self._missing: set[int] = set()

    def sample(self, position: int, displacement) -> None:
        """Keep sample ``position`` of the current period (all 8 sensors, m)."""
        self._y[position] = np.asarray(displacement, dtype=float)[self._sensors]
        self._seen[position] = True

    def command_missing(self, period: int) -> None:
        """Period ``period`` ran without its command (zero wavelet force applied)."""
        self._missing.add(int(period))

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
        N = self.early.N
        limit = np.broadcast_to(np.asarray(force_limit, dtype=float), (4,))
        self.early.force_limit = float(np.max(limit))
        applied = self._sent.pop(period, None)
        if applied is None or period in self._missing:
            applied = np.zeros((4, N))
        self._missing.discard(period)
        detection = None
        if complete and self._seen.all():
            detection = self.early.end_period(period, self._y, applied.T)
        else:
            self.early.reset()
        self._seen[:] = False
        out = np.asarray(force, dtype=float)
        added = self.early.force(target).T if active else None
        clipped = np.zeros(4, dtype=bool)
        if added is not None and added.any():  # else the command passes untouched
            total = out + added
            clipped = (np.abs(total) > limit[:, None]).any(axis=1)
            out = np.clip(total, -limit[:, None], limit[:, None])
        self._sent[target] = out
        for old in [p for p in self._sent if p < period]:
            del self._sent[old]
        return out, detection, clipped
