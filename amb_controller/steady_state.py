"""
Steady-state prediction and the proportional / moderated controllers (thesis chapter 7).

Prediction (eq. 7.2-7.6)
------------------------
For a step in the disturbance coefficients, ``Q(z) = G B_u F / (z - 1)``; the predicted
steady-state coefficients ``W = S Q`` should be the step of final value
``Gamma = lim_{z->1} (1 - z^-1) Q(z)`` at once (eq. 7.4-7.5). With the pseudo-inverse
``(G B_u)^*`` recovering the disturbance step from the measured coefficients, eq. 7.6
gives ``S(z) = Gamma (G B_u)^*(z)`` with ``Gamma = G(1) B_u = sum_k A^(k)`` for a unit
step in each control input. So ``W[k] = G(1) sum_j B^(j) Q[k-j]``: a MIMO FIR filter of
the truncated inverse's order (5 in section 7.4.2). The thesis applies it level by level
(1 x, 2 x, 4 x: ``x_{1,1}, x_{2,1}, x_{3,1}``); with the flat coefficient vector of
:mod:`amb_controller.basis` a block-diagonal (per-level) or a full model can be used.

Controllers (eq. 7.7-7.9)
-------------------------
Proportional: ``U(z) = -k z^-i Q(z)``; moderated: ``U(z) = -k z^-i W(z)``, with ``k`` a
gain matrix (control coefficient per measured coefficient; :func:`collocated_gain`
builds the thesis's scalar ``k_{p,q}`` acting from the sensor beside each bearing) and
``i`` the evaluation delay in periods (3 in section 7.4.2).
"""

from __future__ import annotations

import numpy as np

from amb_controller.errors import ControllerValueError, PeriodSequenceError, ShapeError
from amb_controller.inverse import dc_gain, series_product
from amb_controller.lti import (
    DiscreteStateSpace,
    delay_state_space,
    fir_state_space,
    series,
    static_gain,
)
from amb_controller.transient import ControlStep, _checked_vector

#: Sensor channel beside each bearing axis (planes 2 and 3 are the inner planes next to
#: the AMBs; bearing 1 is nearer plane 1): b1x<-x2, b1y<-y2, b2x<-x3, b2y<-y3.
COLLOCATED_SENSOR = (2, 3, 4, 5)


def steady_state_operator(markov: np.ndarray, inverse_markov: np.ndarray) -> np.ndarray:
    """
    Return the Markov parameters of ``S(z) = Gamma (G B_u)^*(z)`` (eq. 7.6).

    Parameters
    ----------
    markov : numpy.ndarray
        ``A^(0) .. A^(M)`` of ``G B_u``, shape ``(M+1, n_y, n_u)``.
    inverse_markov : numpy.ndarray
        ``B^(0) .. B^(K)``, shape ``(K+1, n_u, n_y)``.

    Returns
    -------
    numpy.ndarray
        ``S^(0) .. S^(K)``, shape ``(K+1, n_y, n_y)`` (dimensionless).

    """
    gamma = dc_gain(markov)
    return series_product(gamma[None], np.asarray(inverse_markov))


class SteadyStatePredictor:
    """
    Streaming predicted steady-state coefficients ``W[k] = sum_j S^(j) Q[k-j]`` (eq. 7.2).

    Parameters
    ----------
    operator : numpy.ndarray
        ``S^(0) .. S^(K)`` from :func:`steady_state_operator`, shape ``(K+1, n_y, n_y)``.

    """

    def __init__(self, operator: np.ndarray) -> None:
        operator = np.asarray(operator, dtype=float)
        if operator.ndim != 3 or operator.shape[1] != operator.shape[2]:
            raise ShapeError(f"operator must have shape (K+1, n_y, n_y), got {operator.shape}")
        self.operator = operator
        self.n_channels = operator.shape[1]
        self._flat = operator.transpose(1, 0, 2).reshape(self.n_channels, -1)
        self.reset()

    def reset(self) -> None:
        """Forget past measurements."""
        self._history = np.zeros((self.operator.shape[0], self.n_channels))
        self._last_period: int | None = None

    def get_state(self) -> tuple[np.ndarray, int | None]:
        """Return a copy of the streaming state (history of ``Q``, last period)."""
        return self._history.copy(), self._last_period

    def set_state(self, state: tuple[np.ndarray, int | None]) -> None:
        """Restore a state from :meth:`get_state`."""
        history, last = state
        self._history = np.array(history, dtype=float)
        self._last_period = last

    def skip(self, period_index: int) -> None:
        """Mark ``period_index`` consumed without a measurement (history unchanged)."""
        self._last_period = int(period_index)

    def step(self, period_index: int, measured: np.ndarray) -> np.ndarray:
        """
        Return the predicted steady-state coefficients after period ``period_index``.

        Parameters
        ----------
        period_index : int
            Consecutive period index.
        measured : numpy.ndarray
            ``Q[k]``, shape ``(n_y,)``.

        Returns
        -------
        numpy.ndarray
            ``W[k]``, shape ``(n_y,)``, in the units of ``measured``.

        """
        q = _checked_vector("measured", measured, self.n_channels)
        if self._last_period is not None and period_index != self._last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {self._last_period + 1}, got {period_index}; reset() first"
            )
        self._last_period = int(period_index)
        self._history[1:] = self._history[:-1]
        self._history[0] = q
        return self._flat @ self._history.ravel()

    def state_space(self) -> DiscreteStateSpace:
        """Return ``S(z)`` as a state-space system."""
        return fir_state_space(self.operator)


