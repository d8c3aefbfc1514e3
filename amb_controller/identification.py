"""
On-line identification of the wavelet-domain Markov parameters (thesis section 6.4).

The thesis applies a step in one control wavelet coefficient at level ``a`` through one
bearing axis, records the measured coefficients and reads the Markov parameters
``A^(k)`` of ``G_{p,q,a,b}(z) = sum_k A^(k) z^-k`` (eq. 6.34) off the step response,
repeating for every axis. :class:`MarkovIdentifier` does this as a least-squares fit of

    q[k] = c + sum_{j=0}^{K} A^(j) u[k-j] + e[k]

to every period fed to it (``u``: applied control coefficients, ``q``: measured ones,
``c``: the constant background, e.g. the synchronous unbalance response). For a single
isolated step this is exactly the thesis's differencing of the step response; with
several steps, returns to zero and noise it averages them all. It uses only the applied
commands and the measurements, so it works the same on the simulator and on a rig.

:class:`StepExperiment` produces the thesis's excitation: each listed control input in
turn steps to ``amplitude`` for ``periods_per_step`` periods and back to zero for as
many. The identifier keeps running sums (normal equations), so memory does not grow
with the experiment length.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from amb_controller.errors import (
    ControllerValueError,
    NotIdentifiedError,
    PeriodSequenceError,
    ShapeError,
)


@dataclass(frozen=True)
class IdentificationResult:
    """
    Least-squares estimate of the wavelet-domain Markov parameters.

    Attributes
    ----------
    markov : numpy.ndarray
        ``A^(0) .. A^(K)``, shape ``(K+1, n_y, n_u)`` (measured per control coefficient).
    offset : numpy.ndarray
        Constant background ``c``, shape ``(n_y,)``.
    residual_rms : numpy.ndarray
        RMS fit residual per measured coefficient, shape ``(n_y,)``.
    n_periods : int
        Number of periods used in the fit.

    """

    markov: np.ndarray
    offset: np.ndarray
    residual_rms: np.ndarray
    n_periods: int


class MarkovIdentifier:
    """
    Recursive least-squares identification of ``A^(0) .. A^(K)`` (eq. 6.34).

    Parameters
    ----------
    n_inputs : int
        Control coefficients per period (axes x levels x translations x quadratures).
    n_outputs : int
        Measured coefficients per period.
    order : int
        Highest Markov index K (the response is assumed settled after K periods).
    fit_offset : bool
        Estimate a constant background ``c`` (default True).

    """

    def __init__(self, n_inputs: int, n_outputs: int, order: int, fit_offset: bool = True) -> None:
        for name, value, minimum in (
            ("n_inputs", n_inputs, 1),
            ("n_outputs", n_outputs, 1),
            ("order", order, 0),
        ):
            if int(value) != value or value < minimum:
                raise ControllerValueError(f"{name} must be an integer >= {minimum}, got {value}")
        self.n_inputs = int(n_inputs)
        self.n_outputs = int(n_outputs)
        self.order = int(order)
        self.fit_offset = bool(fit_offset)
        self._n_reg = (self.order + 1) * self.n_inputs + int(self.fit_offset)
        self.reset()

    def reset(self) -> None:
        """Discard all data."""
        self._rr = np.zeros((self._n_reg, self._n_reg))
        self._ry = np.zeros((self._n_reg, self.n_outputs))
        self._yy = np.zeros(self.n_outputs)
        self._history = np.zeros((self.order + 1, self.n_inputs))
        self._n_seen = 0
        self._n_used = 0
        self._last_period: int | None = None

    @property
    def n_periods(self) -> int:
        """Number of periods used so far (the first ``order`` only fill the history)."""
        return self._n_used

    def update(self, period_index: int, applied: np.ndarray, measured: np.ndarray) -> None:
        """
        Add one period: the control coefficients applied over it and those measured.

        Parameters
        ----------
        period_index : int
            Period k; must follow the previous one by 1 (call :meth:`reset` after a gap).
        applied : numpy.ndarray
            Control coefficients applied over period k, shape ``(n_inputs,)``.
        measured : numpy.ndarray
            Measured coefficients of period k, shape ``(n_outputs,)``.

        """
        u = np.asarray(applied, dtype=float)
        y = np.asarray(measured, dtype=float)
        if u.shape != (self.n_inputs,) or y.shape != (self.n_outputs,):
            raise ShapeError(
                f"applied/measured must have shapes ({self.n_inputs},)/({self.n_outputs},), "
                f"got {u.shape}/{y.shape}"
            )
        if not (np.all(np.isfinite(u)) and np.all(np.isfinite(y))):
            raise ControllerValueError("applied or measured contains NaN/inf; skip the period")
        if self._last_period is not None and period_index != self._last_period + 1:
            raise PeriodSequenceError(
                f"period_index must be {self._last_period + 1}, got {period_index}; "
                "identification needs consecutive periods: reset() and restart the step"
            )
        self._last_period = int(period_index)
        self._history[1:] = self._history[:-1]
        self._history[0] = u
        self._n_seen += 1
        if self._n_seen <= self.order:
            return  # u[k-j] for j > k unknown: the first K periods only fill the history
        phi = self._history.ravel()
        if self.fit_offset:
            phi = np.append(phi, 1.0)
        self._rr += np.outer(phi, phi)
        self._ry += np.outer(phi, y)
        self._yy += y * y
        self._n_used += 1

    def estimate(self, rcond: float = 1e-10) -> IdentificationResult:
        """
        Solve the normal equations.

        Parameters
        ----------
        rcond : float
            Relative singular-value threshold below which the data are taken as not
            exciting the corresponding regressors.

        Returns
        -------
        IdentificationResult

        """
        if self._n_used < self._n_reg:
            raise NotIdentifiedError(
                f"need at least {self._n_reg} periods after the first {self.order} to fit "
                f"{self._n_reg} regressors, have {self._n_used}; keep the experiment running"
            )
        s = np.linalg.svd(self._rr, compute_uv=False)
        if s[-1] <= rcond * s[0]:
            raise NotIdentifiedError(
                "the applied control coefficients do not excite every input at every lag "
                f"(condition {s[0] / max(s[-1], 1e-300):.3g}); step each input at least once and "
                f"hold it for more than order = {self.order} periods"
            )
        theta = np.linalg.solve(self._rr, self._ry)
        rss = self._yy - np.einsum("ij,ij->j", theta, self._ry)
        residual_rms = np.sqrt(np.clip(rss, 0.0, None) / self._n_used)
        gains = theta[: (self.order + 1) * self.n_inputs]
        markov = gains.reshape(self.order + 1, self.n_inputs, self.n_outputs).transpose(0, 2, 1)
        offset = theta[-1] if self.fit_offset else np.zeros(self.n_outputs)
        return IdentificationResult(markov.copy(), offset.copy(), residual_rms, self._n_used)


class StepExperiment:
    """
    Step excitation of thesis section 6.4, one control input at a time.

    Input ``inputs[0]`` is held at ``amplitude`` for ``periods_per_step`` periods, then
    at zero for ``periods_per_step`` periods, then the next input, and so on.

    Parameters
    ----------
    n_inputs : int
        Control coefficients per period.
    inputs : sequence of int
        Which control coefficients to step, in order.
    amplitude : float
        Step size (N * sqrt(samples)).
    periods_per_step : int
        Periods held on (and then off); must exceed the Markov order to be identified.
    start_period : int
        Period index at which the first step starts.

    """

    def __init__(
        self,
        n_inputs: int,
        inputs,
        amplitude: float,
        periods_per_step: int,
        start_period: int = 0,
    ) -> None:
        self.n_inputs = int(n_inputs)
        self.inputs = [int(i) for i in inputs]
        if not self.inputs or any(i < 0 or i >= self.n_inputs for i in self.inputs):
            raise ControllerValueError(
                f"inputs must be a non-empty list of indices in [0, {self.n_inputs}), got {inputs}"
            )
        if not (np.isfinite(amplitude) and amplitude != 0.0):
            raise ControllerValueError(f"amplitude must be finite and non-zero, got {amplitude}")
        if int(periods_per_step) != periods_per_step or periods_per_step < 1:
            raise ControllerValueError(f"periods_per_step must be >= 1, got {periods_per_step}")
        self.amplitude = float(amplitude)
        self.periods_per_step = int(periods_per_step)
        self.start_period = int(start_period)

    @property
    def n_periods(self) -> int:
        """Total length of the experiment in periods."""
        return 2 * self.periods_per_step * len(self.inputs)

    def command(self, period_index: int) -> np.ndarray:
        """Return the control coefficients to apply over ``period_index``."""
        u = np.zeros(self.n_inputs)
        k = period_index - self.start_period
        if 0 <= k < self.n_periods:
            which, phase = divmod(k, 2 * self.periods_per_step)
            if phase < self.periods_per_step:
                u[self.inputs[which]] = self.amplitude
        return u

    def progress(self, period_index: int) -> float:
        """Return the fraction of the experiment completed after ``period_index`` (0..1)."""
        return float(np.clip((period_index - self.start_period + 1) / self.n_periods, 0.0, 1.0))

    def done(self, period_index: int) -> bool:
        """Return True once ``period_index`` is the last period of the experiment or later."""
        return period_index - self.start_period + 1 >= self.n_periods
