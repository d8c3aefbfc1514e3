"""
Divergence guard of the wavelet controller.

Trips when the measured coefficients (or the raw displacement) show the loop running
away: any measured coefficient beyond ``coefficient_bound``, a peak displacement beyond
``displacement_bound`` (m; e.g. a fraction of the 750 um auxiliary-bearing clearance),
or the coefficient norm growing by more than ``growth_factor`` per period for
``growth_periods`` consecutive periods while above ``noise_floor``. After a trip the
supervisor drops the wavelet force to zero and reports; only :meth:`reset` re-arms it.

The contact guard (``ControllerConfig.contact_guard``, on by default) trips it when a probe
reads the clearance of the auxiliary bearing next to it
(:func:`amb_controller.selection.controller_guard`): the
rotor is at that bearing, its support is no longer the one the controller's model describes,
and a controller that goes on integrating there bounces the rotor from contact to contact
(thesis 3.3.2 stops the transient controller on contact; measured on ``amb-compare``'s
``contact_case2``: docs/results.md#compare). It needs no fault monitor: the controller reads
every probe's samples itself.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.errors import ControllerValueError


@dataclass(frozen=True)
class GuardConfig:
    """
    Thresholds of :class:`DivergenceGuard`.

    Attributes
    ----------
    coefficient_bound : float
        Largest admissible measured coefficient (m * sqrt(samples)); ``inf`` = off.
    displacement_bound : float
        Largest admissible displacement in m; ``inf`` = off.
    growth_factor : float
        Per-period growth ratio of the coefficient norm counted as divergence (> 1).
    growth_periods : int
        Consecutive growing periods that trip the guard.
    noise_floor : float
        Norm below which growth is ignored (m * sqrt(samples)).
    probe_clearance : tuple of float, optional
        Per probe channel, the clearance (m) of the auxiliary bearing next to it (inf: none)
        (:attr:`amb_common.rig.Rig.probe_clearance`): a period whose peak at a probe reaches
        it trips the guard (the rotor is at that bearing). None: no such check.

    """

    coefficient_bound: float = np.inf
    displacement_bound: float = np.inf
    growth_factor: float = 1.2
    growth_periods: int = 5
    noise_floor: float = 0.0
    probe_clearance: tuple[float, ...] | None = None

    def __post_init__(self) -> None:
        if self.probe_clearance is not None and not all(c > 0 for c in self.probe_clearance):
            raise ControllerValueError(
                f"probe clearances must be > 0 m (inf: none), got {self.probe_clearance}"
            )
        if not (self.coefficient_bound > 0 and self.displacement_bound > 0):
            raise ControllerValueError("guard bounds must be > 0 (use inf to disable)")
        if not self.growth_factor > 1.0 or self.growth_periods < 1:
            raise ControllerValueError(
                f"growth_factor must be > 1 and growth_periods >= 1, got {self.growth_factor}, "
                f"{self.growth_periods}"
            )


class DivergenceGuard:
    """
    Watch measured coefficients for divergence (see module docstring).

    Parameters
    ----------
    config : GuardConfig
        Thresholds.

    """

    def __init__(self, config: GuardConfig) -> None:
        self.config = config
        self.reset()

    def reset(self) -> None:
        """Re-arm the guard."""
        self.tripped = False
        self.reason = ""
        self._previous_norm: float | None = None
        self._growing = 0

    def update(self, measured: np.ndarray, displacement_peak=None) -> bool:
        """
        Check one period; return True if the guard is (now or already) tripped.

        Parameters
        ----------
        measured : numpy.ndarray
            Measured coefficients of the period.
        displacement_peak : float or numpy.ndarray, optional
            Largest absolute displacement of the period in m, overall (a float: no probe
            check) or per probe channel (one per ``probe_clearance``; another count is
            refused).

        Returns
        -------
        bool

        """
        if self.tripped:
            return True
        cfg = self.config
        measured = np.asarray(measured, dtype=float)
        peak = float(np.max(np.abs(measured))) if measured.size else 0.0
        norm = float(np.linalg.norm(measured))
        if not np.isfinite(norm):
            return self._trip("non-finite measured coefficients")
        if peak > cfg.coefficient_bound:
            return self._trip(f"coefficient {peak:.3g} beyond bound {cfg.coefficient_bound:.3g}")
        if displacement_peak is not None:
            peaks = np.atleast_1d(np.asarray(displacement_peak, dtype=float))
            largest = float(np.max(peaks)) if peaks.size else 0.0
            if largest > cfg.displacement_bound:
                return self._trip(
                    f"displacement {largest:.3g} m beyond bound {cfg.displacement_bound:.3g} m"
                )
            per_probe = np.ndim(displacement_peak) > 0
            if per_probe and cfg.probe_clearance is not None:
                if peaks.size != len(cfg.probe_clearance):
                    raise ControllerValueError(
                        f"{peaks.size} probe peaks for {len(cfg.probe_clearance)} probe clearances"
                    )
                reached = np.flatnonzero(peaks >= np.asarray(cfg.probe_clearance))
                if reached.size:
                    c = int(reached[0])
                    return self._trip(
                        f"probe channel {c} at {peaks[c]:.3g} m, the clearance "
                        f"{cfg.probe_clearance[c]:.3g} m of the auxiliary bearing next to it: "
                        "the rotor is at that bearing"
                    )
        if (
            self._previous_norm is not None
            and norm > cfg.noise_floor
            and norm > cfg.growth_factor * self._previous_norm
        ):
            self._growing += 1
        else:
            self._growing = 0
        self._previous_norm = norm
        if self._growing >= cfg.growth_periods:
            return self._trip(
                f"coefficient norm grew by > {cfg.growth_factor:g} x for {self._growing} periods"
            )
        return False

    def _trip(self, reason: str) -> bool:
        self.tripped = True
        self.reason = reason
        return True
