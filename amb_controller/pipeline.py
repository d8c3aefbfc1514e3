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
from dataclasses import replace
from pathlib import Path

import numpy as np

from amb_controller.command_ledger import MISSING, RESUMED, MissingFlags
from amb_controller.config import (
    BASELINE_CONTROLLERS,
    N_AXES,
    SENSOR_NAMES,
    ConfigError,
    ControllerConfig,
)
from amb_controller.early_action import EarlyActionConfig
from amb_controller.early_model import EarlyActionModel, EarlyModelBank
from amb_controller.early_stage import EarlyStage
from amb_controller.errors import ControllerValueError
from amb_controller.identification import MarkovIdentifier, StepExperiment
from amb_controller.inverse import dc_gain, pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.predictive import PredictiveController
from amb_controller.selection import (
    controller_guard,
    prescribed_response,
    selected_control_basis,
    selected_measurement_basis,
)
from amb_controller.stability import own_model_radius
from amb_controller.status import status_fields
from amb_controller.steady_state import (
    ProportionalController,
    SteadyStatePredictor,
    steady_state_operator,
)
from amb_controller.supervisor import Command, Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController
from amb_wavelet.frontend import ChannelFrontEnd

__all__ = ["ControllerPipeline"]


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
    probe_clearance : tuple of float, optional
        Per probe channel, the clearance of the auxiliary bearing next to it, m
        (``rig.probe_clearance``; None: not known), for the guard
        (:func:`~amb_controller.selection.controller_guard`).

    """

    def __init__(
        self,
        config: ControllerConfig,
        capacity: float,
        model: WaveletModel | None = None,
        channel_labels=None,
        probe_clearance: tuple[float, ...] | None = None,
    ) -> None:
        config.check_capacity(capacity)
        self.config = config
        self.capacity = float(capacity)
        n = config.period_samples
        self.samples_per_period = n
        self._r = n.bit_length() - 1
        self.control = selected_control_basis(config)
        self.measured = selected_measurement_basis(config)
        if channel_labels is None:
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
        guard = controller_guard(config, probe_clearance)
        self.supervisor = WaveletControlSupervisor(
            self.limiter,
            config.delay_periods,
            guard=guard,
            fault_actions=config.fault_actions,
            max_radius=config.max_model_radius,
        )
        self._model: WaveletModel | None = None
        self._model_file = ""
        self._omega = 0.0
        self._stats = {
            "commands_sent": 0,
            "commands_late": 0,
            "commands_partial": 0,
            "inputs_rejected": 0,
        }
        self._compute_time = 0.0
        self._flags = MissingFlags()  # the samples' STATUS_COMMAND_MISSING
        self._last_command: Command | None = None
        self._last_period = -1
        self._period_message = ""
        self._expected: int | None = None
        self.last_measured: np.ndarray | None = None
        self.early: EarlyStage | None = None
        #: the early action's decision at the last period's end (None: none)
        self.early_detection = None
        #: (last period whose command the early action holds, the held coefficients)
        self._law_hold: tuple[int, np.ndarray | None] = (-1, None)
        self._new_period(None)
        if model is None and config.model_file:
            model = WaveletModel.load(config.model_file)
            self._model_file = str(config.model_file)
        if model is not None:
            self.set_model(model)
        if config.early_model_file:
            self.set_early_model(EarlyModelBank.load(config.early_model_file))

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
            self.set_controller(controller)
        else:
            self.supervisor.controller = None

    def set_early_model(
        self, model: EarlyModelBank | EarlyActionModel, config: EarlyActionConfig | None = None
    ) -> None:
        """Add the early action on a sudden unbalance (:mod:`amb_controller.early_action`).

        ``model``: a bank of models at several speeds, or one model (:mod:`.early_model`);
        ``config``: its settings (default: the defaults).
        """
        self.early = EarlyStage.from_model(
            model, self.config.delay_periods, self.samples_per_period, config
        )

    def set_controller(self, controller) -> None:
        """
        Install ``controller`` (built elsewhere, e.g. multi-level) on the model in use.

        Its closed-loop spectral radius on that model is computed here
        (:func:`~amb_controller.stability.own_model_radius`, a few to tens of ms): at or above
        ``max_model_radius`` it may not go ACTIVE, and a running one is switched OFF
        (:class:`~amb_controller.supervisor.WaveletControlSupervisor`).
        """
        radius = None if self._model is None else own_model_radius(self._model.markov, controller)
        self.supervisor.set_controller(controller, radius)

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
        if cfg.controller == "predictive":
            return PredictiveController(
                model.markov, i, cfg.horizon, cfg.moves, cfg.move_weight, cfg.input_weight
            )
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

    def on_fault(self, fault_type: int, status: str = "", revised: bool = False) -> str:
        """Apply the action for a FaultEvent (:meth:`WaveletControlSupervisor.on_fault`)."""
        return self.supervisor.on_fault(int(fault_type), status, revised)

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
        flag = self._flags.observe(m, pos, command_missing)
        if flag == MISSING:
            if self.supervisor.command_missing(m):
                self._stats["commands_late"] += 1
            if self.early is not None:
                self.early.command_missing(m)
        elif flag == RESUMED:  # applied from sample pos on (partial_commands)
            if self.supervisor.command_resumed(m, pos):
                self._stats["commands_partial"] += 1
            if self.early is not None:
                self.early.command_resumed(m, pos)
        if displacement is not None:
            d = np.asarray(displacement, dtype=float)
            if self.early is not None:
                self.early.sample(pos, d, self._omega)
            self._peak = np.maximum(self._peak, np.abs(d))  # per probe (the contact guard)
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
        if self.early is not None:  # issue 18 item 4: amb_controller.early_action
            command = self._with_early_action(m, command, complete)
        self._last_period = m
        self._last_command = command
        self._stats["commands_sent"] += 1
        self._compute_time = time.perf_counter() - t0
        self._new_period(None)
        return command

    def _with_early_action(self, m: int, command: Command, complete: bool) -> Command:
        """
        ``command`` with the early action's plan added, and the law held while the plan acts.

        With ``hold_law`` (and a law told the applied inputs) the law's commands made from
        measurements without the plan's effect, and at ``i >= 2`` from the plan's transient
        periods, are replaced by its command made before the change's onset (module docstring
        of :mod:`amb_controller.early_action`, "The feedback law").
        """
        early, sup = self.early, self.supervisor
        active = sup.mode == Mode.ACTIVE
        limit = self.limiter.limit
        detection = early.test(m, complete, limit)
        if active and early.config.hold_law and sup.tracks_applied:
            if detection is not None and detection.acted:
                onset_period = detection.onset_sample // self.samples_per_period
                made = sup.sent(onset_period + sup.delay - 1)  # made before the onset
                if made is not None:
                    until = m + sup.delay - 1 + self._transient_periods(sup.delay)
                    self._law_hold = (until, made)
            until, held = self._law_hold
            if m <= until:
                command = sup.replace_command(command, held)
        force, clipped = early.compose(command.target_period, command.force, active, limit)
        self.early_detection = detection
        return replace(command, force=force, saturated=np.asarray(command.saturated) | clipped)

    def _transient_periods(self, delay: int) -> int:
        """Periods of the plan's transient force during which the law is also held (i >= 2)."""
        if delay < 2:
            return 0
        return -(-self.early.config.transient_samples // self.samples_per_period)

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
        sup.record_zero(target)
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
    def count_rejected_input(self) -> None:
        """Count an input refused before it reached :meth:`on_sample` (``inputs_rejected``)."""
        self._stats["inputs_rejected"] += 1

    def status(self) -> dict:
        """
        Return the ``ControllerStatus`` fields as a dict (the node copies them).

        Keys: mode, controller, period_index, delay_periods, compute_time (s),
        peak_wavelet_force (4 N), saturated, guard_tripped, identification_progress,
        commands_sent, commands_late, commands_partial (of the late, those the plant applied from
        a later sample on), inputs_rejected, model_file, message.
        """
        return status_fields(self, float(self.supervisor.identification_progress), self._model_file)


def _rank_rtol(config: ControllerConfig) -> float:
    """Singular-value cutoff of the steady-state predictor's inverse (eq. 6.35, 7.6).

    At thesis level p >= 2 the odd control waveforms (the even ones shifted by a quarter
    revolution) are linearly dependent on the even ones, so ``G(1)`` of those levels has exact
    null directions that no input can move (singular values at rounding level). The
    predictor's ``B(1) G(1) = I`` weight then inverts rounding noise, so its inverse is the
    truncated-SVD one. The transient controller keeps the plain inverse: on the coupled
    1x+2x+4x FE loop the truncated one made the exact closed loop less stable
    (``docs/controller_notes.md``, "Truncated-SVD inverse at p >= 2"). At p = 1 alone nothing
    changes (0 = off).
    """
    return 1e-8 if max(config.levels) > 1 else 0.0


def _replace_inverse(model: WaveletModel, inverse: np.ndarray) -> WaveletModel:
    return replace(model, inverse=inverse)
