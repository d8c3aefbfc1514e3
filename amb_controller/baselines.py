"""
Baseline controllers a rotordynamics user would pick instead of the wavelet controller.

Both act once per revolution on the 1 x Fourier coefficients of the measured sensors (the
same inner sensors ``B^(m)`` as the wavelet controller), apply a sinusoidal 1 x force per
bearing axis through the same :class:`~amb_controller.synthesis.ForceLimiter` (same per-axis
peak force limit) and the same :class:`~amb_controller.supervisor.WaveletControlSupervisor`
(delay ``i``, anti-windup hold, fault actions), so that only the control law differs.

Fourier basis (sampled harmonics)
---------------------------------
Over control period k (samples ``n = 0 .. N-1`` of the period, ``theta_n = 2 pi n / N``)::

    q_cos = sqrt(2/N) sum_n x[n] cos(theta_n),   q_sin = sqrt(2/N) sum_n x[n] sin(theta_n)
    f[n]  = sqrt(2/N) (u_cos cos(theta_n) + u_sin sin(theta_n))

The weights are orthonormal over the period, so the coefficient units are those of the
Haar coefficients (m sqrt(samples), N sqrt(samples)); a sinusoid of amplitude ``F`` N has
``|u| = F sqrt(N/2)``. The Haar square wave of the same peak force carries ``4/pi`` (1.27)
times more 1 x force: at equal peak limits the wavelet controller has this advantage, which
the comparison report states.

Complex form: ``Y = q_cos - i q_sin`` so that ``x[n] = sqrt(2/N) Re(Y e^{i theta_n})``; for a
linear time-invariant plant the steady-state map ``Y = T U`` is complex, and the real
``(cos, sin)`` block matrix is ``[[Tr, Ti], [-Ti, Tr]]`` (``T = Tr + i Ti``).

(a) Adaptive open-loop synchronous control (``controller = "synchronous"``)
---------------------------------------------------------------------------
Influence-coefficient control of Burrows & Sahinkaya [1]_ as used on magnetic bearings by
Knospe et al. [2]_: a 1 x force, open loop with respect to the fast dynamics, updated once
per window of ``window`` periods from the window mean ``Y_j``::

    U_{j+1} = U_j - a (T^H T + R)^-1 T^H Y_j                                    (B.1)

with ``T`` the steady-state influence coefficients (complex, sensors x axes) identified by trial
injections (:func:`~amb_apps.plant_models.influence_by_trials`: each axis in turn driven
with a known 1 x force, the change of the steady 1 x response measured), ``a`` the convergence
gain (``ControllerConfig.gain``) and ``R = rho ||T||_F^2 / n_u I``. On a plant ``Y = T_p U + D``
the update error obeys ``E_{j+1} = (I - a (T^H T + R)^-1 T^H T_p) E_j``: it converges iff that
matrix has spectral radius < 1 (with ``T = T_p``, ``R = 0``: ``|1 - a| < 1``, one update cancels
a steady disturbance at ``a = 1``). ``R`` only shapes the step: the fixed point is ``T^H Y = 0``
(the least-squares cancelling force) whatever ``rho``; it is NOT the control-effort penalty of a
weighted least-squares cost ``Y^H Y + U^H R U`` (whose recursive form adds ``R U_j`` inside the
bracket and leaves a residual), which is the version Dyer et al. [4]_ recommend for robustness.
Both facts are tested (``test/beyond/test_baselines.py``).

What eq. B.1 rests on, and what could not be checked
~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~~
* The thesis (section 1.1; chapter 9) describes [1] as "an open-loop
  technique to eliminate synchronous vibration" and Knospe et al. as "adaptive open-loop
  control methods updating control currents on a cyclic basis": a 1 x force updated once
  per cycle (window) from the measured 1 x response, as here.
* The abstract of [2] (the stored copy reachable here had the abstract only, not the
  equations) names three algorithms of this "adaptive open loop" class: a non-recursive
  law with simultaneous estimation, a recursive law with simultaneous estimation, and a
  recursive law with gain scheduling by speed. Eq. B.1 is a recursive law with ``T``
  identified beforehand by trial injections (no simultaneous estimation; one speed, so
  no schedule): the third algorithm at one speed is the closest; the first two, which
  re-estimate ``T`` on line, are not implemented.
* The least-squares direction ``(T^H T)^-1 T^H`` for more sensors than axes and the
  trial-injection identification are the standard influence-coefficient method (the
  abstract of [4] calls the traditional law "weighted least squares optimal control").
* Not checked: the exact equations, symbols and gain ranges of [1] and [2] (neither text
  was available); eq. B.1 is the form the issue specifies, derived here, not copied.

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
[2]: journal, volume and pages confirmed by its stored abstract; [4]: title, authors and DOI
confirmed by its stored first page; [1] and [3]: as cited by the thesis (its bibliography is
not in the text available here), volume and pages not verified.

.. [1] C. R. Burrows, M. N. Sahinkaya, "Vibration control of multi-mode rotor-bearing
   systems", Proc. R. Soc. Lond. A 386 (1983) 77-94.
.. [2] C. R. Knospe, R. W. Hope, S. J. Fedigan, R. D. Williams, "Experiments in the control
   of unbalance response using magnetic bearings", Mechatronics 5(4) (1995) 385-400.
.. [3] P. S. Keogh, M. O. T. Cole, C. R. Burrows, "Multi-state transient rotor vibration
   control using sampled harmonics", ASME J. Vib. Acoust. 124(2) (2002) 186-197.
.. [4] S. W. Dyer, J. Ni, J. Shi, K.-K. Shin, "Robust optimal influence-coefficient
   control of multiple-plane active rotor balancing systems", ASME J. Dyn. Syst. Meas.
   Control 124 (2002), doi:10.1115/1.1435622 (abstract read).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, replace

import numpy as np

from amb_common.names import N_AXES, N_SENSORS
from amb_controller.basis import BasisSet
from amb_controller.errors import ControllerValueError, PeriodSequenceError
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.inverse import dc_gain, pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.pipeline import prescribed_response
from amb_controller.status import status_fields
from amb_controller.supervisor import Command, Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import ControlStep, TransientController

__all__ = [
    "BASELINES",
    "BaselineSettings",
    "HarmonicPipeline",
    "InfluenceCoefficientController",
    "complex_from_real",
    "fourier_control_basis",
    "fourier_measurement_basis",
    "fourier_model",
    "perturb_model",
    "real_from_complex",
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
        update direction; does not change its fixed point, module docstring).
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
# Fourier bases and the complex <-> real (cos, sin) layout
# ---------------------------------------------------------------------------------------------


def _harmonic(samples_per_rev: int) -> tuple[np.ndarray, np.ndarray]:
    theta = 2 * np.pi * np.arange(samples_per_rev) / samples_per_rev
    scale = math.sqrt(2.0 / samples_per_rev)
    return scale * np.cos(theta), scale * np.sin(theta)


def fourier_control_basis(samples_per_rev: int, n_axes: int = N_AXES) -> BasisSet:
    """
    Return the 1 x force waveforms ``sqrt(2/N) cos``, ``sqrt(2/N) sin`` per axis.

    Parameters
    ----------
    samples_per_rev : int
        Samples per period N.
    n_axes : int
        Bearing axes.

    Returns
    -------
    BasisSet
        ``2 n_axes`` coefficients, cos block then sin block (labels ``h1/cos/c{axis}``),
        ``offset = 0``; N per N sqrt(samples).

    """
    cos, sin = _harmonic(samples_per_rev)
    weights = np.zeros((2 * n_axes, n_axes, samples_per_rev))
    labels = []
    for b, (name, wave) in enumerate((("cos", cos), ("sin", sin))):
        for axis in range(n_axes):
            weights[b * n_axes + axis, axis] = wave
            labels.append(f"h1/{name}/c{axis}")
    return BasisSet(weights, 0, tuple(labels))


def fourier_measurement_basis(samples_per_rev: int, sensors) -> BasisSet:
    """
    Return the 1 x analysis weights of the measured sensors (same layout as the control).

    Parameters
    ----------
    samples_per_rev : int
        Samples per period N.
    sensors : sequence of int
        Sensor channels 0..7 ([x1, y1, ..., x4, y4]) measured.

    Returns
    -------
    BasisSet
        ``2 len(sensors)`` coefficients over the 8 channels, cos block then sin block,
        ``offset = 0`` (the window is the period itself).

    """
    cos, sin = _harmonic(samples_per_rev)
    sensors = [int(s) for s in sensors]
    weights = np.zeros((2 * len(sensors), N_SENSORS, samples_per_rev))
    labels = []
    for b, (name, wave) in enumerate((("cos", cos), ("sin", sin))):
        for i, s in enumerate(sensors):
            weights[b * len(sensors) + i, s] = wave
            labels.append(f"h1/{name}/c{s}")
    return BasisSet(weights, 0, tuple(labels))


def complex_from_real(vector: np.ndarray) -> np.ndarray:
    """Return ``Y = q_cos - i q_sin`` from the real layout ``[q_cos..., q_sin...]``."""
    vector = np.asarray(vector, dtype=float)
    n = vector.shape[0] // 2
    return vector[:n] - 1j * vector[n:]


def real_from_complex(phasor: np.ndarray) -> np.ndarray:
    """Return the real layout ``[Re Y..., -Im Y...]`` of complex phasors (inverse of above)."""
    phasor = np.asarray(phasor, dtype=complex)
    return np.concatenate([phasor.real, -phasor.imag])


def complex_gain(real_gain: np.ndarray) -> np.ndarray:
    """
    Return the complex ``T`` of a real ``(cos, sin)`` block gain (module docstring).

    ``Tr = (M_cc + M_ss)/2``, ``Ti = (M_cs - M_sc)/2``: exact when the real gain has the
    complex structure (a linear time-invariant plant at one frequency), the closest
    complex map in the Frobenius norm otherwise.
    """
    m = np.asarray(real_gain, dtype=float)
    ny, nu = m.shape[0] // 2, m.shape[1] // 2
    cc, cs = m[:ny, :nu], m[:ny, nu:]
    sc, ss = m[ny:, :nu], m[ny:, nu:]
    return 0.5 * (cc + ss) + 0.5j * (cs - sc)


def real_gain(complex_t: np.ndarray) -> np.ndarray:
    """Return the real block gain ``[[Tr, Ti], [-Ti, Tr]]`` of a complex ``T``."""
    t = np.asarray(complex_t, dtype=complex)
    return np.block([[t.real, t.imag], [-t.imag, t.real]])


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
# controllers
# ---------------------------------------------------------------------------------------------


@dataclass
class _SyncState:
    u: np.ndarray
    acc: np.ndarray
    count: int
    last_period: int | None

    def copy(self) -> _SyncState:
        return _SyncState(self.u.copy(), self.acc.copy(), self.count, self.last_period)


class InfluenceCoefficientController:
    """
    Adaptive open-loop synchronous control, eq. B.1 (module docstring, refs [1], [2]).

    Parameters
    ----------
    influence : numpy.ndarray
        Complex steady-state influence coefficients ``T``, ``(n_sensors, n_axes)``, in
        measured coefficient per control coefficient (m/N).
    gain : float
        Convergence gain ``a`` in (0, 2).
    delay : int
        Evaluation delay ``i`` >= 1 (commands are for period ``k + i``).
    window : int
        Periods averaged per update.
    rho : float
        Relative step weight ``rho`` of ``R`` (eq. B.1).

    """

    def __init__(
        self, influence: np.ndarray, gain: float, delay: int, window: int = 1, rho: float = 0.0
    ) -> None:
        t = np.asarray(influence, dtype=complex)
        if t.ndim != 2 or not np.all(np.isfinite(t)):
            raise ControllerValueError(f"influence must be a finite 2-D matrix, got {t.shape}")
        if not (math.isfinite(gain) and 0 < gain < 2):
            raise ControllerValueError(f"gain a must lie in (0, 2), got {gain}")
        if int(delay) != delay or delay < 1:
            raise ControllerValueError(f"delay must be an integer >= 1 period, got {delay}")
        if int(window) != window or window < 1:
            raise ControllerValueError(f"window must be an integer >= 1, got {window}")
        self.influence = t
        self.gain = float(gain)
        self.delay = int(delay)
        self.window = int(window)
        n_y, n_u = t.shape
        th = t.conj().T
        reg = rho * float(np.sum(np.abs(t) ** 2)) / n_u
        #: ``a (T^H T + R)^-1 T^H`` (complex, n_u x n_y), precomputed once
        self.update_matrix = self.gain * np.linalg.solve(th @ t + reg * np.eye(n_u), th)
        self.n_inputs = 2 * n_y
        self.n_outputs = 2 * n_u
        self._state = self._initial()

    def _initial(self) -> _SyncState:
        n_u = self.n_outputs // 2
        return _SyncState(np.zeros(n_u, complex), np.zeros(self.n_inputs // 2, complex), 0, None)

    def reset(self) -> None:
        """Zero the synchronous force and the window."""
        self._state = self._initial()

    def get_state(self) -> _SyncState:
        """Return a copy of the state (force phasors, window accumulator)."""
        return self._state.copy()

    def set_state(self, state: _SyncState) -> None:
        """Restore a state from :meth:`get_state`."""
        self._state = state.copy()

    def skip(self, period_index: int) -> None:
        """Consume a period without updating (hold / anti-windup)."""
        self._state.last_period = int(period_index)

    def step(self, period_index: int, measured: np.ndarray) -> ControlStep:
        """
        Add period k's 1 x coefficients to the window; update at its end; command for k+i.

        Parameters
        ----------
        period_index : int
            Measured period k (consecutive).
        measured : numpy.ndarray
            Real layout ``[q_cos..., q_sin...]`` of the measured sensors (m sqrt(samples)).

        Returns
        -------
        ControlStep
            Real layout of the 1 x force coefficients for period ``k + delay``.

        """
        st = self._state
        if st.last_period is not None and period_index != st.last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {st.last_period + 1}, got {period_index}; reset() first"
            )
        st.acc += complex_from_real(measured)
        st.count += 1
        if st.count >= self.window:
            st.u = st.u - self.update_matrix @ (st.acc / st.count)
            st.acc[:] = 0
            st.count = 0
        st.last_period = int(period_index)
        return ControlStep(
            int(period_index) + self.delay, int(period_index), real_from_complex(st.u)
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

    """

    def __init__(self, config, capacity: float, model: WaveletModel, settings=None) -> None:
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
        guard = DivergenceGuard(
            GuardConfig(
                coefficient_bound=config.coefficient_bound,
                displacement_bound=config.displacement_bound,
                growth_factor=config.growth_factor,
                growth_periods=config.growth_periods,
            )
        )
        self.supervisor = WaveletControlSupervisor(
            self.limiter, config.delay_periods, guard=guard, fault_actions=config.fault_actions
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
        self.supervisor.set_controller(controller)
        self._buffer = np.zeros((n, N_SENSORS))
        self._stats = {"commands_sent": 0, "commands_late": 0, "inputs_rejected": 0}
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

    def on_fault(self, fault_type: int) -> str:
        """Apply the configured action for a FaultEvent type; return it."""
        return self.supervisor.on_fault(int(fault_type))

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
        if command_missing and self.supervisor.command_missing(m):
            self._stats["commands_late"] += 1
        x = np.asarray(displacement, dtype=float)
        if x.shape != (N_SENSORS,) or not np.all(np.isfinite(x)):
            self._stats["inputs_rejected"] += 1
            self._ok = False
        else:
            self._buffer[pos] = x
            self._peak = max(self._peak, float(np.max(np.abs(x))))
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
            sup._sent[m + sup.delay] = zeros
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
