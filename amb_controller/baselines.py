"""
Baseline controllers a rotordynamics user would pick instead of the wavelet controller.

Both act once per revolution on the 1 x Fourier coefficients of the measured sensors (the
same inner sensors ``B^(m)`` as the wavelet controller), apply a sinusoidal 1 x force per
bearing axis through the same :class:`~amb_controller.synthesis.ForceLimiter` (same per-axis
peak force limit) and the same :class:`~amb_controller.supervisor.WaveletControlSupervisor`
(delay ``i``, anti-windup hold, fault actions), so that only the control law differs.

This module holds the baselines' settings (:class:`BaselineSettings`), their models
(:func:`fourier_model`, :func:`perturb_model`) and :class:`HarmonicPipeline`, which runs either
law. The 1 x Fourier bases and the complex <-> real (cos, sin) layout are in
:mod:`amb_controller.fourier_basis`.

(a) Adaptive open-loop synchronous control (``controller = "synchronous"``)
---------------------------------------------------------------------------
Influence-coefficient control, eq. B.1:
:class:`~amb_controller.influence_coefficient.InfluenceCoefficientController` (the law, what it
rests on, what could not be checked and its references are in that module).

(b) Sampled-harmonic transient control (``controller = "harmonic"``)
--------------------------------------------------------------------
Keogh, Cole & Burrows [3]_: the plant's transient dynamics in the sampled harmonic
coefficients, ``Q(z) = G_h(z) U(z) + D(z)``, a truncated (pseudo-)inverse of ``G_h`` and the
prescribed closed-loop decay ``alpha(z)`` of a step disturbance::

    U(z) = -z^-i G_h^*(z) (1 / (alpha(z)(z - 1)) - 1) Q(z)                      (B.2)

which is the thesis's eq. 8.10 (with eq. 8.1, ``U = -L Q``) with the Haar coefficients
replaced by the 1 x Fourier ones. It is realised with
:class:`~amb_controller.transient.TransientController` on the Markov parameters of ``G_h``
(:func:`~amb_apps.plant_models.harmonic_model`, exact sampled projection of the FE
model's PID closed loop, :func:`~amb_controller.wavelet_dynamics.wavelet_markov`).

What eq. B.2 rests on, and what could not be checked: the thesis's own account of [3]
(section 8.1): "a multi-state transient controller evaluated from sampled harmonics ...
essentially a steady state controller embedded with transient system dynamics ...
further enhanced through a prescribed transient response dictating the desired system
behaviour to step changes in disturbance", and its statement that chapter 8 is the
wavelet version of it; eq. B.2 is therefore eq. 8.3-8.10 on harmonic coefficients. The
text of [3] was not available (searched: stored web pages, documentation, code): its
exact model form, which harmonics it samples (here 1 x only) and its inverse are not
checked.

References
----------
[3]: as cited by the thesis (its bibliography is not in the text available here), volume and
pages not verified.

.. [3] P. S. Keogh, M. O. T. Cole, C. R. Burrows, "Multi-state transient rotor vibration
   control using sampled harmonics", ASME J. Vib. Acoust. 124(2) (2002) 186-197.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from amb_common.names import N_SENSORS
from amb_controller.command_ledger import MISSING, RESUMED, MissingFlags
from amb_controller.errors import ControllerValueError
from amb_controller.fourier_basis import (
    complex_gain,
    fourier_control_basis,
    fourier_measurement_basis,
)
from amb_controller.influence_coefficient import InfluenceCoefficientController
from amb_controller.inverse import dc_gain, pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.selection import controller_guard, prescribed_response
from amb_controller.stability import own_model_radius
from amb_controller.status import status_fields
from amb_controller.supervisor import Command, Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

__all__ = [
    "BASELINES",
    "BaselineSettings",
    "HarmonicPipeline",
    "fourier_model",
    "perturb_model",
]

BASELINES = ("synchronous", "harmonic")


@dataclass(frozen=True)
class BaselineSettings:
    """
    Settings of the baselines not in :class:`~amb_controller.config.ControllerConfig`.

    Attributes
    ----------
    window : int
        Periods per update of the synchronous controller (eq. B.1), >= 1.
    rho : float
        Relative step weight ``R = rho ||T||_F^2 / n_u I`` of eq. B.1, >= 0 (shapes the
        update direction; does not change its fixed point,
        :mod:`amb_controller.influence_coefficient`).
    trial_force : float
        Amplitude of the 1 x trial force per axis in N for
        :func:`~amb_apps.plant_models.influence_by_trials`.
    trial_settle : int
        Periods waited after each trial change before averaging.
    trial_average : int
        Periods averaged per trial.

    """

    window: int = 2
    rho: float = 0.0
    trial_force: float = 50.0
    trial_settle: int = 30
    trial_average: int = 20

    def __post_init__(self) -> None:
        if int(self.window) != self.window or self.window < 1:
            raise ControllerValueError(f"window must be an integer >= 1 period, got {self.window}")
        if not (math.isfinite(self.rho) and self.rho >= 0):
            raise ControllerValueError(f"rho must be finite and >= 0, got {self.rho}")
        if not (math.isfinite(self.trial_force) and self.trial_force > 0):
            raise ControllerValueError(f"trial_force must be > 0 N, got {self.trial_force}")
        if self.trial_settle < 1 or self.trial_average < 1:
            raise ControllerValueError(
                f"trial_settle and trial_average must be >= 1 period, got "
                f"{self.trial_settle}, {self.trial_average}"
            )


# ---------------------------------------------------------------------------------------------
# models
# ---------------------------------------------------------------------------------------------


def fourier_model(markov, config, omega, source, cb, mb) -> WaveletModel:
    """
    The baselines' model: Fourier-basis Markov series ``markov`` with its least-squares inverse.

    Parameters
    ----------
    markov : numpy.ndarray
        (K, n_y, n_u) Markov parameters in the bases ``mb`` (measured) and ``cb`` (control).
    config : ControllerConfig
        ``period_samples``, ``inverse_order``, ``inverse_regularisation``, ``delay_periods``.
    omega : float
        Running speed, rad/s.
    source : str
        How the series was obtained (``fe-harmonic``, ``trial-injection``).
    cb, mb : BasisSet
        Control and measurement bases (:func:`fourier_control_basis`,
        :func:`fourier_measurement_basis`).

    Returns
    -------
    WaveletModel
        ``wavelet = "fourier"``.
    """
    inverse = pseudo_inverse_series(
        markov, config.inverse_order, regularisation=config.inverse_regularisation
    )
    return WaveletModel(
        markov=markov,
        inverse=inverse,
        wavelet="fourier",
        samples_per_rev=config.period_samples,
        omega=float(omega),
        levels=(1,),
        quadratures=("cos", "sin"),
        delay=config.delay_periods,
        source=source,
        control_labels=cb.labels,
        measured_labels=mb.labels,
    )


def perturb_model(
    model: WaveletModel, gain: float = 1.0, phase: float = 0.0, inverse_order: int | None = None
) -> WaveletModel:
    """
    Return ``model`` with a gain and phase error on every measured quadrature pair.

    For each measured pair (Haar ``even``/``odd`` or Fourier ``cos``/``sin`` of one level,
    translation and sensor) the phasor ``Y = q_even - i q_odd`` of every Markov parameter
    becomes ``gain e^{i phase} Y``::

        q_even' = gain (cos(phase) q_even + sin(phase) q_odd)
        q_odd'  = gain (-sin(phase) q_even + cos(phase) q_odd)

    i.e. the model's response to every control coefficient is scaled and rotated in
    phase (a model error a user meets: calibration gain, sensor or amplifier phase lag).
    The inverse is recomputed from the perturbed Markov parameters.

    Parameters
    ----------
    model : WaveletModel
    gain : float
        Gain factor (> 0), e.g. 1.3 for +30 %.
    phase : float
        Phase error in rad.
    inverse_order : int, optional
        Inverse truncation order (default: the model's).

    Returns
    -------
    WaveletModel
        ``source`` tagged with the perturbation.

    """
    if not (math.isfinite(gain) and gain > 0 and math.isfinite(phase)):
        raise ControllerValueError(f"gain must be > 0 and phase finite, got {gain}, {phase}")
    labels = list(model.measured_labels)
    if not labels:
        raise ControllerValueError("model has no measured labels: cannot pair quadratures")
    pairs = []
    for i, lab in enumerate(labels):
        for a, b in (("/even/", "/odd/"), ("/cos/", "/sin/")):
            if a in lab:
                pairs.append((i, labels.index(lab.replace(a, b))))
    c, s = math.cos(phase), math.sin(phase)
    markov = model.markov.copy()
    e = np.array([p[0] for p in pairs])
    o = np.array([p[1] for p in pairs])
    markov[:, e] = gain * (c * model.markov[:, e] + s * model.markov[:, o])
    markov[:, o] = gain * (-s * model.markov[:, e] + c * model.markov[:, o])
    order = model.inverse.shape[0] - 1 if inverse_order is None else int(inverse_order)
    inverse = pseudo_inverse_series(markov, order)
    return replace(
        model,
        markov=markov,
        inverse=inverse,
        source=f"{model.source} x{gain:g} {math.degrees(phase):+g}deg",
    )


# ---------------------------------------------------------------------------------------------
# pipeline (same interface as ControllerPipeline, as the closed loop and the node use it)
# ---------------------------------------------------------------------------------------------


class HarmonicPipeline:
    """
    Samples in, one command per period out, for the 1 x Fourier baselines.

    Same contract as :class:`~amb_controller.pipeline.ControllerPipeline` (``on_sample``,
    ``on_fault``, ``set_mode``, ``status``, ``reset``): the measured vector of period m is
    the 1 x Fourier projection of its N displacement samples (the filterbank records are
    not used); a gap, a step back or a joined period gives a zero, ``hold`` command and
    resets the controller.

    Parameters
    ----------
    config : ControllerConfig
        ``controller`` in :data:`BASELINES`; delay, sensors, force limits, gain (eq. B.1),
        prescribed response (eq. B.2), guard and fault actions are used.
    capacity : float
        Bearing capacity in N.
    model : WaveletModel
        From :mod:`amb_apps.plant_models`: ``harmonic_model`` (harmonic), or
        ``influence_by_trials`` / ``harmonic_model`` (synchronous: its steady-state gain is
        used).
    settings : BaselineSettings, optional
    probe_clearance : tuple of float, optional
        As for :class:`~amb_controller.pipeline.ControllerPipeline` (the contact guard).

    """

    def __init__(
        self,
        config,
        capacity: float,
        model: WaveletModel,
        settings=None,
        probe_clearance: tuple[float, ...] | None = None,
    ) -> None:
        if config.controller not in BASELINES:
            raise ControllerValueError(
                f"HarmonicPipeline runs {BASELINES}, got controller {config.controller!r}"
            )
        if model is None:
            raise ControllerValueError(
                "the baselines need a model: harmonic_model() or influence_by_trials()"
            )
        config.check_capacity(capacity)
        self.config = config
        self.settings = settings or BaselineSettings()
        n = config.period_samples
        self.samples_per_period = n
        self.control = fourier_control_basis(n)
        self.measured = fourier_measurement_basis(n, config.sensors)
        expected = (self.measured.n_coefficients, self.control.n_coefficients)
        if model.markov.shape[1:] != expected or model.wavelet != "fourier":
            raise ControllerValueError(
                f"model must be a Fourier model of shape (M+1, {expected[0]}, {expected[1]}), "
                f"got {model.wavelet!r} {model.markov.shape}; build it with harmonic_model() "
                "or influence_by_trials() for these sensors"
            )
        self.model = model
        self._weights = np.ascontiguousarray(self.measured.weights.transpose(0, 2, 1))
        self.limiter = ForceLimiter(self.control, np.array(config.force_limit), capacity)
        guard = controller_guard(config, probe_clearance)
        self.supervisor = WaveletControlSupervisor(
            self.limiter,
            config.delay_periods,
            guard=guard,
            fault_actions=config.fault_actions,
            max_radius=config.max_model_radius,
        )
        if config.controller == "harmonic":
            controller = TransientController(
                model.inverse, prescribed_response(config), config.delay_periods
            )
        else:
            controller = InfluenceCoefficientController(
                complex_gain(dc_gain(model.markov)),
                config.gain,
                config.delay_periods,
                self.settings.window,
                self.settings.rho,
            )
        # the harmonic controller's closed loop on its own 1 x model; None for the synchronous
        # one (open loop per window, eq. B.1: no realisation to close)
        self.supervisor.set_controller(controller, own_model_radius(model.markov, controller))
        self._buffer = np.zeros((n, N_SENSORS))
        self._flags = MissingFlags()  # the samples' STATUS_COMMAND_MISSING
        self._stats = {
            "commands_sent": 0,
            "commands_late": 0,
            "commands_partial": 0,
            "inputs_rejected": 0,
        }
        self._compute_time = 0.0
        self.reset()

    def reset(self) -> None:
        """OFF, guard re-armed, period assembly cleared (model kept)."""
        self.supervisor.reset()
        self._period: int | None = None
        self._expected: int | None = None
        self._ok = False
        self._peak = 0.0
        self._last_period = -1
        self._last_command: Command | None = None
        self.last_measured: np.ndarray | None = None

    def set_mode(self, mode) -> tuple[bool, str]:
        """Request OFF, ACTIVE or HOLD (as :meth:`ControllerPipeline.set_mode`)."""
        try:
            mode = Mode(int(mode))
        except ValueError:
            return False, f"unknown mode {mode}; expected 0..3"
        return self.supervisor.set_mode(mode)

    def on_fault(self, fault_type: int, status: str = "", revised: bool = False) -> str:
        """Apply the action for a FaultEvent (:meth:`WaveletControlSupervisor.on_fault`)."""
        return self.supervisor.on_fault(int(fault_type), status, revised)

    def on_sample(
        self, sample_index: int, records, displacement, omega=None, command_missing=False
    ) -> Command | None:
        """
        Feed one sample's displacements (8, m); return the command at a period's end.

        ``records`` (filterbank output) is accepted for interface compatibility and unused;
        ``command_missing`` is the sample's ``STATUS_COMMAND_MISSING`` (as
        :meth:`amb_controller.pipeline.ControllerPipeline.on_sample`).
        """
        n = int(sample_index)
        N = self.samples_per_period
        m, pos = divmod(n, N)
        if self._period != m:
            self._period = m
            self._ok = pos == 0
            self._peak = 0.0
        if self._expected is not None and n != self._expected:
            self._ok = False
        self._expected = n + 1
        flag = self._flags.observe(m, pos, command_missing)
        if flag == MISSING and self.supervisor.command_missing(m):
            self._stats["commands_late"] += 1
        elif flag == RESUMED and self.supervisor.command_resumed(m, pos):
            self._stats["commands_partial"] += 1  # applied from sample pos (partial_commands)
        x = np.asarray(displacement, dtype=float)
        if x.shape != (N_SENSORS,) or not np.all(np.isfinite(x)):
            self._stats["inputs_rejected"] += 1
            self._ok = False
        else:
            self._buffer[pos] = x
            self._peak = np.maximum(self._peak, np.abs(x))  # per probe (the contact guard)
        if pos != N - 1:
            return None
        return self._end_period(m)

    def _end_period(self, m: int) -> Command:
        t0 = time.perf_counter()
        sup = self.supervisor
        complete = self._ok and (self._last_period < 0 or self._last_period == m - 1)
        if complete:
            q = np.einsum("inc,nc->i", self._weights, self._buffer)
            self.last_measured = q
            command = sup.step(m, q, self._peak)
        else:
            self.last_measured = None
            sup.reset_controller()
            zeros = np.zeros(self.control.n_coefficients)
            result = self.limiter.apply(zeros)
            sup.record_zero(m + sup.delay)
            command = Command(
                m + sup.delay, m, zeros, result.force, sup.mode, True, result.saturated,
                bool(sup.guard is not None and sup.guard.tripped), f"period {m} incomplete",
            )  # fmt: skip
        self._last_period = m
        self._last_command = command
        self._stats["commands_sent"] += 1
        self._compute_time = time.perf_counter() - t0
        self._period = None
        return command

    def status(self) -> dict:
        """Return the ``ControllerStatus`` fields (as :meth:`ControllerPipeline.status`)."""
        return status_fields(self, 1.0, "")
