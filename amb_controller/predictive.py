"""
Receding-horizon (predictive) controller on the identified Markov parameters (issue 18, item 2).

The transient controller of eq. 8.10 inverts the model, ``(G B_u)^*`` of eq. 6.35. The 1 x
coefficient-domain model of the rig has zeros outside the unit circle (|z| ~ 1.3 at the first
critical speed), which no stable truncated inverse equalises; at the third critical the
inverse makes the loop unstable on its own model. This controller never forms an inverse: it
predicts the measured coefficients with the Markov parameters and chooses the commands that
minimise a quadratic cost of the prediction, the classical dynamic matrix control of Cutler and
Ramaker (1980) in the coefficient domain. Everything it needs is what the on-line
identification (section 6.4) gives: ``A^(0) .. A^(M)``.

Formulation
-----------
Model (eq. 6.34 with the same-period term, :mod:`amb_controller.inverse`), per period k::

    q[k] = sum_{j=0}^{M} A_j u[k-j] + d[k]

with ``u`` the control coefficients applied over a period and ``d`` all that the control did
not cause (the unbalance response through the PID loop, a fault). At the end of period k the
commands up to ``u[k+i-1]`` are decided (``i`` the delay), so the disturbance is estimated with
the inputs the plant really applied (the force limiter's output, zeros for a lost command)::

    d^[k] = q[k] - sum_j A_j u[k-j]                                             (P1)

and held constant over the horizon (a mass loss or a step force is a step of unbalance: its
steady coefficient response is constant). With the decision ``U = (u[k+i], ..,
u[k+i+C-1])`` (``C`` moves, the last one held) the predicted coefficients are::

    q^[k+i+h] = sum_j A_j u[k+i+h-j] + d^[k],   h = 0 .. P-1                    (P2)
              = Phi_h U + f_h[k]

(``f_h`` the free response: decided inputs and ``d^``), and the command minimises::

    J = sum_{h<P} ( || q^[k+i+h] ||^2 + sigma^2 || u[k+i+h] ||^2 )
        + rho^2 sum_{c<C} || u[k+i+c] - u[k+i+c-1] ||^2                           (P3)

``rho = move_weight * sigma_max(G(1))`` and ``sigma = input_weight * sigma_max(G(1))``
(``G(1) = sum_j A_j``), so both weights are dimensionless. ``move_weight = 0`` asks for the
fastest cancellation the model allows, larger values slow the moves. ``input_weight`` is a
Tikhonov term: in steady state the command is ``-(G^T G + sigma^2 I)^-1 G^T d^``, so directions
of ``G(1)`` whose singular value is well above ``sigma`` are cancelled (offset ``(sigma /
s_i)^2``) and those below it are left alone instead of being driven with forces the bearings
cannot give (the inner-sensor model at the third critical speed, where ``G(1)`` is nearly
singular). The minimiser is ``U* = (Phi^T Phi + rho^2 D^T D + sigma^2 W)^-1 (rho^2 D^T e
u[k+i-1] - Phi^T f)`` (``W`` counts the periods each move is applied); only its first block
is applied and the problem is posed again next period. All of (P1)-(P3) is linear, so the law
is one precomputed gain::

    u[k+i] = K [q[k]; u[k+i-1]; ..; u[k-M]]                                      (P4)

a matrix product of ``n_u x (n_y + (M + i) n_u)`` per period (8 x 120 for the 1 x model
with 8 control coefficients, M = 12, i = 2): microseconds.

Properties
----------
* Offset-free (``input_weight = 0``): at a steady state with ``u`` constant, (P1) makes ``d^``
  the true disturbance and the minimiser of (P3) removes the steady coefficients the inputs
  can reach (the integral action of eq. 8.10's ``beta`` comes from the disturbance estimate).
* With ``C = 1`` and ``P`` beyond the model's settling (mean-level control) the command jumps to
  the steady input that cancels the estimated disturbance, ``-G(1)^+ d^``, and no inverse of
  ``G(z)`` is formed: zeros outside the unit circle only cost performance.
* Its loop on its own model is checked like every controller's: :meth:`state_space` realises
  (P4) with the delay, and :func:`amb_controller.stability.own_model_radius` closes it around
  the FIR model.
* The force limit: the law is the unconstrained minimiser, limited per axis by the
  :class:`~amb_controller.synthesis.ForceLimiter`; since (P1) uses the applied (limited)
  inputs, the estimate is not wound up by saturation (the supervisor reports what was applied
  through :meth:`PredictiveController.record_applied`). A constrained quadratic programme is
  not solved.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.errors import ControllerValueError, PeriodSequenceError, ShapeError
from amb_controller.inverse import dc_gain
from amb_controller.lti import DiscreteStateSpace
from amb_controller.transient import ControlStep

__all__ = ["PredictiveController", "PredictiveState", "predictive_gain"]


def predictive_gain(
    markov: np.ndarray,
    delay: int,
    horizon: int,
    moves: int,
    move_weight: float,
    input_weight: float,
) -> np.ndarray:
    """
    Return the gain ``K`` of (P4): ``u[k+i] = K [q[k]; u[k+i-1]; ..; u[k-M]]``.

    Parameters
    ----------
    markov : numpy.ndarray
        ``A^(0) .. A^(M)``, shape ``(M + 1, n_y, n_u)`` (measured per control coefficient).
    delay : int
        Evaluation delay ``i`` >= 1, periods.
    horizon : int
        Prediction horizon ``P`` >= 1, periods after the first one the command reaches.
    moves : int
        Control moves ``C``, 1 <= C <= P (the last one is held to the horizon).
    move_weight : float
        Dimensionless ``rho / sigma_max(G(1))`` >= 0 of (P3).
    input_weight : float
        Dimensionless ``sigma / sigma_max(G(1))`` >= 0 of (P3): the weight of the command
        itself in every period of the horizon.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_u, n_y + (M + i) n_u)``.

    """
    markov = np.asarray(markov, dtype=float)
    if markov.ndim != 3 or not np.all(np.isfinite(markov)):
        raise ShapeError(f"markov must be a finite array (M+1, n_y, n_u), got {markov.shape}")
    for name, value, low in (("delay", delay, 1), ("horizon", horizon, 1), ("moves", moves, 1)):
        if int(value) != value or value < low:
            raise ControllerValueError(f"{name} must be an integer >= {low}, got {value}")
    if moves > horizon:
        raise ControllerValueError(f"moves ({moves}) must not exceed horizon ({horizon})")
    for name, value in (("move_weight", move_weight), ("input_weight", input_weight)):
        if not (np.isfinite(value) and value >= 0):
            raise ControllerValueError(f"{name} must be finite and >= 0, got {value}")
    n_terms, n_y, n_u = markov.shape
    m, i, p, c = n_terms - 1, int(delay), int(horizon), int(moves)
    n_past = m + i  # u[k+i-1] .. u[k-M]
    n_x = n_y + n_past * n_u

    def past(row: int) -> slice:  # u[k+i-1-row] in x
        return slice(n_y + row * n_u, n_y + (row + 1) * n_u)

    # (P1): d^ = q - sum_j A_j u[k-j],  u[k-j] is past row i-1+j
    d_hat = np.zeros((n_y, n_x))
    d_hat[:, :n_y] = np.eye(n_y)
    for j in range(n_terms):
        d_hat[:, past(i - 1 + j)] -= markov[j]
    # (P2): q^_h = Phi_h U + F_h x
    phi = np.zeros((p * n_y, c * n_u))
    free = np.zeros((p * n_y, n_x))
    for h in range(p):
        rows = slice(h * n_y, (h + 1) * n_y)
        free[rows] = d_hat
        for j in range(n_terms):
            if j <= h:  # u[k+i+h-j] is a decision, move min(h-j, C-1)
                move = min(h - j, c - 1)
                phi[rows, move * n_u : (move + 1) * n_u] += markov[j]
            else:  # decided already: past row j-h-1
                free[rows, past(j - h - 1)] += markov[j]
    # (P3): moves D U - E x, E picks u[k+i-1]
    diff = np.eye(c * n_u) - np.eye(c * n_u, k=-n_u)
    pick = np.zeros((c * n_u, n_x))
    pick[:n_u, past(0)] = np.eye(n_u)
    scale = np.linalg.norm(dc_gain(markov), 2)
    rho, sigma = float(move_weight) * scale, float(input_weight) * scale
    # sum over the horizon of ||u||^2: move c is applied once, the last one P - C + 1 times
    held = np.ones(c)
    held[-1] = p - c + 1
    lhs = phi.T @ phi + rho**2 * diff.T @ diff + sigma**2 * np.kron(np.diag(held), np.eye(n_u))
    rhs = rho**2 * diff.T @ pick - phi.T @ free
    try:
        solution = np.linalg.solve(lhs, rhs)
    except np.linalg.LinAlgError as exc:
        raise ControllerValueError(
            "the predictive cost has no unique minimiser (the model moves no coefficient in "
            "some control direction): use move_weight > 0"
        ) from exc
    return solution[:n_u]


@dataclass
class PredictiveState:
    """Explicit state of :class:`PredictiveController`: the applied inputs by period."""

    applied: dict[int, np.ndarray]
    last_period: int | None

    def copy(self) -> PredictiveState:
        """Return a deep copy."""
        return PredictiveState({p: u.copy() for p, u in self.applied.items()}, self.last_period)


class PredictiveController:
    """
    Receding-horizon controller (P1)-(P4) of the module docstring, period by period.

    Parameters
    ----------
    markov : numpy.ndarray
        Model ``A^(0) .. A^(M)``, shape ``(M + 1, n_y, n_u)``.
    delay : int
        Evaluation delay ``i`` >= 1, periods.
    horizon, moves, move_weight, input_weight
        ``P``, ``C`` and the dimensionless weights of (P3) (:func:`predictive_gain`; their
        defaults and ranges: :class:`~amb_controller.config.ControllerConfig`).

    Notes
    -----
    The controller remembers the inputs applied over the last ``M + i`` periods. It assumes it
    commanded what it returned from :meth:`step`; the supervisor corrects that with
    :meth:`record_applied` when the force limiter cut the command, a HOLD sent another one, or a
    command was lost (``tracks_applied``).
    """

    #: the supervisor reports the applied inputs instead of holding the state on saturation
    tracks_applied = True

    def __init__(
        self,
        markov: np.ndarray,
        delay: int,
        horizon: int,
        moves: int,
        move_weight: float,
        input_weight: float,
    ) -> None:
        self.gain = predictive_gain(markov, delay, horizon, moves, move_weight, input_weight)
        self.delay = int(delay)
        self.horizon, self.moves = int(horizon), int(moves)
        self.move_weight, self.input_weight = float(move_weight), float(input_weight)
        self.n_outputs = self.gain.shape[0]
        self.n_inputs = markov.shape[1]
        self._n_past = markov.shape[0] - 1 + self.delay
        self._state = PredictiveState({}, None)

    def reset(self) -> None:
        """Forget all past inputs (the plant ran with zero wavelet force)."""
        self._state = PredictiveState({}, None)

    def get_state(self) -> PredictiveState:
        """Return a copy of the explicit state."""
        return self._state.copy()

    def set_state(self, state: PredictiveState) -> None:
        """Restore a state returned by :meth:`get_state`."""
        self._state = state.copy()

    def skip(self, period_index: int) -> None:
        """Mark ``period_index`` consumed without a command of its own (zero until recorded)."""
        self._state.last_period = int(period_index)

    def record_applied(self, period_index: int, coefficients: np.ndarray) -> None:
        """Record what the plant applies over ``period_index`` (limited, held or zero)."""
        self._state.applied[int(period_index)] = np.array(coefficients, dtype=float)

    def step(self, period_index: int, measured: np.ndarray) -> ControlStep:
        """
        Consume the measured coefficients of period k; return the command for ``k + i``.

        Parameters
        ----------
        period_index : int
            k; must follow the previous one by 1 (:meth:`reset` after a gap).
        measured : numpy.ndarray
            ``q[k]``, shape ``(n_y,)``.

        Returns
        -------
        ControlStep

        """
        q = np.asarray(measured, dtype=float)
        if q.shape != (self.n_inputs,):
            raise ShapeError(f"measured must have shape ({self.n_inputs},), got {q.shape}")
        if not np.all(np.isfinite(q)):
            raise ControllerValueError(f"measured contains NaN or inf: {q}; reset() after it")
        k = int(period_index)
        state = self._state
        if state.last_period is not None and k != state.last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {state.last_period + 1} (previous + 1), got {k}; call "
                "reset() to restart after a missing period"
            )
        zero = np.zeros(self.n_outputs)
        top = k + self.delay - 1
        past = [state.applied.get(top - r, zero) for r in range(self._n_past)]
        command = self.gain @ np.concatenate([q, *past])
        state.applied[k + self.delay] = command
        for old in [p for p in state.applied if p <= top - self._n_past + 1]:
            del state.applied[old]
        state.last_period = k
        return ControlStep(k + self.delay, k, command)

    def state_space(self) -> DiscreteStateSpace:
        """
        Return (P4) with its delay, from measured to applied coefficients.

        States ``s[k] = (c[k-1], .., c[k-L])``, ``c[k] = u[k+i]`` the command made at the end
        of period k and ``L = M + i``: ``c[k] = K_q q[k] + K_u s[k]``, output ``u[k] =
        c[k-i]`` (no feed-through: the command acts ``i`` periods later).
        """
        n_u, n_y, n_l = self.n_outputs, self.n_inputs, self._n_past
        n = n_l * n_u
        a = np.zeros((n, n))
        a[:n_u] = self.gain[:, n_y:]
        a[n_u:, :-n_u] = np.eye(n - n_u)
        b = np.zeros((n, n_y))
        b[:n_u] = self.gain[:, :n_y]
        c = np.zeros((n_u, n))
        c[:, (self.delay - 1) * n_u : self.delay * n_u] = np.eye(n_u)
        return DiscreteStateSpace(a, b, c, np.zeros((n_u, n_y)))
