"""
Early action on a sudden unbalance: estimate it from the fault's own period, cancel it next.

Issue 18, item 4. The period-rate controllers (eq. 8.10, :mod:`amb_controller.predictive`,
the baselines) see a fault through the coefficients of whole periods: a mass loss late in its
period gives them a partial coefficient, and their first informed force comes a period or more
after the fault, while the response of a rotor at a critical speed has by then grown several
times (``docs/results.md#bound``: at the first critical speed the best force from 0.11
revolution after the fault keeps the peak at the pre-fault 25.6 um, the best period-rate
controller reaches 82.5 um). The samples of the fault's period already say what happened: a
430 g cm loss at the first critical speed moves the inner probes 0.5 um four samples (of 64)
after it and 5.7 um after seven, against 0.2 um of probe noise. This module reads them.

Model
-----
Both parts are sample-domain responses of the rig's PID loop at the running speed (``N``
samples per revolution, one control period per revolution), linear and time invariant:

* ``bearing_markov[n, s, a]``: sensor ``s`` at sample ``n`` after 1 N held over sample 0 on
  bearing axis ``a`` (the wavelet force's own input, zero-order hold), m/N;
* ``plane_responses[p, n, s, c]``: sensor ``s`` at sample ``n`` after a unit sudden unbalance
  (1 kg m) appears in plane ``p`` at sample 0, with angle 0 (``c = 0``) and pi/2 (``c = 1``)
  at that instant, m/(kg m). An unbalance is a forward-rotating force
  ``Re(me omega^2 e^{i(theta + omega t)})`` (eq. 3.3), so the response to a loss appearing at
  sample ``k`` with any angle is this pair shifted by ``k`` and combined with two real weights
  ``theta = (me cos phi_k, me sin phi_k)``, ``phi_k`` the unbalance's angle at its onset.

From the measured displacements ``y`` and the applied wavelet force ``f`` the controller
removes its own force's effect, ``z[n] = y[n] - sum_j H[j] f[n - j]`` (``H`` =
``bearing_markov``), so that ``z`` is periodic whenever the disturbances are, whatever the
feedback law does.

Detection and estimate (a generalised likelihood ratio test)
-------------------------------------------------------------
At the end of period ``m``, with ``ref`` the mean of ``z`` over the ``R`` periods before
``m - 1`` (all quiet), the innovation over the last two periods is
``e = z[m-1, m] - (ref, ref)`` (``2 N n_s`` values). For every plane ``p`` and onset ``k`` in
the window, the least-squares weights and the energy they explain are::

    theta_{p,k} = (A_{p,k}^T A_{p,k})^-1 A_{p,k}^T e,     E_{p,k} = e^T A_{p,k} theta_{p,k}   (E1)

(``A_{p,k}``: the plane's pair shifted to ``k``, zero before it). The most likely change
maximises ``E``; it is accepted when

* ``E / sigma_e^2 >= threshold`` (the likelihood ratio of "an unbalance appeared" against
  "noise only", ``sigma_e^2`` the innovation's variance per value, measured over the quiet
  periods), and
* the residual ``(||e||^2 - E) / (2 N n_s sigma_e^2) <= max_residual`` (what is left is
  noise: a contact, a sensor offset or a controller step is not an unbalance and is left to
  the feedback law and the fault monitor), or, for a large change, what is left is a small
  part of the innovation, ``(||e||^2 - E) <= max_unexplained ||e||^2``: a model a fraction of
  a percent off the plant (the speed between two models of a bank) leaves a residual that grows
  with the change, many times the noise for a large one, however well the unbalance explains it
  (the 430 g cm loss with the plant 10 % slower than the scenario, the nearest model 0.4 % off:
  likelihood ratio 1.0e8, residual 3.76 noise variances, 4e-5 of the innovation).

A change that passes the first test but not the second, with its best onset in the newest
period, is tested once more a period later, the window moved on by one period, instead of
ending the quiet history: a loss in a period's last samples gives the window a few samples of
response, which the fit may not yet tell from model error (the 430 g cm loss at the first
critical speed with the plant 5 % slower than its exact model: likelihood ratio 5712,
residual 1.57, and no decision, as the history was then restarted and the test re-armed
only eight periods later).

The magnitude ``me = ||theta||`` and the plane are reported (:attr:`EarlyAction.detections`).

The force
---------
The first sample a command made now can reach is ``k0 = (m + i) N`` (delay ``i``,
``ARCHITECTURE.md`` "Time"). The estimated change's response from ``k0`` on is
``y_d = A_{p,k} theta`` continued; the added force is

* a steady 1 x force at the bearings, forward whirl at both (4 real weights ``w``), that
  cancels ``y_d`` in the least-squares sense at the objective sensors (the feedback sensors)
  over the horizon's last two revolutions (the unbalance's steady response), applied in every
  period from ``k0`` on::

      w = -c (C_t^T C_t)^-1 C_t^T y_d[tail],                                           (E2)

* and, over the first ``M`` samples from ``k0``, the force ``df`` that damps what the change
  excited before ``k0`` (the transient that no steady force removes), smooth, and joining the
  steady force without a jump::

      df = argmin ||H_M df + y_d + C w / c||^2 + (lambda ||H_M||)^2 ||df||^2
                  + (mu ||H_M||)^2 ||D df + s||^2                                       (E3)

  (``H_M``: the bearing Markov parameters as a block Toeplitz matrix from ``M`` force samples
  to the ``L``-sample horizon at the objective sensors; ``D``: first differences per axis
  from zero before ``k0`` to zero after ``M`` samples; ``s``: the steady force's own steps
  over those samples, its switch-on at ``k0`` the first; ``lambda`` = ``transient_weight``,
  ``mu`` = ``transient_smoothing``), then scaled by ``c`` too. ``c = 1 - m^2`` is the robust
  scale for a force path off by up to ``m`` = ``gain_margin`` (:class:`EarlyActionConfig`).

The amplifiers bound how fast a bearing's force can change (eq. 2.42: ``K_i (V - R I) / L``,
:attr:`amb_common.rig.AmbData.force_slew_rate`, 7.15e5 N/s for Table 2.2's coils). A plan
whose largest step per sample, steady and transient force together from zero before ``k0``,
exceeds ``slew_budget`` of that slew over one sample is made again with the next smoothing of a
ladder (``mu`` = ``transient_smoothing``, then 0.25, 0.5, .., 16 above it), the least smooth
that keeps within it; if even the smoothest does not, the whole plan (steady and transient) is
scaled down until it does::

    max_n |f[n] - f[n - 1]| <= slew_budget x slew_rate x 2 pi / (omega N)               (E4)

The rest of the slew is left for the PID loop and the feedback law (their forces change by a
few 1e4 N/s at the vibration levels of the suite). The ladder costs one ``(4 M)^2`` product
per try; each smoothing's matrix is computed once.

The feedback law
----------------
A decision at the end of period ``m`` acts from ``m + i``; the feedback law's commands made at
the ends of periods ``m .. m + i - 1`` are computed from measurements that hold the change but
not yet the plan's effect, so they cancel the same change a second time. With ``hold_law`` the
controller pipeline replaces them by the law's command made before the change's onset (and
tells the law so: it records what was applied). At ``i >= 2`` it also holds the commands made
from the periods of the plan's transient force (``M`` samples): the law reads a step
disturbance into them, and its answer lands ``i`` periods later, when the transient has gone;
at ``i = 1`` it lands in the next period, where the law trims what the plan missed. Measured
(``mass_loss_1st``, docs/controller_notes.md): at i = 2, amb-compare's gain and phase cases
stay at the floor the fault's own period sets (82.6 um; with the force paths 30 % off, unheld,
the law and the plan over-acted in the same period: 118.6 um, the law alone 112.1); holding
only the first ``i`` commands at i = 2 left a 22-24 um bump two periods after the plan, which
the fault monitor in the loop called a contact in 5 of 5 first-critical runs; holding through
the transient at i = 1 raised the nominal peak from 10.2 to 11.3 um and the gain cases by a
quarter.

(E1)-(E4) are matrix products with matrices computed once from the model (:meth:`EarlyAction
.__init__`; the plan's in :class:`amb_controller.early_plan.PlanMaker`): the test costs one
product of ``(planes 2N 2) x (2N n_s)`` per period. After a detection the reference is formed
again from the periods after it (``arm_periods`` quiet periods), so a second loss is estimated
on top of the first and added to the plan. The feedback law keeps running: it sees the rotor
with the change cancelled and trims what the estimate missed.

What it does not do: it acts on a sudden unbalance only (a mass loss, eq. 3.3, or a synchronous
force through an AMB, the thesis's test disturbance of section 8.5.2: the same rotating force
at the bearing's node, a plane of the model with ``me = F / Omega^2``), and it needs
the sample-domain model above (the FE route: :func:`amb_apps.plant_models.early_action_model`;
on a rig the bearing part can be identified as the coefficient model is, section 6.4, with the
step response taken per sample, and the plane part by trial masses).
"""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass

