"""
ROS-free core of the ``wavelet_controller`` node: filterbank records in, one command per period out.

The pipeline joins the pieces of chapters 6-8 in the lock-step order of the project
(``ARCHITECTURE.md``, "Time")::

    Coefficient records of sample n  ->  measured vector of period m (basis order)
        -> at the last sample of period m: WaveletControlSupervisor.step(m, q[m])
        -> Command for period m + i (zeros when OFF), exactly one per measured period

Period assembly
---------------
Control period m covers samples ``m N .. m N + N - 1`` (``N = samples_per_period``, one
revolution). The measured coefficient ``x_{p,q}`` of period m is the filterbank detail of
level ``j = R - p + 1`` with translation index ``m 2^(p-1) + q - 1``, completed inside the
period (:func:`amb_wavelet.period.period_position`); even and odd quadrature values come from
the front end's ``fixed/even/*`` and ``fixed/odd/*`` channels (section 4.3). The vector is
laid out as :func:`amb_controller.basis.measurement_basis` (level, translation, quadrature,
sensor channel), the layout the model's Markov parameters use.

Gaps and start-up
-----------------
A period is used only if every coefficient it needs arrived, is ``settled`` (no start-up
zeros of a filterbank reset in its support, :mod:`amb_wavelet.analysis`) and all its samples
were seen in order. Otherwise (a gap in ``sample_index``, a filterbank reset, the first
periods of a long wavelet) the pipeline still answers with one command for ``m + i``, but
with zero force and ``hold = True``; the controller state is reset (its difference equation
needs consecutive periods) and a running identification is abandoned. Nothing measured on
one side of a gap is ever combined with the other side.

Gain normalisation (decision)
-----------------------------
The thesis gives ``k_{1,1}`` (0.21, 0.34, 0.41, 0.68; section 7.4.2) without units. Here the
proportional law ``U = -k z^-i Q`` (eq. 7.7) and the moderated law ``U = -k z^-i W`` (eq. 7.9)
use the gain matrix ``k G(1)^+``: ``G(1) = sum_k A^(k)`` is the model's steady-state gain
(measured per control coefficient) and ``^+`` its Moore-Penrose pseudo-inverse, so ``k`` is
dimensionless and ``k = 1`` would cancel a steady measured coefficient in one step on a
static plant. The thesis's numbers and ours are therefore comparable as ratios, not as
absolute values (said in every report).
"""

from __future__ import annotations

import math
import time
from dataclasses import asdict, dataclass, field, fields
from pathlib import Path

import numpy as np

from amb_controller.basis import QUADRATURES, BasisSet, control_basis, measurement_basis
from amb_controller.errors import ControllerValueError
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.identification import MarkovIdentifier, StepExperiment
from amb_controller.inverse import dc_gain, pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.response import PrescribedResponse
from amb_controller.steady_state import (
    ProportionalController,
    SteadyStatePredictor,
    steady_state_operator,
)
from amb_controller.supervisor import Command, Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

__all__ = [
    "CONTROLLERS",
    "RESPONSES",
    "ConfigError",
    "ControllerConfig",
    "ControllerPipeline",
]

CONTROLLERS = ("none", "proportional", "moderated", "transient", "synchronous", "harmonic")
#: 1 x Fourier baselines, run by :class:`amb_controller.baselines.HarmonicPipeline`.
BASELINE_CONTROLLERS = ("synchronous", "harmonic")
RESPONSES = ("exponential", "linear", "series")
FAULT_ACTIONS = ("hold", "off", "ignore")
SENSOR_NAMES = ("x1", "y1", "x2", "y2", "x3", "y3", "x4", "y4")
N_AXES = 4


class ConfigError(ControllerValueError):
    """A controller configuration field has an invalid value (the message names it)."""


def _fail(name: str, value, allowed: str) -> ConfigError:
    return ConfigError(
        f"controller config field '{name}' = {value!r} is invalid: expected {allowed}; "
        "correct the parameter (params file or amb-sim option) and restart"
    )


