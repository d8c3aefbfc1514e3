"""
Mode logic between the controller core and the ``wavelet_controller`` node.

Once per control period the node hands :meth:`WaveletControlSupervisor.step` the
measured coefficients of period k and publishes the returned :class:`Command` for
period ``k + delay``: control coefficients and their force samples (even in OFF mode,
as zeros, to keep the lock-step loop alive). Modes follow ``ControllerStatus``:

* ``OFF``: zero force, controller reset.
* ``IDENTIFYING``: the :class:`~amb_controller.identification.StepExperiment` drives
  the commands; the measured coefficients and the commands actually applied in each
  period feed the :class:`~amb_controller.identification.MarkovIdentifier`. When the
  last step has been followed by ``order`` settling periods the fit is made, stored
  in :attr:`identification_result`, and the mode returns to OFF.
* ``ACTIVE``: the controller (transient, proportional or moderated) runs; each command
  passes the :class:`~amb_controller.synthesis.ForceLimiter`. While any axis saturates
  the controller's state is held (not advanced: anti-windup) and the scaled command is
  sent.
* A command the plant did not apply (the period ran with zero wavelet force and its samples
  carry ``STATUS_COMMAND_MISSING``: lost, late, or the plant's watchdog) is reported with
  :meth:`WaveletControlSupervisor.command_missing`. The controller's step that computed it
  is undone (anti-windup, see "Commands the plant did not apply" below). A command a realtime
  plant applied from a later sample on (its samples flagged up to there) is then reported with
  :meth:`WaveletControlSupervisor.command_resumed`: the share that acted is recorded, and the
  step counts as made or undone, whichever is nearer what acted.
* ``HOLD``: no new correction; the controller state is frozen (fault reconfiguration,
  e.g. auxiliary-bearing contact). With ``hold_ramp_periods = 0`` the last command is
  repeated (hold-last); with ``hold_ramp_periods = n > 0`` the last command is scaled
  down linearly to zero over n periods (ramp-to-zero). After a divergence-guard trip the
  force is zero at once and only :meth:`reset` re-arms.

Hold-last or ramp-to-zero (decision)
------------------------------------
Thesis section 3.3.2 asks a reconfigurable controller to switch to the controller "most
suited" to the faulty plant and names the drawback: "it is essential to use the correct
controller". Once the rotor touches the auxiliary bearing the identified wavelet-domain
model (chapter 6, a linear rotor on its AMBs) no longer describes the plant: the rotor is
constrained by the auxiliary bearing and driven by its friction force (eq. 5.2), so the
last command, computed for the contact-free plant, is a stale open-loop force. What an
AMB engineer expects at touchdown is the certified levitation loop alone (here: the PID
the plant runs, the same as ``OFF``), without a force step: a step of the added force is
itself a step disturbance (eq. 8.3) that excites the rotor again. Ramp-to-zero gives
both; hold-last keeps cancelling a steady unbalance that the controller had already
removed (useful when the contact did not come from the controller's own force). Both
are reasonable, so both exist; the default here stays hold-last (``0``) for the existing
node and supervisor contract. On the figure-5.27 case-2 scenario (controller engaged at the
mass-loss alarm, HOLD at the contact event) ramp-to-zero makes fewer contacts than
hold-last: ``amb-compare`` rows ``wavelet_reconf_alarm`` and ``wavelet_reconf_alarm_ramp``
of ``contact_case2``, docs/results.md#compare (the first run: ``docs/controller_notes.md``).
On contact, ramp-to-zero is the contact-safe setting. Leaving a ramped
HOLD for ACTIVE resets the controller, because the force actually applied is no longer
the one its integral state (``beta``, eq. 8.10) remembers.

A controller its own model says diverges
---------------------------------------
An added controller must never make the rotor worse than the PID loop it is added to. The one
check that needs no run is the closed loop of the controller on the model it was designed from
(:func:`~amb_controller.stability.own_model_radius`, eq. 8.12 with the truncated inverse of
eq. 6.35): with the four inner sensors at the third critical speed ``G(1)`` is nearly singular
and that radius is 1.03, and every such controller diverged in the simulator (to tens of mm
against the 0.75 mm auxiliary clearance). So a controller whose radius is at or above
``max_radius`` (:data:`~amb_controller.stability.MAX_MODEL_RADIUS` = 0.98 by default) is not
set ACTIVE: :meth:`WaveletControlSupervisor.set_mode` refuses with the radius and the limit,
and :attr:`~WaveletControlSupervisor.message` (the status) says so. A new model or a
run-time change of the prescribed response that makes a running controller unsafe switches
it OFF with the same reason. The check is only as good as the model: a radius below the
limit does not promise a stable loop on the plant (contacts, saturation and model error are
outside it).

Commands the plant did not apply
--------------------------------
The transient controller integrates (``beta`` has its pole at z = 1, eq. 8.10): each period
it adds to the force it believes is acting. If its commands stop reaching the plant (a lost
or late command, the plant's command watchdog after a stall, a controller restarted while
the plant runs on its PID) the measured coefficients keep the disturbance's full size and the
integrators wind up; when a command gets through again the force is far too large (measured
in process with the mass loss at the first critical speed: ``docs/controller_notes.md``,
"Commands the plant did not apply"). So a missing command is treated like a saturated one: the
step that computed it did not happen. The controller's state is restored to what it was
before that step (the step is skipped, as the saturation hold does) and the steps after it,
which the delay ``i > 1`` has already made, are made again from it (their commands are
already sent and stand; only the state is corrected). The integrators then hold the force
that last acted, and a new controller whose commands never arrived stays at its initial
state, so its first applied command is the prescribed response to the disturbance as it is.

A controller with ``tracks_applied`` (the predictive one, :mod:`amb_controller.predictive`) has
no integrator to wind up: it estimates the disturbance from the inputs the plant applied. It is
told them instead (``record_applied``: the limited command, the HOLD command, zero for a lost
one) and is neither held on saturation nor replayed.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from enum import IntEnum

import numpy as np

from amb_common.faults import FINAL, PROVISIONAL, WITHDRAWN, FaultType
from amb_controller.command_ledger import CommandLedger, Step
from amb_controller.errors import ControllerValueError, NotIdentifiedError
from amb_controller.guard import DivergenceGuard
from amb_controller.identification import IdentificationResult, MarkovIdentifier, StepExperiment
from amb_controller.stability import MAX_MODEL_RADIUS
from amb_controller.synthesis import ForceLimiter


class Mode(IntEnum):
    """Controller modes, numbered as ``amb_msgs/ControllerStatus.MODE_*``."""

    OFF = 0
    IDENTIFYING = 1
    ACTIVE = 2
    HOLD = 3


#: FaultEvent.fault_type values (amb_msgs/FaultEvent.msg).
AUX_BEARING_CONTACT = int(FaultType.AUX_BEARING_CONTACT)
COIL_FAILURE = int(FaultType.COIL_FAILURE)
#: The reconfiguration on a fault (thesis 3.3.2): on a contact hold the force that acts (the
#: rotor touches; a changing force would rub it on), on a coil or amplifier failure stop (the
#: plant the model was identified on has lost an actuator axis: its commands no longer mean
#: what they did; the PID carries on).
DEFAULT_FAULT_ACTIONS = {AUX_BEARING_CONTACT: "hold", COIL_FAILURE: "off"}


@dataclass(frozen=True)
class Command:
    """
    One command for a future control period (maps onto ``ControlCommand``).

    Attributes
    ----------
    target_period : int
        Period ``k + delay`` the command is for.
    based_on_period : int
        Last measured period used (k).
    coefficients : numpy.ndarray
        Control coefficients in the control-basis order (N * sqrt(samples)).
    force : numpy.ndarray
        Force samples, shape ``(n_axes, samples_per_period)`` (N).
    mode : Mode
        Mode in force when the command was made.
    hold : bool
        True when the controller is holding (no new correction).
    saturated : numpy.ndarray of bool
        Per axis.
    guard_tripped : bool
        Divergence guard state.
    message : str
        Reason for the current mode.

    """

    target_period: int
    based_on_period: int
    coefficients: np.ndarray
    force: np.ndarray
    mode: Mode
    hold: bool
    saturated: np.ndarray
    guard_tripped: bool
    message: str = ""


@dataclass
class _Identification:
    experiment: StepExperiment
    identifier: MarkovIdentifier
    last_measured_period: int = field(init=False)

    def __post_init__(self) -> None:
        self.last_measured_period = (
            self.experiment.start_period + self.experiment.n_periods + self.identifier.order - 1
        )


class WaveletControlSupervisor:
    """
    Modes, saturation, guard and identification around one controller.

    Parameters
    ----------
    limiter : ForceLimiter
        Synthesis and per-axis force limit (defines the control coefficient layout).
    delay : int
        Evaluation delay ``i`` >= 1 in periods (commands are for ``k + delay``).
    controller : object, optional
        A controller with ``step``, ``reset``, ``skip``, ``get_state``, ``set_state``,
        ``delay`` (:class:`~amb_controller.transient.TransientController` or
        :class:`~amb_controller.steady_state.ProportionalController`).
    guard : DivergenceGuard, optional
        Divergence guard.
    fault_actions : dict of int to str, optional
        ``FaultEvent.fault_type`` -> ``"hold"``, ``"off"`` or ``"ignore"``
        (default: hold on auxiliary-bearing contact).
    hold_ramp_periods : int, optional
        Periods over which HOLD ramps the held command linearly to zero (>= 0; 0: repeat
        the last command, hold-last). Module docstring, "Hold-last or ramp-to-zero".
    max_radius : float, optional
        Largest closed-loop spectral radius on the controller's own model with which it may
        be ACTIVE (module docstring, "A controller its own model says diverges").

    """

    def __init__(
        self,
        limiter: ForceLimiter,
        delay: int,
        controller=None,
        guard: DivergenceGuard | None = None,
        fault_actions: dict[int, str] | None = None,
        hold_ramp_periods: int = 0,
        max_radius: float = MAX_MODEL_RADIUS,
    ) -> None:
        if int(delay) != delay or delay < 1:
            raise ControllerValueError(f"delay must be an integer >= 1 period, got {delay}")
        if int(hold_ramp_periods) != hold_ramp_periods or hold_ramp_periods < 0:
            raise ControllerValueError(
                f"hold_ramp_periods must be an integer >= 0 periods, got {hold_ramp_periods}"
            )
        if not max_radius > 0:
            raise ControllerValueError(f"max_radius must be > 0, got {max_radius}")
        self.hold_ramp_periods = int(hold_ramp_periods)
        self.max_radius = float(max_radius)
        self.radius: float | None = None
        self.limiter = limiter
        self.delay = int(delay)
        self.guard = guard
        self.fault_actions = dict(DEFAULT_FAULT_ACTIONS if fault_actions is None else fault_actions)
        for action in self.fault_actions.values():
            if action not in ("hold", "off", "ignore"):
                raise ControllerValueError(f"fault action must be hold/off/ignore, got {action!r}")
        self._ledger = CommandLedger(limiter.basis)  # commands sent, steps, lost ones undone
        self.controller = None
        self._provisional_hold = False  # the HOLD was entered on a provisional fault class
        self.mode = Mode.OFF
        self.message = "off"
        if controller is not None:
            self.set_controller(controller)
        self.identification_result: IdentificationResult | None = None
        self._identification: _Identification | None = None
        self._last = np.zeros(limiter.basis.n_coefficients)
        self._held: np.ndarray | None = None  # command at HOLD entry (ramp-to-zero)
        self._held_periods = 0

    # ------------------------------------------------------------------ configuration
    def set_controller(self, controller, radius: float | None = None) -> None:
        """
        Install a controller (its delay must equal the supervisor's).

        Parameters
        ----------
        controller : object
            As the constructor's.
        radius : float, optional
            Its closed-loop spectral radius on its own model
            (:func:`~amb_controller.stability.own_model_radius`; None: not known, not checked).
            At or above ``max_radius`` it may not go ACTIVE, and a running one (ACTIVE or
            HOLD) is switched OFF with the reason in :attr:`message`.

        """
        if getattr(controller, "delay", None) != self.delay:
            raise ControllerValueError(
                f"controller delay {getattr(controller, 'delay', None)} differs from the "
                f"supervisor's {self.delay}"
            )
        if controller.n_outputs != self.limiter.basis.n_coefficients:
            raise ControllerValueError(
                f"controller gives {controller.n_outputs} control coefficients, the control "
                f"basis has {self.limiter.basis.n_coefficients}"
            )
        self.controller = controller
        self.radius = None if radius is None else float(radius)
        self.reset_controller()
        refusal = self.unsafe_reason()
        if refusal and self.mode in (Mode.ACTIVE, Mode.HOLD):
            self.set_mode(Mode.OFF)
            self.message = f"off: {refusal}"

    def unsafe_reason(self) -> str:
        """Why the installed controller may not go ACTIVE on its own model ('' if it may)."""
        if self.radius is None or self.radius < self.max_radius:
            return ""
        return (
            f"closed loop on its own model has spectral radius {self.radius:.3f} >= "
            f"max_model_radius {self.max_radius:g}: it would "
            + ("diverge" if self.radius >= 1.0 else "hardly decay")
            + "; the PID loop carries on alone (identify again, change w, v, delay or sensors)"
        )

    def set_mode(self, mode: Mode) -> tuple[bool, str]:
        """
        Request OFF, ACTIVE or HOLD (IDENTIFYING via :meth:`start_identification`).

        Returns
        -------
        tuple of (bool, str)
            Accepted, and the reason (as ``SetControllerMode`` returns).

        """
        mode = Mode(mode)
        if mode == Mode.IDENTIFYING:
            return False, "use start_identification() to enter IDENTIFYING"
        if mode == Mode.ACTIVE:
            if self.controller is None:
                return False, "no controller model loaded: identify or load a model first"
            refusal = self.unsafe_reason()
            if refusal:
                self.message = f"{self.mode.name.lower()}: ACTIVE refused: {refusal}"
                return False, f"ACTIVE refused: {refusal}"
            if self.guard is not None and self.guard.tripped:
                return False, f"divergence guard tripped ({self.guard.reason}); reset() first"
            if self.mode != Mode.HOLD or self._held_periods > 0:
                self.reset_controller()  # a ramped hold applied less than it remembers
        if mode == Mode.OFF:
            self._identification = None
            if self.controller is not None:
                self.reset_controller()
        self._enter(mode)
        self.message = mode.name.lower()
        return True, self.message

    def _enter(self, mode: Mode) -> None:
        """Switch to ``mode``; entering HOLD starts the ramp from the last command."""
        if mode == Mode.HOLD and self.mode != Mode.HOLD:
            self._held = self._last.copy()
            self._held_periods = 0
        elif mode != Mode.HOLD:
            self._held = None
            self._held_periods = 0
        self._provisional_hold = False  # on_fault sets it after entering a HOLD
        self.mode = mode

    def start_identification(self, experiment: StepExperiment, identifier: MarkovIdentifier):
        """Enter IDENTIFYING with this excitation and estimator."""
        if experiment.n_inputs != self.limiter.basis.n_coefficients:
            raise ControllerValueError(
                f"experiment has {experiment.n_inputs} inputs, control basis "
                f"{self.limiter.basis.n_coefficients}"
            )
        identifier.reset()
        self._identification = _Identification(experiment, identifier)
        self.identification_result = None
        self.mode = Mode.IDENTIFYING
        self.message = "identifying"

    def on_fault(self, fault_type: int, status: str = "", revised: bool = False) -> str:
        """
        Apply the configured reconfiguration for a fault event; return the action.

        Parameters
        ----------
        fault_type : int
            ``FaultEvent.fault_type``.
        status : str
            The event's ``status`` evidence: ``""`` (a monitor without provisional classes),
            ``"provisional"`` or ``"final"`` act alike (the reconfiguration acts on the earliest
            class); ``"withdrawn"`` (a provisional class that turned out to be another
            fault's consequence) takes no action of its own.
        revised : bool
            A final event's ``revised`` evidence: its provisional class was another.

        Returns
        -------
        str
            ``"hold"``, ``"off"`` or ``"ignore"`` (the configured action), or ``"resume"``: a
            HOLD entered on a provisional class was left for ACTIVE because that class was
            withdrawn or revised, and the final class asks for nothing else.
        """
        resumed = False
        if (
            self._provisional_hold
            and self.mode == Mode.HOLD
            and (status == WITHDRAWN or (status == FINAL and revised))
        ):
            resumed, why = self.set_mode(Mode.ACTIVE)
            self.message = (
                f"active again: the provisional fault was {status}"
                if resumed
                else f"hold: the provisional fault was {status}, but {why}"
            )
        if status == WITHDRAWN:
            return "resume" if resumed else "ignore"
        action = self.fault_actions.get(int(fault_type), "ignore")
        if action == "hold" and self.mode == Mode.ACTIVE:
            self._enter(Mode.HOLD)
            self._provisional_hold = status == PROVISIONAL
            self.message = f"hold on fault {fault_type}"
        elif action == "off" and self.mode in (Mode.ACTIVE, Mode.HOLD):
            self.set_mode(Mode.OFF)
            self.message = f"off on fault {fault_type}"
        elif resumed:
            return "resume"
        return action

    def reset(self) -> None:
        """Return to OFF, re-arm the guard and forget sent commands."""
        if self.guard is not None:
            self.guard.reset()
        self.set_mode(Mode.OFF)
        self._ledger.clear()
        self._last = np.zeros(self.limiter.basis.n_coefficients)

    @property
    def tracks_applied(self) -> bool:
        """Whether the controller in use is told the applied inputs (predictive), not held."""
        return bool(getattr(self.controller, "tracks_applied", False))

    def sent(self, target: int) -> np.ndarray | None:
        """The coefficients sent for period ``target`` (None: none kept for it)."""
        return self._ledger.sent(target)

    def replace_command(self, command: Command, coefficients: np.ndarray) -> Command:
        """
        ``command`` with ``coefficients`` (limited) instead of the controller's own.

        The replacement is what is sent for ``command.target_period`` and what a controller
        told the applied inputs records as applied (only such a controller may have its
        commands replaced: another would keep its own command in its state). The early
        action holds the feedback law this way while its plan alone acts (:class:`amb_controller
        .early_action.EarlyActionConfig`, ``hold_law``).
        """
        if not self.tracks_applied:
            raise ControllerValueError("only a law told the applied inputs may be overridden")
        result = self.limiter.apply(np.asarray(coefficients, dtype=float))
        target = command.target_period
        self._ledger.record(target, result.coefficients)
        self._last = result.coefficients
        self.controller.record_applied(target, result.coefficients)
        return replace(
            command,
            coefficients=result.coefficients,
            force=result.force,
            saturated=result.saturated,
        )

    def reset_controller(self) -> None:
        """Reset the controller's state (integrators and history to zero)."""
        self.controller.reset()
        self._ledger.forget_steps()  # nothing of before the reset is taken back

    def command_missing(self, period_index: int) -> bool:
        """
        Report that period ``period_index`` ran with zero wavelet force, without its command.

        The plant flags such a period's samples ``STATUS_COMMAND_MISSING``. The command sent
        for it, if any, is undone: the controller returns to its state before the step that
        made it, that step counts as skipped, and later steps are made again (module notes,
        "Commands the plant did not apply"). What the period applied is recorded as zero
        (:meth:`applied`, the identification's input).

        Call it at the period's first flagged sample, before the period's own step; later
        calls for the same period are ignored.

        Parameters
        ----------
        period_index : int
            The period that ran without a command.

        Returns
        -------
        bool
            True if this supervisor had sent a command for the period (it was lost or late)
            and this is the first report of the period.

        """
        return self._ledger.missing(period_index, self.controller, self.tracks_applied)

    def command_resumed(self, period_index: int, position: int) -> bool:
        """
        Report that period ``period_index``, flagged missing, ran with its command from a sample on.

        A realtime plant with partial commands (``plant_sim``'s ``partial_commands``) applies a
        command that arrives during its period to the samples still ahead: the period's samples
        carry ``STATUS_COMMAND_MISSING`` up to ``position`` and none from there. The share that
        acted is recorded (:meth:`applied`) and the undo is taken back or kept, whichever is
        nearer what acted (:meth:`amb_controller.command_ledger.CommandLedger.resumed`).

        Parameters
        ----------
        period_index : int
            The period, reported by :meth:`command_missing` at its first sample.
        position : int
            Its first sample without the flag, ``0 < position < N``.

        Returns
        -------
        bool
            True if this supervisor had sent a command for the period and this is the first
            such report; else nothing is changed.
        """
        return self._ledger.resumed(period_index, position, self.controller, self.tracks_applied)

    def record_zero(self, target_period: int) -> None:
        """Record a zero-force command for ``target_period`` sent outside :meth:`step`.

        The pipeline answers an incomplete period with zero force; :meth:`applied` and the
        undo of lost commands must know it.
        """
        self._ledger.record(target_period, self._ledger.zeros)

    def applied(self, period_index: int) -> np.ndarray:
        """Return the control coefficients commanded for ``period_index`` (zeros if none)."""
        return self._ledger.applied(period_index)

    # ------------------------------------------------------------------ period step
    def step(self, period_index: int, measured: np.ndarray, displacement_peak=None) -> Command:
        """
        Consume period k; return the command for period ``k + delay``.

        Parameters
        ----------
        period_index : int
            Measured period k.
        measured : numpy.ndarray
            Measured coefficients of period k (controller input layout).
        displacement_peak : float or numpy.ndarray, optional
            Largest absolute displacement over period k in m, overall or per probe channel
            (for the guard: :meth:`DivergenceGuard.update`).

        Returns
        -------
        Command

        """
        k = int(period_index)
        target = k + self.delay
        zeros = np.zeros(self.limiter.basis.n_coefficients)
        hold = False
        guard_tripped = False
        if self.guard is not None and self.mode != Mode.OFF:
            was = self.guard.tripped
            guard_tripped = self.guard.update(measured, displacement_peak)
            if guard_tripped and not was:
                self._enter(Mode.HOLD)
                self.message = f"guard: {self.guard.reason}"
                if self.controller is not None:
                    self.reset_controller()
        result = None
        running = self.mode in (Mode.ACTIVE, Mode.HOLD) and self.controller is not None
        tracks = running and self.tracks_applied
        # the state before the step, for the anti-windup hold and the replay of a lost command;
        # a controller told the applied inputs needs neither (module docstring)
        saved = self.controller.get_state() if running and not tracks else None
        if self.mode == Mode.IDENTIFYING:
            coefficients = self._identify(k, measured, target)
        elif self.mode == Mode.ACTIVE:
            coefficients = self.controller.step(k, measured).coefficients
            result = self.limiter.apply(coefficients)
            if result.saturated.any():
                if not tracks:
                    self.controller.set_state(saved)  # anti-windup: hold the state
                    self.controller.skip(k)
                hold = True
        elif self.mode == Mode.HOLD:
            hold = True
            if self.controller is not None and not guard_tripped:
                self.controller.skip(k)
            coefficients = zeros if guard_tripped else self._hold_command()
        else:
            coefficients = zeros
        if tracks and not guard_tripped:
            self._ledger.steps[target] = Step(k, None, None, hold)  # a marker: it ran
        elif running and not guard_tripped:
            self._ledger.steps[target] = Step(k, np.array(measured, dtype=float), saved, hold)
        else:
            self._ledger.steps.clear()  # the controller was reset or is not running
        if result is None:
            result = self.limiter.apply(coefficients)
        if tracks and not guard_tripped:
            self.controller.record_applied(target, result.coefficients)
        self._last = result.coefficients
        self._ledger.record(target, result.coefficients)
        self._ledger.prune(k, self.delay)
        return Command(
            target,
            k,
            result.coefficients,
            result.force,
            self.mode,
            hold,
            result.saturated,
            bool(self.guard is not None and self.guard.tripped),
            self.message,
        )

    def _hold_command(self) -> np.ndarray:
        """
        Command of one HOLD period: the last one, or its linear ramp to zero.

        With ``n = hold_ramp_periods > 0`` the j-th HOLD period (j = 1, 2, ...) sends
        ``max(0, 1 - j/n)`` times the command in force at HOLD entry: the force is linear
        in the control coefficients (eq. 6.7), so its amplitude falls linearly to zero
        over n periods and stays zero.
        """
        if self.hold_ramp_periods == 0 or self._held is None:
            return self._last
        self._held_periods += 1
        return max(0.0, 1.0 - self._held_periods / self.hold_ramp_periods) * self._held

    def _identify(self, k: int, measured: np.ndarray, target: int) -> np.ndarray:
        ident = self._identification
        if k >= ident.experiment.start_period:
            ident.identifier.update(k, self.applied(k), measured)
        if k >= ident.last_measured_period:
            try:
                self.identification_result = ident.identifier.estimate()
                self.message = f"identified from {ident.identifier.n_periods} periods"
            except NotIdentifiedError as exc:
                self.message = f"identification failed: {exc}"
            self._identification = None
            self.mode = Mode.OFF
            return np.zeros(self.limiter.basis.n_coefficients)
        return ident.experiment.command(target)

    @property
    def identification_progress(self) -> float:
        """Fraction 0..1 of the running identification (1 when none is running)."""
        if self._identification is None:
            return 1.0
        ident = self._identification
        last = ident.last_measured_period
        done = ident.identifier.n_periods + ident.identifier.order
        return float(min(1.0, done / max(1, last - ident.experiment.start_period + 1)))
