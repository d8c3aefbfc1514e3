"""
Settings of the early action on a sudden unbalance (:mod:`amb_controller.early_action`).

Their own module so that the detector (:mod:`.early_action`) and the plan
(:mod:`.early_plan`) both read them without importing each other.
"""

from __future__ import annotations

from dataclasses import dataclass

from amb_controller.errors import ControllerValueError

__all__ = ["EarlyActionConfig"]


@dataclass(frozen=True)
class EarlyActionConfig:
    """
    Settings of :class:`~amb_controller.early_action.EarlyAction`.

    The equations and the notes cited below are in the docstring of
    :mod:`amb_controller.early_action`.

    Attributes
    ----------
    threshold : float
        Likelihood-ratio threshold ``E / sigma_e^2`` of (E1), >= 10. Default 200: a false
        detection needs a noise excursion of about 14 standard deviations along one of the
        ``planes x 2 N`` candidate directions (at 60, model error under a +30 % gain
        perturbation passed as a 0.7 g cm "change" three periods before the real loss, and
        the re-arming after it missed the loss).
    max_residual : float
        Largest residual of the best fit, per value, as a multiple of ``sigma_e^2`` (> 1).
    max_unexplained : float
        In [0, 0.1]: a fit whose residual is larger is accepted all the same when it leaves at
        most this fraction of the innovation's energy (0: never). Default 1e-3: an
        unbalance's response fits a loss to 4e-5 of its energy with the model 0.4 % off
        (early_action's notes); what the residual test is there to refuse, a contact, a probe
        offset, a controller step, leaves far more.
    reference_periods : int
        ``R`` >= 1, quiet periods averaged into the reference.
    arm_periods : int
        Quiet periods needed (after start or after a detection) before the test runs, >= R.
    transient_samples : int
        ``M`` >= 0, samples of the transient force (E3) from ``k0`` (0: steady force only).
    transient_weight : float
        ``lambda`` >= 0 of (E3), relative to ``||H_M||``.
    transient_smoothing : float
        ``mu`` >= 0: weight of the added force's sample-to-sample steps in (E3), relative to
        ``||H_M||`` (the steady force's switch-on at ``k0`` included), the least smoothing
        tried; (E4) raises it when the plan steps faster than the amplifiers can. Default 0:
        with the fault monitor's kink rule (``MonitorConfig.control_kink``) an unsmoothed
        force no longer rings the monitor's contact test (no contact called in the 20 runs of
        the first- and second-critical losses at five fault phases, i = 1 and 2), and the
        peaks at i = 1 are lower than with ``mu = 2`` (docs/controller_notes.md).
    slew_budget : float
        In (0, 1]: the fraction of the amplifiers' slew (the model's ``slew_rate`` over one
        sample) the plan's own steps may use (E4); the rest is the PID loop's and the
        feedback law's. A model without a slew rate (inf) is not bounded.
    hold_law : bool
        Hold the feedback law at its command from before the change's onset while its
        measurements do not yet show the plan (early_action's docstring, "The feedback law"; the
        controller pipeline does it, for a law told the applied inputs). Default True.
    horizon_periods : int
        ``L / N``, periods of the predicted response used by (E2)-(E3), >= 2.
    min_noise : float
        Floor of the innovation's standard deviation ``sigma_e``, m (a noise-free simulation
        would otherwise make every rounding error a detection).
    force_budget : float
        In (0, 1]: the plan (steady + transient) stays within this fraction of the force
        limit; a larger transient force (E3) is scaled down as a whole. The limiter would
        otherwise clip it sample by sample into a force that no longer cancels anything: on
        the figure-5.27 contact case a clipped 2430 N plan put the rotor on its auxiliary
        bearing. Scaling keeps the plan's shape, so what is left of the transient is
        ``(1 - scale)`` of it: never more than without the transient force.
    gain_margin : float
        In [0, 1): the relative error ``m`` of the model's force path the plan is made robust
        to. The plan is an open-loop force: a path ``g`` times the model's leaves ``1 -
        c / g`` of the change for the feedback law when the plan is scaled by ``c``; the
        worst case over ``g`` in ``[1 - m, 1 + m]`` is smallest for ``c = 1 - m^2`` (both
        ends equal, ``m``), against ``m / (1 - m)`` unscaled (43 % at m = 0.3).
    min_effect : float
        A change is acted on only if its predicted response over the horizon peaks at
        ``min_effect`` innovation standard deviations or more: a change the probes can hardly
        see is not worth an open-loop force (and is, more likely, model error: on the
        second-critical run two such "changes" of 0.03 and 0.15 g cm passed the likelihood
        test at 220 and 279).
    speed_tolerance : float
        In (0, 0.1]: the largest relative difference between the measured speed and the speed
        of the model in use (:meth:`amb_controller.early_model.EarlyModelBank.select`);
        farther from every model of its bank the stage does not test. Default 0.005: within
        it the 430 g cm losses at the first and second critical speeds run as with the exact
        model; at 1 % the second critical's loss is not decided, and the first's is not with
        the plant 1 % faster than its model (docs/controller_notes.md).
    """

    threshold: float = 200.0
    max_residual: float = 1.5
    max_unexplained: float = 1e-3
    reference_periods: int = 4
    arm_periods: int = 8
    transient_samples: int = 64
    transient_weight: float = 0.03
    transient_smoothing: float = 0.0
    horizon_periods: int = 6
    min_noise: float = 1e-9
    force_budget: float = 0.6
    gain_margin: float = 0.3
    min_effect: float = 10.0
    speed_tolerance: float = 0.005
    slew_budget: float = 0.6
    hold_law: bool = True

    def __post_init__(self) -> None:
        checks = [
            (self.threshold >= 10.0, f"threshold must be >= 10, got {self.threshold}"),
            (self.max_residual > 1.0, f"max_residual must be > 1, got {self.max_residual}"),
            (0.0 <= self.max_unexplained <= 0.1, "max_unexplained must be in [0, 0.1]"),
            (self.reference_periods >= 1, "reference_periods must be >= 1"),
            (
                self.arm_periods >= self.reference_periods,
                f"arm_periods ({self.arm_periods}) must be >= reference_periods "
                f"({self.reference_periods})",
            ),
            (self.transient_samples >= 0, "transient_samples must be >= 0"),
            (self.transient_weight >= 0.0, "transient_weight must be >= 0"),
            (self.transient_smoothing >= 0.0, "transient_smoothing must be >= 0"),
            (self.horizon_periods >= 2, "horizon_periods must be >= 2"),
            (self.min_noise > 0.0, "min_noise must be > 0 m"),
            (0.0 < self.force_budget <= 1.0, "force_budget must be in (0, 1]"),
            (0.0 <= self.gain_margin < 1.0, "gain_margin must be in [0, 1)"),
            (self.min_effect >= 0.0, "min_effect must be >= 0"),
            (0.0 < self.speed_tolerance <= 0.1, "speed_tolerance must be in (0, 0.1]"),
            (0.0 < self.slew_budget <= 1.0, "slew_budget must be in (0, 1]"),
        ]
        for ok, message in checks:
            if not ok:
                raise ControllerValueError(message)