@dataclass(frozen=True)
class ControllerConfig:
    """
    Plain configuration of :class:`ControllerPipeline` (the node's ROS parameters).

    Attributes
    ----------
    wavelet : str
        Orthogonal PyWavelets name (analysis and control wavelet).
    samples_per_rev : int
        Samples per revolution, a power of two >= 4.
    samples_per_period : int
        Control period in samples; 0 means ``samples_per_rev``. Only one revolution is
        supported (the thesis's T, chapters 7-8).
    levels : tuple of int
        Thesis levels p used for measurement and control (1 = 1 x running speed).
    quadratures : tuple of str
        Quadrature channels, ``("even", "odd")`` (section 4.3) or a subset.
    frames : tuple of str
        Frames the controller reads; only ``("fixed",)`` is supported (the bearing forces
        act in the fixed frame).
    sensors : tuple of int
        Sensor channels 0..7 ([x1, y1, ..., x4, y4]) the controller measures: the selection
        ``B^(m)`` of eq. 7.2. Default: the inner planes 2 and 3 beside the AMBs, so that
        ``G B_u`` is square (4 sensors, 4 axes) and the inverse of eq. 6.35 is a true
        inverse; with more sensors than axes the least-squares inverse leaves an oblique
        residual ``I - G (B G)^-1 B`` that the integral action of eq. 8.10 cannot remove
        (section 8.2) and that, on the FE model, amplifies the outer planes' 1 x vibration.
    delay_periods : int
        Evaluation delay i >= 1 (thesis: 2 in chapter 8, 3 in section 7.4.2).
    controller : str
        ``none``, ``proportional`` (eq. 7.7), ``moderated`` (eq. 7.9) or ``transient``
        (eq. 8.10); ``synchronous`` and ``harmonic`` are the 1 x Fourier baselines of
        :mod:`amb_controller.baselines` (run by its ``HarmonicPipeline``, not by this one).
    response : str
        Prescribed response of the transient controller: ``exponential`` (eq. 8.6, ``w``,
        ``v``), ``linear`` (``rate`` per period) or ``series`` (``series`` = c_1..c_K,
        eq. 8.7).
    w, v : float
        Exponential response, ``0 < w < 1``, ``0 <= v < 1``.
    rate : float
        Linear decay per period, ``0 < rate < 1``.
    series : tuple of float
        c_1 .. c_K of eq. 8.7 (c_1 != 0).
    gain : float
        Dimensionless k of the proportional / moderated controllers (module docstring), > 0.
    inverse_order : int
        Truncation order K of the pseudo-inverse (eq. 6.35; the thesis uses 5), >= 0.
    inverse_regularisation : float
        Tikhonov weight of the inverse (model units), >= 0.
    predictor_dc_weight : float
        Weight of ``B(1) G(1) = I`` in the steady-state predictor's inverse (eq. 7.6), >= 0.
    force_limit : tuple of float
        Wavelet force limit per axis [b1x, b1y, b2x, b2y] in N, each in
        ``(0, amb.force_limit]`` of the rig.
    coefficient_bound : float
        Divergence guard on any measured coefficient (m sqrt(samples)); ``inf`` = off.
    displacement_bound : float
        Divergence guard on the peak displacement of a period (m); ``inf`` = off.
    growth_factor : float
        Guard: per-period growth ratio counted as divergence (> 1).
    growth_periods : int
        Guard: consecutive growing periods that trip it (>= 1).
    fault_actions : dict of int to str
        ``FaultEvent.fault_type`` -> ``hold``, ``off`` or ``ignore``.
    model_file : str
        Wavelet model ``.npz`` to load at start ('' = none).
    identification_order : int
        Markov order K fitted by on-line identification (>= 1).
    identification_amplitude : float
        Default step in one control coefficient (N sqrt(samples)), != 0.
    identification_periods_per_step : int
        Default periods each step is held on (and then off); > identification_order.

    """

    wavelet: str = "haar"
    samples_per_rev: int = 64
    samples_per_period: int = 0
    levels: tuple[int, ...] = (1,)
    quadratures: tuple[str, ...] = QUADRATURES
    frames: tuple[str, ...] = ("fixed",)
    sensors: tuple[int, ...] = (2, 3, 4, 5)
    delay_periods: int = 2
    controller: str = "transient"
    response: str = "exponential"
    w: float = 0.75
    v: float = 0.75
    rate: float = 0.2
    series: tuple[float, ...] = ()
    gain: float = 0.21
    inverse_order: int = 5
    inverse_regularisation: float = 0.0
    predictor_dc_weight: float = 10.0
    force_limit: tuple[float, ...] = (1000.0, 1000.0, 1000.0, 1000.0)
    coefficient_bound: float = math.inf
    displacement_bound: float = math.inf
    growth_factor: float = 1.5
    growth_periods: int = 8
    fault_actions: dict[int, str] = field(default_factory=lambda: {2: "hold"})
    model_file: str = ""
    identification_order: int = 12
    identification_amplitude: float = 20.0
    identification_periods_per_step: int = 16

    def __post_init__(self) -> None:
        self._validate()

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_dict(cls, d: dict, capacity: float | None = None) -> ControllerConfig:
        """
        Build and validate a configuration from a plain mapping.

        Parameters
        ----------
        d : dict
            Field name -> value (unknown names are refused). ``force_limit`` may be one
            number for all axes.
        capacity : float, optional
            Bearing capacity in N (``amb.force_limit`` of the rig); when given every force
            limit must not exceed it.

        Returns
        -------
        ControllerConfig

        Raises
        ------
        ConfigError
            Naming the field, the value and the allowed range.

        """
        if not isinstance(d, dict):
            raise ConfigError(f"controller config must be a mapping, got {type(d).__name__}")
        known = {f.name for f in fields(cls)}
        unknown = sorted(set(d) - known)
        if unknown:
            raise ConfigError(
                f"unknown controller config field(s) {unknown}; allowed: {sorted(known)}"
            )
        kw = dict(d)
        for name in ("levels", "quadratures", "frames", "series", "sensors"):
            if name in kw:
                value = kw[name]
                kw[name] = tuple(value) if isinstance(value, list | tuple) else (value,)
        if "force_limit" in kw:
            fl = kw["force_limit"]
            fl = tuple(fl) if isinstance(fl, list | tuple) else (fl,) * N_AXES
            kw["force_limit"] = fl
        if "fault_actions" in kw:
            try:
                kw["fault_actions"] = {int(k): str(a) for k, a in dict(kw["fault_actions"]).items()}
            except (TypeError, ValueError) as exc:
                raise _fail(
                    "fault_actions", d["fault_actions"], "a mapping fault_type -> action"
                ) from exc
        config = cls(**kw)
        if capacity is not None:
            config.check_capacity(capacity)
        return config

    def to_dict(self) -> dict:
        """Return the fields as plain Python values (lists for tuples)."""
        out = asdict(self)
        for k, v in out.items():
            if isinstance(v, tuple):
                out[k] = list(v)
        return out

    def check_capacity(self, capacity: float) -> None:
        """Raise :class:`ConfigError` if a force limit exceeds the bearing capacity (N)."""
        if any(f > capacity for f in self.force_limit):
            raise _fail(
                "force_limit",
                list(self.force_limit),
                f"each limit in (0, {capacity:g}] N (amb.force_limit of the rig)",
            )

    @property
    def period_samples(self) -> int:
        """Samples per control period (``samples_per_period`` or ``samples_per_rev``)."""
        return self.samples_per_period or self.samples_per_rev

    # ------------------------------------------------------------------ validation
    def _validate(self) -> None:
        import pywt

        if not isinstance(self.wavelet, str) or self.wavelet not in pywt.wavelist(kind="discrete"):
            raise _fail("wavelet", self.wavelet, "an orthogonal PyWavelets name (pywt.wavelist)")
        if not pywt.Wavelet(self.wavelet).orthogonal:
            raise _fail("wavelet", self.wavelet, "an orthogonal wavelet (haar, dbN, symN, coifN)")
        spr = self.samples_per_rev
        if not _is_int(spr) or spr < 4 or spr & (spr - 1):
            raise _fail("samples_per_rev", spr, "a power of two >= 4")
        if not _is_int(self.samples_per_period) or self.samples_per_period not in (0, spr):
            raise _fail(
                "samples_per_period",
                self.samples_per_period,
                f"0 or samples_per_rev = {spr} (one revolution per control period)",
            )
        r = spr.bit_length() - 1
        if (
            not self.levels
            or any(not _is_int(p) or not 1 <= p <= r for p in self.levels)
            or len(set(self.levels)) != len(self.levels)
        ):
            raise _fail("levels", list(self.levels), f"distinct thesis levels p in 1..{r}")
        if (
            not self.quadratures
            or any(q not in QUADRATURES for q in self.quadratures)
            or len(set(self.quadratures)) != len(self.quadratures)
        ):
            raise _fail("quadratures", list(self.quadratures), f"a subset of {QUADRATURES}")
        if tuple(self.frames) != ("fixed",):
            raise _fail("frames", list(self.frames), "['fixed'] (forces act in the fixed frame)")
        if (
            not self.sensors
            or any(not _is_int(c) or not 0 <= c < len(SENSOR_NAMES) for c in self.sensors)
            or len(set(self.sensors)) != len(self.sensors)
        ):
            raise _fail("sensors", list(self.sensors), "distinct sensor channels in 0..7")
        if not _is_int(self.delay_periods) or not 1 <= self.delay_periods <= 16:
            raise _fail("delay_periods", self.delay_periods, "an integer in 1..16 periods")
        if self.controller not in CONTROLLERS:
            raise _fail("controller", self.controller, f"one of {CONTROLLERS}")
        if self.response not in RESPONSES:
            raise _fail("response", self.response, f"one of {RESPONSES}")
        if not (_finite(self.w) and 0.0 < self.w < 1.0):
            raise _fail("w", self.w, "0 < w < 1 (eq. 8.6)")
        if not (_finite(self.v) and 0.0 <= self.v < 1.0):
            raise _fail("v", self.v, "0 <= v < 1 (|v| < 1, eq. 8.6; v < 0 alternates)")
        if not (_finite(self.rate) and 0.0 < self.rate < 1.0):
            raise _fail("rate", self.rate, "0 < rate < 1 per period")
        if self.response == "series" and (
            not self.series or not all(_finite(c) for c in self.series) or self.series[0] == 0
        ):
            raise _fail("series", list(self.series), "finite c_1..c_K with c_1 != 0 (eq. 8.7)")
        if not (_finite(self.gain) and self.gain > 0.0):
            raise _fail("gain", self.gain, "a dimensionless k > 0")
        if not _is_int(self.inverse_order) or not 0 <= self.inverse_order <= 50:
            raise _fail("inverse_order", self.inverse_order, "an integer in 0..50")
        if not (_finite(self.inverse_regularisation) and self.inverse_regularisation >= 0):
            raise _fail("inverse_regularisation", self.inverse_regularisation, ">= 0")
        if not (_finite(self.predictor_dc_weight) and self.predictor_dc_weight >= 0):
            raise _fail("predictor_dc_weight", self.predictor_dc_weight, ">= 0")
        if len(self.force_limit) != N_AXES or not all(
            _finite(f) and f > 0 for f in self.force_limit
        ):
            raise _fail("force_limit", list(self.force_limit), "4 limits > 0 N (one per axis)")
        for name in ("coefficient_bound", "displacement_bound"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise _fail(name, value, "> 0 (inf = off)")
        if not (_finite(self.growth_factor) and self.growth_factor > 1.0):
            raise _fail("growth_factor", self.growth_factor, "> 1")
        if not _is_int(self.growth_periods) or self.growth_periods < 1:
            raise _fail("growth_periods", self.growth_periods, "an integer >= 1")
        for fault, action in self.fault_actions.items():
            if action not in FAULT_ACTIONS or not 0 <= int(fault) <= 255:
                raise _fail(
                    "fault_actions",
                    dict(self.fault_actions),
                    f"fault_type 0..255 -> {FAULT_ACTIONS}",
                )
        if not isinstance(self.model_file, str):
            raise _fail("model_file", self.model_file, "a path string ('' = none)")
        if not _is_int(self.identification_order) or not 1 <= self.identification_order <= 60:
            raise _fail("identification_order", self.identification_order, "an integer in 1..60")
        if not (_finite(self.identification_amplitude) and self.identification_amplitude != 0):
            raise _fail("identification_amplitude", self.identification_amplitude, "finite, != 0")
        pps = self.identification_periods_per_step
        if not _is_int(pps) or pps <= self.identification_order:
            raise _fail(
                "identification_periods_per_step",
                pps,
                f"an integer > identification_order = {self.identification_order}",
            )


def _is_int(value) -> bool:
    return isinstance(value, int | np.integer) and not isinstance(value, bool)


def _finite(value) -> bool:
    return isinstance(value, int | float | np.floating) and math.isfinite(value)


def selected_measurement_basis(config: ControllerConfig) -> BasisSet:
    """
    Measured-coefficient basis of the configured levels, quadratures and sensors.

    The rows of :func:`amb_controller.basis.measurement_basis` (8 sensor channels) whose
    channel is in ``config.sensors``, in the same order (level, translation, quadrature,
    channel); labels keep the physical channel (``c2`` = x2).
    """
    full = measurement_basis(
        config.wavelet, config.period_samples, config.levels, len(SENSOR_NAMES), config.quadratures
    )
    keep = [i for i, lab in enumerate(full.labels) if int(lab.split("/c")[-1]) in config.sensors]
    return BasisSet(full.weights[keep], full.offset, tuple(full.labels[i] for i in keep))


def prescribed_response(config: ControllerConfig) -> PrescribedResponse:
    """Return the alpha(z) of eq. 8.6-8.7 the configuration asks for."""
    if config.response == "exponential":
        return PrescribedResponse.exponential(config.w, config.v)
    if config.response == "linear":
        return PrescribedResponse.linear_decay(config.rate)
    return PrescribedResponse.from_series(config.series)


class ControllerPipeline:
    """
    Coefficient records in, one :class:`~amb_controller.supervisor.Command` per period out.

    Parameters
    ----------
    config : ControllerConfig
        Validated configuration.
    capacity : float
        Bearing capacity per axis in N (``rig.amb.force_limit``); the force limits must not
        exceed it.
    model : WaveletModel, optional
        Wavelet-domain model (identified or from the FE model). Without one, only OFF and
        IDENTIFYING are possible until :meth:`set_model` or an identification.
    channel_labels : sequence of str, optional
        Labels of the filterbank's channels (``ChannelFrontEnd.labels``); default: the
        front end with both frames and both quadratures (32 channels).

    """

    def __init__(
        self,
        config: ControllerConfig,
        capacity: float,
        model: WaveletModel | None = None,
        channel_labels=None,
    ) -> None:
        config.check_capacity(capacity)
        self.config = config
        self.capacity = float(capacity)
        n = config.period_samples
        self.samples_per_period = n
        self._r = n.bit_length() - 1
        self.control = control_basis(config.wavelet, n, config.levels, N_AXES, config.quadratures)
        self.measured = selected_measurement_basis(config)
        if channel_labels is None:
            from amb_wavelet.frontend import ChannelFrontEnd

            channel_labels = ChannelFrontEnd(config.samples_per_rev).labels
        labels = list(channel_labels)
        self._columns = {}
        for quad in config.quadratures:
            try:
                self._columns[quad] = np.array(
                    [labels.index(f"fixed/{quad}/{name}") for name in SENSOR_NAMES]
                )
            except ValueError as exc:
                raise ConfigError(
                    f"filterbank channels {labels} lack 'fixed/{quad}/*': configure the "
                    "filterbank with the fixed frame and the quadratures the controller uses"
                ) from exc
        self.n_channels = len(labels)
        # per (filterbank level j, translation q): positions in the measured vector and the
        # filterbank columns that fill them
        groups: dict[tuple[int, int], tuple[list[int], list[int]]] = {}
        for i, label in enumerate(self.measured.labels):
            p, q, quad, c = label.split("/")
            idx, cols = groups.setdefault((self._r - int(p[1:]) + 1, int(q[1:])), ([], []))
            idx.append(i)
            cols.append(int(self._columns[quad][int(c[1:])]))
        self._groups = {key: (np.array(i), np.array(c)) for key, (i, c) in groups.items()}
        self._group_index = {key: g for g, key in enumerate(self._groups)}
        self._levels_j = {j for j, _ in self._groups}
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
        self._model: WaveletModel | None = None
        self._model_file = ""
        self._omega = 0.0
        self._stats = {"commands_sent": 0, "commands_late": 0, "inputs_rejected": 0}
        self._compute_time = 0.0
        self._last_command: Command | None = None
        self._last_period = -1
        self._period_message = ""
        self._expected: int | None = None
        self.last_measured: np.ndarray | None = None
        self._new_period(None)
        if model is None and config.model_file:
            model = WaveletModel.load(config.model_file)
            self._model_file = str(config.model_file)
        if model is not None:
            self.set_model(model)

    # ------------------------------------------------------------------ model
    @property
    def model(self) -> WaveletModel | None:
        """The wavelet-domain model in use (None before identification or loading)."""
        return self._model

    def set_model(self, model: WaveletModel, model_file: str = "") -> None:
        """
        Install a model and build the configured controller from it.

        Raises
        ------
        ConfigError
            If the model's wavelet, samples per period or coefficient layout differ from
            the configuration.

        """
        cfg = self.config
        expected = (self.measured.n_coefficients, self.control.n_coefficients)
        if model.markov.shape[1:] != expected:
            raise ConfigError(
                f"model has {model.markov.shape[1:]} (measured, control) coefficients, the "
                f"configuration {expected}; identify again with this configuration"
            )
        if model.wavelet != cfg.wavelet or int(model.samples_per_rev) != self.samples_per_period:
            raise ConfigError(
                f"model is for {model.wavelet!r} at {model.samples_per_rev} samples/period, the "
                f"configuration {cfg.wavelet!r} at {self.samples_per_period}; identify again"
            )
        if model.control_labels and tuple(model.control_labels) != self.control.labels:
            raise ConfigError("model control coefficient labels differ from the configuration")
        if model.inverse.shape[0] != cfg.inverse_order + 1:
            inverse = pseudo_inverse_series(
                model.markov, cfg.inverse_order, regularisation=cfg.inverse_regularisation
            )
            model = _replace_inverse(model, inverse)
        self._model = model
        if model_file:
            self._model_file = str(model_file)
        controller = self._build_controller(model)
        if controller is not None:
            self.supervisor.set_controller(controller)
        else:
            self.supervisor.controller = None

    def _build_controller(self, model: WaveletModel):
        cfg = self.config
        i = cfg.delay_periods
        if cfg.controller == "none":
            return None
        if cfg.controller in BASELINE_CONTROLLERS:
            raise ConfigError(
                f"controller {cfg.controller!r} is a 1 x Fourier baseline: run it with "
                "amb_controller.baselines.HarmonicPipeline (amb-sim --controller selects it)"
            )
        if cfg.controller == "transient":
            return TransientController(model.inverse, prescribed_response(cfg), i)
        gain = cfg.gain * np.linalg.pinv(dc_gain(model.markov))
        predictor = None
        if cfg.controller == "moderated":
            inverse = pseudo_inverse_series(
                model.markov,
                cfg.inverse_order,
                regularisation=cfg.inverse_regularisation,
                dc_weight=cfg.predictor_dc_weight,
                rank_rtol=_rank_rtol(cfg),
            )
            predictor = SteadyStatePredictor(steady_state_operator(model.markov, inverse))
        return ProportionalController(gain, i, predictor)

    def save_model(self, path: str | Path) -> Path:
        """Write the model in use to ``path`` (``.npz``); return the path."""
        if self._model is None:
            raise ControllerValueError(
                "no model to save: run start_identification() to completion or load a model"
            )
        out = self._model.save(path)
        self._model_file = str(out)
        return out

    # ------------------------------------------------------------------ modes
    def set_mode(self, mode: Mode | int) -> tuple[bool, str]:
        """Request OFF, ACTIVE or HOLD; return (accepted, reason) as SetControllerMode."""
        try:
            mode = Mode(int(mode))
        except ValueError:
            return False, f"unknown mode {mode}; expected 0..3 (ControllerStatus.MODE_*)"
        if mode == Mode.ACTIVE and self.config.controller == "none":
            return False, "controller 'none' configured: nothing to activate"
        return self.supervisor.set_mode(mode)

    def start_identification(
        self,
        axes=None,
        level: int | None = None,
        amplitude: float | None = None,
        periods_per_step: int | None = None,
    ) -> tuple[bool, str]:
        """
        Start the on-line identification of section 6.4 at the next period.

        Each control coefficient of ``level`` on each axis of ``axes`` (both quadratures)
        is stepped to ``amplitude`` for ``periods_per_step`` periods and back to zero for as
        many, one at a time; :class:`~amb_controller.identification.MarkovIdentifier` fits
        Markov parameters of order ``identification_order``. On completion the model is
        installed (see :attr:`model`) and the mode returns to OFF.

        Parameters
        ----------
        axes : sequence of int, optional
            Bearing axes 0..3 (default all). Every control coefficient must be excited.
        level : int, optional
            Thesis level p (default: the single configured level).
        amplitude : float, optional
            Step in N sqrt(samples) (default ``identification_amplitude``).
        periods_per_step : int, optional
            Default ``identification_periods_per_step``.

        Returns
        -------
        tuple of (bool, str)
            Accepted, and the reason.

        """
        cfg = self.config
        axes = list(range(N_AXES)) if axes is None else [int(a) for a in axes]
        if level is None:
            if len(cfg.levels) != 1:
                return False, f"give the level: configured levels {list(cfg.levels)}"
            level = cfg.levels[0]
        amplitude = cfg.identification_amplitude if amplitude is None else float(amplitude)
        pps = cfg.identification_periods_per_step if periods_per_step is None else periods_per_step
        if self.supervisor.mode in (Mode.ACTIVE, Mode.HOLD):
            return False, "identification needs OFF (PID only); set mode OFF first"
        if not (math.isfinite(amplitude) and amplitude != 0):
            return False, f"amplitude must be finite and non-zero, got {amplitude}"
        if int(pps) != pps or pps <= cfg.identification_order:
            return False, (
                f"periods_per_step must exceed identification_order = "
                f"{cfg.identification_order}, got {pps}"
            )
        inputs = [
            i
            for i, label in enumerate(self.control.labels)
            if label.startswith(f"p{level}/") and int(label.split("/c")[-1]) in axes
        ]
        if len(inputs) != self.control.n_coefficients:
            return False, (
                f"axes {axes} at level {level} excite {len(inputs)} of "
                f"{self.control.n_coefficients} control coefficients; every one must be "
                "stepped (all 4 axes at every configured level)"
            )
        start = self._last_period + 1 + cfg.delay_periods
        experiment = StepExperiment(
            self.control.n_coefficients, inputs, amplitude, int(pps), start_period=start
        )
        identifier = MarkovIdentifier(
            self.control.n_coefficients, self.measured.n_coefficients, cfg.identification_order
        )
        self.supervisor.start_identification(experiment, identifier)
        return True, (
            f"identifying {len(inputs)} control coefficients from period {start}, "
            f"{experiment.n_periods} periods"
        )

    def on_fault(self, fault_type: int) -> str:
        """Apply the configured action for a FaultEvent type; return it."""
        return self.supervisor.on_fault(int(fault_type))

    def reset(self) -> None:
        """OFF, guard re-armed, period assembly and counters cleared (model kept)."""
        self.supervisor.reset()
        self._new_period(None)
        self._expected = None
        self._last_period = -1
        self._last_command = None
        for key in self._stats:
            self._stats[key] = 0

    # ------------------------------------------------------------------ stream
    def _new_period(self, period: int | None) -> None:
        self._period = period
        self._q = np.zeros(self.measured.n_coefficients)
        self._have = np.zeros(len(self._groups), dtype=bool)
        self._ok = True
        self._peak = 0.0
        self._period_message = ""

    def on_sample(
        self,
        sample_index: int,
        records,
        displacement=None,
        omega: float | None = None,
        command_missing: bool = False,
    ) -> Command | None:
        """
        Feed the records completed by one sample; return a command at a period's end.

        Parameters
        ----------
        sample_index : int
            Index of the sample that completed ``records`` (consecutive; a gap or a step
            back abandons the current period, see module docstring).
        records : list of amb_wavelet.analysis.Coefficient
            What the filterbank returned for this sample (may be empty), values over the
            full channel set in ``channel_labels`` order.
        displacement : array_like, optional
            The 8 sensor displacements of the sample in m (for the guard's peak bound).
        omega : float, optional
            Running speed in rad/s (recorded in an identified model).
        command_missing : bool
            The sample's ``STATUS_COMMAND_MISSING``: its period ran without the command (zero
            wavelet force). The command is counted late and the controller's step that made
            it is undone (:meth:`WaveletControlSupervisor.command_missing`).

        Returns
        -------
        Command or None
            At the last sample of period m: the command for ``m + delay_periods`` (zeros,
            ``hold = True`` if period m was incomplete); else None.

        """
        n = int(sample_index)
        N = self.samples_per_period
        m, pos = divmod(n, N)
        if omega is not None:
            self._omega = float(omega)
        if self._period != m:
            self._new_period(m)
            if pos != 0:
                self._invalidate(f"period {m} joined at sample {pos} of {N}")
        if self._expected is not None and n != self._expected:
            self._invalidate(f"sample {n} after {self._expected - 1}: gap")
        self._expected = n + 1
        if command_missing and self.supervisor.command_missing(m):
            self._stats["commands_late"] += 1
        if displacement is not None:
            d = np.asarray(displacement, dtype=float)
            self._peak = max(self._peak, float(np.max(np.abs(d))) if d.size else 0.0)
        for rec in records:
            if rec.kind != "detail" or rec.level not in self._levels_j:
                continue
            if rec.values.shape != (self.n_channels,) or not np.all(np.isfinite(rec.values)):
                self._stats["inputs_rejected"] += 1
                self._invalidate(f"period {m}: malformed coefficient record rejected")
                continue
            per = 2 ** (self._r - rec.level)
            k, q = divmod(int(rec.translation_index), per)
            if k != m:
                continue  # completed outside this period (not possible in order; ignore)
            idx, cols = self._groups[(rec.level, q + 1)]
            self._q[idx] = rec.values[cols]
            self._have[self._group_index[(rec.level, q + 1)]] = True
            if not rec.settled:
                self._invalidate(f"period {m}: start-up coefficients (not settled)")
        if pos != N - 1:
            return None
        return self._end_period(m)

    def _invalidate(self, reason: str) -> None:
        """Mark the current period unusable; keep the first reason."""
        if self._ok:
            self._period_message = reason
        self._ok = False

    def _end_period(self, m: int) -> Command:
        t0 = time.perf_counter()
        sup = self.supervisor
        complete = self._ok and bool(self._have.all())
        if complete and self._last_period != m - 1 and self._last_period >= 0:
            complete = False
            self._period_message = f"period {m} after {self._last_period}: periods missing"
        self.last_measured = self._q.copy() if complete else None
        if complete:
            command = sup.step(m, self._q.copy(), self._peak)
            self._after_identification()
        else:
            command = self._skip(m)
        self._last_period = m
        self._last_command = command
        self._stats["commands_sent"] += 1
        self._compute_time = time.perf_counter() - t0
        self._new_period(None)
        return command

    def _skip(self, m: int) -> Command:
        """Zero-force command for an incomplete period; restart the controller's history."""
        sup = self.supervisor
        if sup.controller is not None:
            sup.reset_controller()
        if sup.mode == Mode.IDENTIFYING:
            sup.set_mode(Mode.OFF)
            sup.message = f"identification abandoned: {self._period_message or 'incomplete'}"
        zeros = np.zeros(self.control.n_coefficients)
        result = self.limiter.apply(zeros)
        target = m + sup.delay
        sup._sent[target] = zeros
        msg = self._period_message or f"period {m} incomplete"
        return Command(
            target, m, zeros, result.force, sup.mode, True, result.saturated,
            bool(sup.guard is not None and sup.guard.tripped), msg,
        )  # fmt: skip

    def _after_identification(self) -> None:
        sup = self.supervisor
        result = sup.identification_result
        if result is None:
            return
        sup.identification_result = None
        cfg = self.config
        inverse = pseudo_inverse_series(
            result.markov, cfg.inverse_order, regularisation=cfg.inverse_regularisation
        )
        model = WaveletModel(
            markov=result.markov,
            inverse=inverse,
            wavelet=cfg.wavelet,
            samples_per_rev=self.samples_per_period,
            omega=self._omega,
            levels=tuple(cfg.levels),
            quadratures=tuple(cfg.quadratures),
            delay=cfg.delay_periods,
            offset=result.offset,
            residual_rms=result.residual_rms,
            source="identification",
            control_labels=self.control.labels,
            measured_labels=self.measured.labels,
        )
        message = sup.message
        self.set_model(model)
        self._model_file = ""
        sup.message = message

    # ------------------------------------------------------------------ status
    def status(self) -> dict:
        """
        Return the ``ControllerStatus`` fields as a dict (the node copies them).

        Keys: mode, controller, period_index, delay_periods, compute_time (s),
        peak_wavelet_force (4 N), saturated, guard_tripped, identification_progress,
        commands_sent, commands_late, inputs_rejected, model_file, message.
        """
        return status_fields(self, float(self.supervisor.identification_progress), self._model_file)


def status_fields(pipeline, identification_progress: float, model_file: str) -> dict:
    """The ``ControllerStatus`` fields of a pipeline (this one or a baseline's).

    Parameters
    ----------
    pipeline : ControllerPipeline or amb_controller.baselines.HarmonicPipeline
        Anything with ``config``, ``supervisor``, ``_last_command``, ``_last_period``,
        ``_compute_time`` (s) and ``_stats`` (commands_sent, commands_late, inputs_rejected).
    identification_progress : float
        0..1.
    model_file : str
        Model file in use ('' = none).

    Returns
    -------
    dict
        Keys as the message fields (see :meth:`ControllerPipeline.status`).
    """
    sup = pipeline.supervisor
    cmd = pipeline._last_command
    peak = np.zeros(N_AXES) if cmd is None else np.max(np.abs(cmd.force), axis=1)
    stats = pipeline._stats
    return {
        "mode": int(sup.mode),
        "controller": pipeline.config.controller,
        "period_index": int(pipeline._last_period),
        "delay_periods": int(pipeline.config.delay_periods),
        "compute_time": float(pipeline._compute_time),
        "peak_wavelet_force": peak.astype(float),
        "saturated": bool(cmd is not None and np.any(cmd.saturated)),
        "guard_tripped": bool(sup.guard is not None and sup.guard.tripped),
        "identification_progress": float(identification_progress),
        "commands_sent": int(stats["commands_sent"]),
        "commands_late": int(stats["commands_late"]),
        "inputs_rejected": int(stats["inputs_rejected"]),
        "model_file": model_file,
        "message": (cmd.message if cmd is not None and cmd.message else sup.message),
    }


def _rank_rtol(config: ControllerConfig) -> float:
    """Singular-value cutoff of the steady-state predictor's inverse (eq. 6.35, 7.6).

    At thesis level p >= 2 the odd control waveforms (the even ones shifted by a quarter
    revolution) are linearly dependent on the even ones, so ``G(1)`` of those levels has exact
    null directions that no input can move (singular values ~1e-16 of the largest). The
    predictor's ``B(1) G(1) = I`` weight then inverts rounding noise (terms up to 1e13), so its
    inverse is the truncated-SVD one. The transient controller keeps the plain inverse: on the
    coupled 1x+2x+4x FE loop the truncated one raised the exact closed-loop spectral radius from
    1.0 to 1.055-1.076 (test/beyond, issue 9 report). At p = 1 alone nothing changes (0 = off).
    """
    return 1e-8 if max(config.levels) > 1 else 0.0


def _replace_inverse(model: WaveletModel, inverse: np.ndarray) -> WaveletModel:
    from dataclasses import replace

    return replace(model, inverse=inverse)