import numpy as np

from amb_controller.early_config import EarlyActionConfig
from amb_controller.early_model import EarlyActionModel
from amb_controller.early_plan import Plan, PlanMaker, block_toeplitz, periodic
from amb_controller.errors import ControllerValueError, ShapeError

__all__ = ["Detection", "EarlyAction", "EarlyActionConfig"]


@dataclass(frozen=True)
class Detection:
    """
    One accepted change: period of the decision, onset sample, plane, unbalance.

    Also the plan's smoothing ``mu`` and its largest step per sample, N, after (E4), its
    largest predicted displacement ``predicted_peak`` (m, any sensor) and ``clearance_share``,
    the largest over the sensors of the predicted displacement, raised by ``1 + gain_margin``,
    over that sensor's clearance: the plan is applied (``acted``) if it is at most 1.
    """

    period: int
    onset_sample: int
    plane: str
    me: float
    angle: float
    likelihood_ratio: float
    residual: float
    first_period: int
    acted: bool = True
    predicted_peak: float = 0.0
    clearance_share: float = 0.0
    smoothing: float = 0.0
    largest_step: float = 0.0


class EarlyAction:
    """
    Streaming detector and canceller of sudden unbalance changes (module docstring).

    Feed it every period's displacements at the model's sensors and the wavelet force applied
    in that period (:meth:`end_period`); add :meth:`force` of a period to the command for it.

    Parameters
    ----------
    model : EarlyActionModel
    config : EarlyActionConfig
    delay : int
        The controller's delay ``i`` >= 1: a decision at the end of period ``m`` acts from
        period ``m + i``.
    force_limit : float
        Per-axis limit of the wavelet force, N (with ``config.force_budget``); the attribute
        of that name may be changed between periods (a run-time parameter change).

    Notes
    -----
    A plan is applied only if the displacement it predicts at every sensor (the reference
    periods' measured motion, periodic, plus the planned residual change, sample by sample),
    raised by ``1 + gain_margin``, stays inside that sensor's ``clearance`` in the model (the
    nearest clearance bearing's: on the Bath rig 0.9 mm by the retainers at the shaft's ends,
    0.75 mm at the inner probes by the auxiliary bearings). Beyond it contacts
    and the magnets' nonlinearity, which the linear model does not hold, decide the motion,
    and the change is left to the feedback law (the 430 g cm losses at 29 and 67 Hz of the
    fault suite: predicted 926-1141 um; acted on anyway, the rotor is on its bearings as
    with the law alone). The measured motion, not the reference ``z``: under a feedback law
    that cancels a steady unbalance ``z`` is the uncontrolled response (``docs/
    controller_notes.md``, "The clearance check on the measured motion").
    """

    def __init__(
        self,
        model: EarlyActionModel,
        config: EarlyActionConfig,
        delay: int,
        force_limit: float = math.inf,
    ) -> None:
        if int(delay) < 1:
            raise ControllerValueError(f"delay must be >= 1, got {delay}")
        self.model = model
        self.config = config
        self.delay = int(delay)
        self.force_limit = float(force_limit)
        # the plan's linear prediction, with the model's relative error, inside each sensor's
        # clearance, (n_s,) m
        self.safe_displacement = np.array(model.clearance) / (1.0 + config.gain_margin)
        N = model.samples_per_rev
        self.N = N
        h = model.bearing_markov
        L = min(config.horizon_periods * N, h.shape[0])
        g = model.plane_responses
        if g.shape[1] < L + 2 * N:
            raise ShapeError(f"plane_responses need {L + 2 * N} samples, have {g.shape[1]}")
        self.L = L
        n_s = h.shape[1]
        self.n_s = n_s
        # z = y - sum_j T_j f[m - j]: T_j maps period m - j's force to period m's outputs
        n_hist = math.ceil(h.shape[0] / N) + 1
        full = block_toeplitz(h, n_hist * N, n_hist * N)
        # [T_0 T_1 .. T_J] in one float32 matrix (the products are memory-bound: 7 MB of
        # float64 at 64 samples per revolution; float32's 1e-7 is far below the noise)
        self._n_hist = n_hist
        self._t = np.hstack(
            [
                full[(n_hist - 1) * N * n_s :, (n_hist - 1 - j) * N * 4 : (n_hist - j) * N * 4]
                for j in range(n_hist)
            ]
        ).astype(np.float32)
        # (E1): every plane p and onset k of the 2 N-sample window
        W = 2 * N
        rows, grams = [], []
        for p in range(g.shape[0]):
            for k in range(W):
                a = np.zeros((W, n_s, 2))
                a[k:] = g[p, : W - k]
                a = a.reshape(W * n_s, 2)
                # pinv: onsets at the window's end see (almost) nothing of the change
                rows.append(np.linalg.pinv(a, rcond=1e-9))
                grams.append(a.T @ a)
        self._q = np.concatenate(rows).astype(np.float32)  # (planes W 2, W n_s)
        self._gram = np.array(grams).reshape(g.shape[0], W, 2, 2)
        # (E2)-(E4): the force against an estimated change
        self._maker = PlanMaker(model, config, L)
        self.M = self._maker.M
        self.step_limit = self._maker.step_limit
        self.last_smoothing = self.last_step = 0.0  # of the last plan (its Detection's too)
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget the history, the plan and the detections (e.g. after a gap or a restart)."""
        n_hist = self._n_hist
        self._forces: deque[np.ndarray] = deque([np.zeros(self.N * 4)] * n_hist, maxlen=n_hist)
        # the newest periods: reference ``z`` (N n_s,) and measured displacement (N, n_s), m
        # (the test reads the first, the clearance check the second)
        self._periods: deque[tuple[np.ndarray, np.ndarray]] = deque(
            maxlen=self.config.reference_periods + 2
        )
        self._quiet = 0
        self._history_periods = 0
        self._noise2: float | None = None
        self._quiet_values: deque[float] = deque(maxlen=16)
        self._plans: list[tuple[int, Plan]] = []
        self.detections: list[Detection] = []
        self._deferred = False  # the last test was put off by a period (module notes)

    @property
    def armed(self) -> bool:
        """Whether the test runs at the next period's end."""
        return self._quiet >= self.config.arm_periods and self._noise2 is not None

    # ------------------------------------------------------------------ per period
    def force(self, period: int) -> np.ndarray:
        """The added force for ``period``, shape ``(N, 4)`` [b1x, b1y, b2x, b2y], N."""
        out = np.zeros((self.N, 4))
        for first, plan in self._plans:
            if period >= first:
                out += plan.steady
                out += plan.transient.get(period, 0.0)
        return out

    def end_period(self, period: int, displacement, applied_force) -> Detection | None:
        """
        Take period ``period``'s displacements and applied wavelet force; test.

        Parameters
        ----------
        period : int
            Consecutive period index (a gap: call :meth:`reset` first).
        displacement : array_like
            Shape ``(N, n_s)``, m: the model's sensors (``model.sensors``).
        applied_force : array_like
            Shape ``(N, 4)``, N: the wavelet force the plant applied in the period (all of
            it: feedback, this module's and limits).

        Returns
        -------
        Detection or None
            A change accepted at this period's end (its force acts from ``period + delay``).
        """
        N, n_s = self.N, self.n_s
        y = np.asarray(displacement, dtype=float)
        f = np.asarray(applied_force, dtype=float)
        if y.shape != (N, n_s) or f.shape != (N, 4):
            raise ShapeError(f"need displacement ({N}, {n_s}) and force ({N}, 4)")
        self._forces.appendleft(f.ravel())
        applied = np.concatenate(self._forces).astype(np.float32)
        z = y.ravel() - (self._t @ applied).astype(float)
        self._periods.append((z, y.copy()))
        self._history_periods += 1
        R = self.config.reference_periods
        if len(self._periods) < R + 2 or self._history_periods < self._n_hist:
            return None
        zs = [z for z, _ in self._periods]
        ref = np.mean(zs[:R], axis=0)
        if not self.armed:
            self._update_quiet(zs, ref)
            return None
        e = np.concatenate([zs[R] - ref, zs[R + 1] - ref])
        energy = float(e @ e)
        theta = (self._q @ e.astype(np.float32)).astype(float).reshape(-1, 2 * N, 2)
        g, t0, t1 = self._gram, theta[..., 0], theta[..., 1]  # E of (E1): theta^T G theta
        explained = t0 * (g[..., 0, 0] * t0 + g[..., 0, 1] * t1) + t1 * (
            g[..., 1, 0] * t0 + g[..., 1, 1] * t1
        )
        p, k = np.unravel_index(int(np.argmax(explained)), explained.shape)
        best = float(explained[p, k])
        lr = best / self._noise2
        residual = (energy - best) / (e.size * self._noise2)
        fits = residual <= self.config.max_residual or (
            energy - best <= self.config.max_unexplained * energy
        )
        if lr < self.config.threshold or not fits:
            if lr >= self.config.threshold and k >= N and not self._deferred:
                self._deferred = True  # too young to fit: once more next period (notes)
                return None
            self._deferred = False
            self._update_quiet(zs, ref)
            return None
        self._deferred = False
        th = theta[p, k]
        first = period + self.delay
        plan, planned, effect = self._plan(p, k, th, period, first)
        if effect < self.config.min_effect * math.sqrt(self._noise2):
            self._update_quiet(zs, ref)
            return None
        # on top of what the rotor does now, the feedback law's force included (held by the
        # pipeline while the plan acts, ``hold_law``), not of ``ref``: ``z`` has the law's
        # force taken out; k0 starts a period, so the periodic motion lines up sample by sample
        now = np.mean([y for _, y in list(self._periods)[:R]], axis=0)
        peaks = np.max(np.abs(planned + periodic(now, self.L)), axis=0)  # (n_s,)
        share = float(np.max(peaks / self.safe_displacement))
        acted = share <= 1.0
        if acted:
            self._plans.append((first, plan))
        onset = (period - 1) * N + int(k)
        det = Detection(
            period=period,
            onset_sample=onset,
            plane=self.model.planes[p],
            me=float(math.hypot(*th)),
            angle=float(math.atan2(th[1], th[0])),
            likelihood_ratio=float(lr),
            residual=float(residual),
            first_period=first,
            acted=acted,
            predicted_peak=float(np.max(peaks)),
            clearance_share=share,
            smoothing=self.last_smoothing,
            largest_step=self.last_step,
        )
        self.detections.append(det)
        self._quiet = 0  # a new reference after the change
        self._periods.clear()
        return det

    def _update_quiet(self, zs: list[np.ndarray], ref: np.ndarray) -> None:
        """Count the newest period quiet when it is noise about the reference; learn sigma_e."""
        newest = zs[-1] - ref
        per_value = float(newest @ newest) / newest.size
        if self._noise2 is None or per_value <= 4.0 * self._noise2:
            self._quiet += 1
            # the median of the last quiet periods' innovation variance (measured, robust
            # to a period of start-up transient taken for quiet)
            self._quiet_values.append(per_value)
            self._noise2 = max(self.config.min_noise**2, float(np.median(self._quiet_values)))
        else:
            self._quiet = 0
            self._periods.clear()

    def _plan(
        self, p: int, k: int, theta: np.ndarray, period: int, first: int
    ) -> tuple[Plan, np.ndarray, float]:
        """(E2)-(E4) for the change at window sample ``k`` in plane ``p``.

        Returns the plan, the planned residual from ``k0`` on (``(L, n_s)``) and the change's
        own predicted peak from ``k0`` on, m.
        """
        N, L = self.N, self.L
        g = self.model.plane_responses[p]
        # window starts at period - 1; k0 = first * N; offset of k0 from the onset:
        off = (first - period + 1) * N - int(k)
        yd = (g[off : off + L] @ theta).ravel()  # (L n_s,)
        plan, residual = self._maker.make(yd, first, self.force_limit)
        self.last_smoothing, self.last_step = plan.smoothing, plan.largest_step
        return plan, residual, float(np.max(np.abs(yd)))
