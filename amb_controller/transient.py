"""
Wavelet transient controller of thesis chapter 8 as a difference equation in k.

Controller (eq. 8.10), per control period k (sign convention of
:mod:`amb_controller.stability`)::

    U(z) = -L(z) Q(z),   L(z) = z^-i (G B_u)^*(z) beta(z),
    beta(z) = 1 / (alpha(z)(z - 1)) - 1     (one SISO filter per measured channel)

Realisation (explicit state, no per-sample loops)
-------------------------------------------------
1. ``r[k] = sum_{j=0}^{K} B^(j) q[k-j]``: the truncated inverse of eq. 6.35 as one
   matrix product with the history ``q[k] .. q[k-K]`` (state ``history``, shape
   ``(K+1, n_y)``).
2. ``s[k] = beta(r[k])``: each channel through its ``beta`` filter (transposed direct
   form II, the realisation of :func:`scipy.signal.lfilter`; state ``zi`` of shape
   ``(L-1, n_u)`` updated for all channels at once). ``beta`` has a pole at z = 1: it
   is the integral action that removes the steady-state coefficients.
3. ``u[k+i] = -s[k]``: the delay ``z^-i`` is the gap between the period whose
   coefficients were measured (``period_index``) and the period the command is for
   (``target_period = period_index + i``); it is realised by the node/plant, which
   apply the command i periods later, so it needs no state here. ``i >= 1``: the
   measured coefficients of a period exist only after the period has ended.

Order of the factors: with one ``alpha`` for all measured channels (the common case,
and the thesis's experiments) ``beta`` is a scalar and commutes with ``B(z)``, so it is
applied after the inverse, on the ``n_u`` command channels: ``n_u`` integrators, all
controllable and observable. With a different ``alpha`` per measured channel (the
diagonal alpha of section 8.2) ``beta`` must act first, on the ``n_y`` measured
channels; when ``n_y > n_u`` the extra ``n_y - n_u`` integrators act in directions the
least-squares inverse almost annihilates: they show up as closed-loop poles at z = 1
and can integrate measurement noise, so prefer one ``alpha`` per level.

``state_space()`` returns the same controller, delay included, as a
:class:`~amb_controller.lti.DiscreteStateSpace` for the exact closed-loop pole check.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.errors import ControllerValueError, PeriodSequenceError, ShapeError
from amb_controller.lti import (
    DiscreteStateSpace,
    block_diagonal,
    delay_state_space,
    fir_state_space,
    series,
    siso_filter_state_space,
    static_gain,
)
from amb_controller.response import PrescribedResponse


@dataclass(frozen=True)
class ControlStep:
    """
    One command of a period-synchronous controller.

    Attributes
    ----------
    target_period : int
        Control period the command is for (``period_index + delay``).
    based_on_period : int
        Last measured period used.
    coefficients : numpy.ndarray
        Control wavelet coefficients, shape ``(n_u,)`` (N * sqrt(samples)).

    """

    target_period: int
    based_on_period: int
    coefficients: np.ndarray


@dataclass
class TransientState:
    """Explicit state of :class:`TransientController` (copyable for anti-windup hold)."""

    zi: np.ndarray
    history: np.ndarray
    last_period: int | None

    def copy(self) -> TransientState:
        """Return a deep copy."""
        return TransientState(self.zi.copy(), self.history.copy(), self.last_period)


class TransientController:
    """
    MIMO wavelet transient controller ``U = -z^-i (G B_u)^* beta Q`` (eq. 8.5, 8.10).

    Parameters
    ----------
    inverse_markov : numpy.ndarray
        ``B^(0) .. B^(K)`` of eq. 6.35, shape ``(K+1, n_u, n_y)``, from
        :func:`amb_controller.inverse.pseudo_inverse_series`.
    alphas : PrescribedResponse or sequence of PrescribedResponse
        Prescribed response for all measured channels, or one per measured channel (the
        diagonal of the alpha matrix, section 8.2).
    delay : int
        Evaluation delay ``i`` >= 1 in control periods.

    """

    def __init__(self, inverse_markov: np.ndarray, alphas, delay: int) -> None:
        inverse_markov = np.asarray(inverse_markov, dtype=float)
        if inverse_markov.ndim != 3 or not np.all(np.isfinite(inverse_markov)):
            raise ShapeError(
                "inverse_markov must be a finite array of shape (K+1, n_u, n_y), got shape "
                f"{inverse_markov.shape}"
            )
        if int(delay) != delay or delay < 1:
            raise ControllerValueError(
                f"delay must be an integer >= 1 period, got {delay}: the coefficients of a "
                "period are known only after it ends, so the command is for a later period"
            )
        self.inverse_markov = inverse_markov
        self.delay = int(delay)
        n_terms, self.n_outputs, self.n_inputs = inverse_markov.shape
        if isinstance(alphas, PrescribedResponse):
            alphas = [alphas] * self.n_inputs
        self.alphas = list(alphas)
        if len(self.alphas) != self.n_inputs:
            raise ControllerValueError(
                f"expected 1 or {self.n_inputs} prescribed responses (one per measured "
                f"channel), got {len(self.alphas)}"
            )
        self._beta_first = not all(
            np.array_equal(a.num, self.alphas[0].num) and np.array_equal(a.den, self.alphas[0].den)
            for a in self.alphas
        )
        if not self._beta_first:
            self.alphas_applied = [self.alphas[0]] * self.n_outputs
        else:
            self.alphas_applied = self.alphas
        betas = [a.beta() for a in self.alphas_applied]
        length = max(num.size for num, _ in betas)
        self._b = np.stack([np.pad(num, (0, length - num.size)) for num, _ in betas], axis=1)
        self._a = np.stack([np.pad(den, (0, length - den.size)) for _, den in betas], axis=1)
        self._b_flat = inverse_markov.transpose(1, 0, 2).reshape(self.n_outputs, -1)
        self._n_terms = n_terms
        self._state = self._initial_state()

    # ------------------------------------------------------------------ state
    def _initial_state(self) -> TransientState:
        return TransientState(
            zi=np.zeros((self._b.shape[0] - 1, len(self.alphas_applied))),
            history=np.zeros((self._n_terms, self.n_inputs)),
            last_period=None,
        )

    def reset(self) -> None:
        """Forget all past measurements (integrators and inverse history to zero)."""
        self._state = self._initial_state()

    def get_state(self) -> TransientState:
        """Return a copy of the explicit state."""
        return self._state.copy()

    def set_state(self, state: TransientState) -> None:
        """Restore a state returned by :meth:`get_state` (e.g. to hold while saturated)."""
        self._state = state.copy()

    def skip(self, period_index: int) -> None:
        """Mark ``period_index`` consumed without updating the filters (hold / anti-windup)."""
        self._state.last_period = int(period_index)

    # ------------------------------------------------------------------ step
    def step(self, period_index: int, measured: np.ndarray) -> ControlStep:
        """
        Consume the measured coefficients of one period; return the command for ``k + i``.

        Parameters
        ----------
        period_index : int
            Index k of the period the coefficients were measured over; must follow the
            previous one by exactly 1 (call :meth:`reset` after a gap).
        measured : numpy.ndarray
            Measured wavelet coefficients ``q[k]``, shape ``(n_y,)`` (m * sqrt(samples)).

        Returns
        -------
        ControlStep
            Control coefficients for period ``k + delay``.

        """
        q = _checked_vector("measured", measured, self.n_inputs)
        state = self._state
        if state.last_period is not None and period_index != state.last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {state.last_period + 1} (previous + 1), got "
                f"{period_index}; call reset() to restart after a missing period"
            )
        if self._beta_first:
            r = self._beta_step(state, q)
            state.history[1:] = state.history[:-1]
            state.history[0] = r
            command = -(self._b_flat @ state.history.ravel())
        else:
            state.history[1:] = state.history[:-1]
            state.history[0] = q
            command = -self._beta_step(state, self._b_flat @ state.history.ravel())
        state.last_period = int(period_index)
        return ControlStep(int(period_index) + self.delay, int(period_index), command)

    def _beta_step(self, state: TransientState, x: np.ndarray) -> np.ndarray:
        """Advance the per-channel beta filters by one period (transposed DF-II)."""
        y = self._b[0] * x + (state.zi[0] if state.zi.shape[0] else 0.0)
        if state.zi.shape[0]:
            shifted = np.vstack([state.zi[1:], np.zeros((1, state.zi.shape[1]))])
            state.zi = self._b[1:] * x + shifted - self._a[1:] * y
        return y

    # ------------------------------------------------------------------ analysis
    def state_space(self) -> DiscreteStateSpace:
        """
        Return the controller ``-z^-i B(z) beta(z)`` from measured to applied coefficients.

        Returns
        -------
        DiscreteStateSpace
            ``n_y`` inputs (measured coefficients of period k), ``n_u`` outputs (control
            coefficients applied over period k).

        """
        betas = block_diagonal(
            [siso_filter_state_space(*a.beta(), n_channels=1) for a in self.alphas_applied]
        )
        inverse = fir_state_space(self.inverse_markov)
        chain = series(betas, inverse) if self._beta_first else series(inverse, betas)
        chain = series(chain, delay_state_space(self.delay, self.n_outputs))
        return series(chain, static_gain(-np.eye(self.n_outputs)))


def _checked_vector(name: str, value, size: int) -> np.ndarray:
    q = np.asarray(value, dtype=float)
    if q.shape != (size,):
        raise ShapeError(f"{name} must have shape ({size},), got {q.shape}")
    if not np.all(np.isfinite(q)):
        raise ControllerValueError(f"{name} contains NaN or inf: {q}; drop this period and reset()")
    return q