def collocated_gain(k: float, blocks: int, n_axes: int = 4, n_sensors: int = 8) -> np.ndarray:
    """
    Return the thesis's scalar gain ``k_{p,q}`` as a matrix from the collocated sensors.

    Parameters
    ----------
    k : float
        Gain (control coefficient per measured coefficient, N/m).
    blocks : int
        Number of (level, translation, quadrature) blocks shared by the control and
        measured layouts of :mod:`amb_controller.basis`.
    n_axes, n_sensors : int
        Channels per block (4 axes, 8 sensors by convention).

    Returns
    -------
    numpy.ndarray
        Shape ``(blocks * n_axes, blocks * n_sensors)``.

    """
    if n_axes != len(COLLOCATED_SENSOR) or n_sensors != 8:
        raise ControllerValueError("collocated_gain assumes 4 bearing axes and 8 sensor channels")
    block = np.zeros((n_axes, n_sensors))
    block[np.arange(n_axes), COLLOCATED_SENSOR] = k
    return np.kron(np.eye(blocks), block)


class ProportionalController:
    """
    Proportional wavelet controller ``U = -k z^-i Q`` or moderated ``U = -k z^-i W`` (eq. 7.7-7.9).

    Parameters
    ----------
    gain : numpy.ndarray
        ``k``, shape ``(n_u, n_y)``.
    delay : int
        Evaluation delay ``i`` >= 1 in periods.
    predictor : SteadyStatePredictor, optional
        If given, the controller acts on the predicted steady state ``W`` (moderated).

    """

    def __init__(self, gain: np.ndarray, delay: int, predictor: SteadyStatePredictor | None = None):
        gain = np.atleast_2d(np.asarray(gain, dtype=float))
        if int(delay) != delay or delay < 1:
            raise ControllerValueError(f"delay must be an integer >= 1 period, got {delay}")
        if predictor is not None and predictor.n_channels != gain.shape[1]:
            raise ShapeError(
                f"gain takes {gain.shape[1]} measured coefficients, predictor gives "
                f"{predictor.n_channels}"
            )
        self.gain = gain
        self.delay = int(delay)
        self.predictor = predictor
        self.n_inputs = gain.shape[1]
        self.n_outputs = gain.shape[0]
        self._last_period: int | None = None

    def reset(self) -> None:
        """Forget past measurements."""
        self._last_period = None
        if self.predictor is not None:
            self.predictor.reset()

    def get_state(self):
        """Return a copy of the state (predictor history)."""
        if self.predictor is None:
            return self._last_period
        return (self._last_period, *self.predictor.get_state())

    def set_state(self, state) -> None:
        """Restore a state from :meth:`get_state`."""
        if self.predictor is None:
            self._last_period = state
        else:
            self._last_period, history, last = state
            self.predictor.set_state((history, last))

    def skip(self, period_index: int) -> None:
        """Mark ``period_index`` consumed without updating the predictor (hold)."""
        self._last_period = int(period_index)
        if self.predictor is not None:
            self.predictor.skip(period_index)

    def step(self, period_index: int, measured: np.ndarray) -> ControlStep:
        """
        Return the command for period ``period_index + delay``.

        Parameters
        ----------
        period_index : int
            Consecutive period index.
        measured : numpy.ndarray
            ``Q[k]``, shape ``(n_y,)``.

        Returns
        -------
        ControlStep

        """
        q = _checked_vector("measured", measured, self.n_inputs)
        if self._last_period is not None and period_index != self._last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {self._last_period + 1}, got {period_index}; reset() first"
            )
        signal = q if self.predictor is None else self.predictor.step(period_index, q)
        self._last_period = int(period_index)
        return ControlStep(int(period_index) + self.delay, int(period_index), -(self.gain @ signal))

    def state_space(self) -> DiscreteStateSpace:
        """Return ``-k z^-i`` (or ``-k z^-i S(z)``) from measured to applied coefficients."""
        chain = static_gain(np.eye(self.n_inputs))
        if self.predictor is not None:
            chain = self.predictor.state_space()
        chain = series(chain, static_gain(-self.gain))
        return series(chain, delay_state_space(self.delay, self.n_outputs))
