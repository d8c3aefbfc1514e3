"""
Configuration of the wavelet controller: :class:`ControllerConfig`, one home for each field.

Every field carries its default, a description with its unit, the allowed range (the text the
validation names in its refusal) and whether it may change while the controller runs
(:func:`~amb_common.config_fields.param`, ``dataclasses.field`` metadata). The
``wavelet_controller`` node declares its ROS parameters from these fields
(:func:`~amb_common.config_fields.parameter_fields`), ``amb-sim`` and the experiments
build the same dataclass, and :meth:`ControllerConfig._validate` refuses an invalid value with
the field's name, the value and the allowed range, whichever of them set it.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields

import numpy as np
import pywt

from amb_common.config_fields import param
from amb_common.names import N_AXES, SENSOR_NAMES
from amb_common.topics import DELAY_PERIODS
from amb_controller.basis import QUADRATURES
from amb_controller.errors import ControllerValueError
from amb_controller.stability import MAX_MODEL_RADIUS
from amb_controller.supervisor import DEFAULT_FAULT_ACTIONS

__all__ = [
    "BASELINE_CONTROLLERS",
    "CONTROLLERS",
    "FAULT_ACTIONS",
    "OUTPUT_BASES",
    "RESPONSES",
    "ConfigError",
    "ControllerConfig",
]

OUTPUT_BASES = ("wavelet", "sinusoid")
CONTROLLERS = (
    "none",
    "proportional",
    "moderated",
    "transient",
    "predictive",
    "synchronous",
    "harmonic",
)
#: 1 x Fourier baselines, run by :class:`amb_controller.baselines.HarmonicPipeline`.
BASELINE_CONTROLLERS = ("synchronous", "harmonic")
RESPONSES = ("exponential", "linear", "series")
FAULT_ACTIONS = ("hold", "off", "ignore")


class ConfigError(ControllerValueError):
    """A controller configuration field has an invalid value (the message names it)."""


def _fail(name: str, value, allowed: str | None = None) -> ConfigError:
    if allowed is None:
        allowed = _FIELDS[name].metadata["allowed"]
    return ConfigError(
        f"controller config field '{name}' = {value!r} is invalid: expected {allowed}; "
        "correct the parameter (params file or amb-sim option) and restart"
    )


@dataclass(frozen=True)
class ControllerConfig:
    """
    Plain configuration of :class:`~amb_controller.pipeline.ControllerPipeline`.

    The node's ROS parameters: each field's description, unit and allowed range are its
    :func:`~amb_common.config_fields.param` metadata. Validated on construction
    (:class:`ConfigError`): no field has an ``ints``/``floats`` range for the ROS descriptor to
    enforce, the refusal names the range (and a run-time refusal says why, see the node).
    """

    wavelet: str = param(
        "haar",
        description="orthogonal PyWavelets name of the analysis and control wavelet",
        allowed="an orthogonal PyWavelets name (pywt.wavelist)",
    )
    samples_per_rev: int = param(
        64, description="samples per revolution", allowed="a power of two >= 4"
    )
    samples_per_period: int = param(
        0,
        description="control period in samples (0 = samples_per_rev); only one revolution, "
        "the thesis's T (chapters 7-8), is supported",
        allowed="0 or samples_per_rev (one revolution per control period)",
    )
    levels: tuple[int, ...] = param(
        (1,),
        description="thesis levels p used for measurement and control (1 = 1 x running speed)",
        allowed="distinct thesis levels p in 1..log2(samples_per_rev)",
    )
    output_basis: str = param(
        "wavelet",
        description="waveform of the control force: wavelet (the thesis: the control "
        "wavelet's synthesis of the control coefficients) | sinusoid (the 1 x cosine and sine "
        "per axis for the even and odd quadratures: the same control law without the "
        "wavelet's harmonics; levels [1] only)",
        allowed=f"one of {OUTPUT_BASES} (sinusoid with levels [1] only)",
    )
    quadratures: tuple[str, ...] = param(
        QUADRATURES,
        description="quadrature channels (section 4.3), both or a subset",
        allowed=f"a subset of {QUADRATURES}",
    )
    frames: tuple[str, ...] = param(
        ("fixed",),
        description="frames the controller reads (the bearing forces act in the fixed frame)",
        allowed="['fixed'] (forces act in the fixed frame)",
        parameter=False,
    )
    # The default, the inner planes 2 and 3 beside the AMBs, makes G B_u square (4 sensors, 4
    # axes) so that the inverse of eq. 6.35 is a true inverse; with more sensors than axes the
    # least-squares inverse leaves an oblique residual I - G (B G)^-1 B that the integral
    # action of eq. 8.10 cannot remove (section 8.2) and that, on the FE model, amplifies the
    # outer planes' 1 x vibration.
    sensors: tuple[int, ...] = param(
        (2, 3, 4, 5),
        description="sensor channels 0..7 ([x1, y1, ..., x4, y4]) measured, the selection "
        "B^(m) of eq. 7.2 (default: the inner planes 2 and 3 beside the AMBs)",
        allowed="distinct sensor channels in 0..7",
    )
    delay_periods: int = param(
        DELAY_PERIODS,
        description="evaluation delay i, periods (eq. 8.10; thesis: 2 in chapter 8, 3 in "
        "section 7.4.2)",
        allowed="an integer in 1..16 periods",
    )
    controller: str = param(
        "transient",
        description="none | proportional (eq. 7.7) | moderated (eq. 7.9) | transient "
        "(eq. 8.10) | predictive (receding horizon on the Markov parameters, "
        "amb_controller.predictive); synchronous and harmonic are the 1 x Fourier "
        "baselines, run by amb_controller.baselines.HarmonicPipeline, not by ControllerPipeline",
        allowed=f"one of {CONTROLLERS}",
    )
    response: str = param(
        "exponential",
        description="prescribed response of the transient controller: exponential (w, v; "
        "eq. 8.6) | linear (rate per period) | series (c_1..c_K, eq. 8.7)",
        allowed=f"one of {RESPONSES}",
    )
    w: float = param(
        0.75,
        description="exponential response gain w (eq. 8.6), dimensionless",
        allowed="0 < w < 1 (eq. 8.6)",
        runtime=True,
    )
    v: float = param(
        0.75,
        description="exponential response pole v (eq. 8.6), dimensionless",
        allowed="0 <= v < 1 (|v| < 1, eq. 8.6; v < 0 alternates)",
        runtime=True,
    )
    rate: float = param(
        0.2,
        description="linear response: decay per period, dimensionless",
        allowed="0 < rate < 1 per period",
        runtime=True,
    )
    series: tuple[float, ...] = param(
        (),
        description="c_1..c_K of the response series (eq. 8.7), dimensionless",
        allowed="finite c_1..c_K with c_1 != 0 (eq. 8.7)",
    )
    gain: float = param(
        0.21,
        description="dimensionless k of the proportional/moderated controllers (gain matrix "
        "k G(1)^+, see amb_controller.pipeline)",
        allowed="a dimensionless k > 0",
        runtime=True,
    )
    inverse_order: int = param(
        5,
        description="truncation order K of the pseudo-inverse (eq. 6.35; the thesis uses 5)",
        allowed="an integer in 0..50",
    )
    inverse_regularisation: float = param(
        0.0, description="Tikhonov weight of the inverse, model units", allowed=">= 0"
    )
    predictor_dc_weight: float = param(
        10.0,
        description="weight of B(1) G(1) = I in the steady-state predictor's inverse (eq. 7.6)",
        allowed=">= 0",
    )
    horizon: int = param(
        20,
        description="predictive controller: prediction horizon P, periods (cost (P3) of "
        "amb_controller.predictive)",
        allowed="an integer in 1..200 periods, >= moves",
    )
    moves: int = param(
        3,
        description="predictive controller: control moves C optimised per period (the last "
        "held to the horizon; 1 = mean-level control)",
        allowed="an integer in 1..horizon",
    )
    move_weight: float = param(
        0.25,
        description="predictive controller: weight of the command's change per period relative "
        "to the model's steady gain sigma_max(G(1)), dimensionless (0 = fastest)",
        allowed="finite, >= 0",
    )
    input_weight: float = param(
        0.03,
        description="predictive controller: weight of the command itself relative to the "
        "model's steady gain sigma_max(G(1)), dimensionless (a Tikhonov term: directions of "
        "G(1) weaker than it are not driven; 0 = offset-free)",
        allowed="finite, >= 0",
    )
    force_limit: tuple[float, ...] = param(
        (1000.0, 1000.0, 1000.0, 1000.0),
        description="wavelet force limit per axis [b1x, b1y, b2x, b2y], N, each at most the "
        "bearing capacity (amb.force_limit of the rig)",
        allowed="4 limits > 0 N (one per axis)",
        runtime=True,
    )
    max_model_radius: float = param(
        MAX_MODEL_RADIUS,
        description="largest closed-loop spectral radius of the controller on its own model "
        "with which it may go ACTIVE (amb_controller.stability.own_model_radius; above 1 lets "
        "a loop its model predicts to diverge run: experiments only; inf = off)",
        allowed="> 0 (inf = off)",
    )
    coefficient_bound: float = param(
        math.inf,
        description="divergence guard on any measured coefficient, m sqrt(samples) (inf = off)",
        allowed="> 0 (inf = off)",
    )
    displacement_bound: float = param(
        math.inf,
        description="divergence guard on the peak displacement of a period, m (inf = off)",
        allowed="> 0 (inf = off)",
    )
    contact_guard: bool = param(
        True,
        description="divergence guard also on a period's peak displacement at a probe next to "
        "an auxiliary bearing as large as that bearing's clearance (rig.probe_clearance: the "
        "rotor is at the bearing, thesis 3.3.2): the added force goes to zero until a reset",
        allowed="true or false",
    )
    growth_factor: float = param(
        1.5, description="guard: per-period growth ratio counted as divergence", allowed="> 1"
    )
    growth_periods: int = param(
        8,
        description="guard: consecutive growing periods that trip it",
        allowed="an integer >= 1",
    )
    fault_actions: dict[int, str] = param(  # noqa: RUF009 (param returns a field)
        default_factory=lambda: dict(DEFAULT_FAULT_ACTIONS),
        description="FaultEvent.fault_type -> action (hold | off | ignore)",
        allowed=f"fault_type 0..255 -> {FAULT_ACTIONS}",
    )
    model_file: str = param(
        "",
        description="wavelet model .npz to load at start ('' = none)",
        allowed="a path string ('' = none)",
    )
    early_model_file: str = param(
        "",
        description="early-action model .npz (amb-early-model; one speed or a bank, the model "
        "nearest the measured speed used): read the fault's own period for a sudden unbalance "
        "and cancel it from the next ('' = off)",
        allowed="a path string ('' = off)",
    )
    identification_order: int = param(
        12,
        description="Markov order K fitted by on-line identification",
        allowed="an integer in 1..60",
    )
    identification_amplitude: float = param(
        20.0,
        description="default identification step in one control coefficient, N sqrt(samples)",
        allowed="finite, != 0",
    )
    identification_periods_per_step: int = param(
        16,
        description="default periods each identification step is held on (and then off)",
        allowed="an integer > identification_order",
    )

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
        if not isinstance(self.wavelet, str) or self.wavelet not in pywt.wavelist(kind="discrete"):
            raise _fail("wavelet", self.wavelet)
        if not pywt.Wavelet(self.wavelet).orthogonal:
            raise _fail("wavelet", self.wavelet, "an orthogonal wavelet (haar, dbN, symN, coifN)")
        spr = self.samples_per_rev
        if not _is_int(spr) or spr < 4 or spr & (spr - 1):
            raise _fail("samples_per_rev", spr)
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
        if self.output_basis not in OUTPUT_BASES or (
            self.output_basis == "sinusoid" and tuple(self.levels) != (1,)
        ):
            raise _fail("output_basis", self.output_basis)
        if (
            not self.quadratures
            or any(q not in QUADRATURES for q in self.quadratures)
            or len(set(self.quadratures)) != len(self.quadratures)
        ):
            raise _fail("quadratures", list(self.quadratures))
        if tuple(self.frames) != ("fixed",):
            raise _fail("frames", list(self.frames))
        if (
            not self.sensors
            or any(not _is_int(c) or not 0 <= c < len(SENSOR_NAMES) for c in self.sensors)
            or len(set(self.sensors)) != len(self.sensors)
        ):
            raise _fail("sensors", list(self.sensors))
        if not _is_int(self.delay_periods) or not 1 <= self.delay_periods <= 16:
            raise _fail("delay_periods", self.delay_periods)
        if self.controller not in CONTROLLERS:
            raise _fail("controller", self.controller)
        if self.response not in RESPONSES:
            raise _fail("response", self.response)
        if not (_finite(self.w) and 0.0 < self.w < 1.0):
            raise _fail("w", self.w)
        if not (_finite(self.v) and 0.0 <= self.v < 1.0):
            raise _fail("v", self.v)
        if not (_finite(self.rate) and 0.0 < self.rate < 1.0):
            raise _fail("rate", self.rate)
        if self.response == "series" and (
            not self.series or not all(_finite(c) for c in self.series) or self.series[0] == 0
        ):
            raise _fail("series", list(self.series))
        if not (_finite(self.gain) and self.gain > 0.0):
            raise _fail("gain", self.gain)
        if not _is_int(self.inverse_order) or not 0 <= self.inverse_order <= 50:
            raise _fail("inverse_order", self.inverse_order)
        if not (_finite(self.inverse_regularisation) and self.inverse_regularisation >= 0):
            raise _fail("inverse_regularisation", self.inverse_regularisation)
        if not (_finite(self.predictor_dc_weight) and self.predictor_dc_weight >= 0):
            raise _fail("predictor_dc_weight", self.predictor_dc_weight)
        if not _is_int(self.horizon) or not 1 <= self.horizon <= 200:
            raise _fail("horizon", self.horizon)
        if not _is_int(self.moves) or not 1 <= self.moves <= self.horizon:
            raise _fail("moves", self.moves, f"an integer in 1..horizon = {self.horizon}")
        for name in ("move_weight", "input_weight"):
            if not (_finite(getattr(self, name)) and getattr(self, name) >= 0):
                raise _fail(name, getattr(self, name))
        if len(self.force_limit) != N_AXES or not all(
            _finite(f) and f > 0 for f in self.force_limit
        ):
            raise _fail("force_limit", list(self.force_limit))
        if not (isinstance(self.max_model_radius, int | float) and self.max_model_radius > 0):
            raise _fail("max_model_radius", self.max_model_radius)
        for name in ("coefficient_bound", "displacement_bound"):
            value = getattr(self, name)
            if not (isinstance(value, int | float) and value > 0):
                raise _fail(name, value)
        if not isinstance(self.contact_guard, bool):
            raise _fail("contact_guard", self.contact_guard)
        if not (_finite(self.growth_factor) and self.growth_factor > 1.0):
            raise _fail("growth_factor", self.growth_factor)
        if not _is_int(self.growth_periods) or self.growth_periods < 1:
            raise _fail("growth_periods", self.growth_periods)
        for fault, action in self.fault_actions.items():
            if action not in FAULT_ACTIONS or not 0 <= int(fault) <= 255:
                raise _fail("fault_actions", dict(self.fault_actions))
        if not isinstance(self.model_file, str):
            raise _fail("model_file", self.model_file)
        if not isinstance(self.early_model_file, str):
            raise _fail("early_model_file", self.early_model_file)
        if not _is_int(self.identification_order) or not 1 <= self.identification_order <= 60:
            raise _fail("identification_order", self.identification_order)
        if not (_finite(self.identification_amplitude) and self.identification_amplitude != 0):
            raise _fail("identification_amplitude", self.identification_amplitude)
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


_FIELDS = {f.name: f for f in fields(ControllerConfig)}
