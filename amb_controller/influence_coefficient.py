"""
The influence-coefficient controller: adaptive open-loop synchronous control, eq. B.1.

The control law of the ``synchronous`` baseline (``controller = "synchronous"``), run by
:class:`~amb_controller.baselines.HarmonicPipeline` on the 1 x Fourier coefficients of
:mod:`amb_controller.fourier_basis`.

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
----------------------------------------------------
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

References
----------
[2]: journal, volume and pages confirmed by its stored abstract; [4]: title, authors and DOI
confirmed by its stored first page; [1]: as cited by the thesis (its bibliography is not in the
text available here), volume and pages not verified.

.. [1] C. R. Burrows, M. N. Sahinkaya, "Vibration control of multi-mode rotor-bearing
   systems", Proc. R. Soc. Lond. A 386 (1983) 77-94.
.. [2] C. R. Knospe, R. W. Hope, S. J. Fedigan, R. D. Williams, "Experiments in the control
   of unbalance response using magnetic bearings", Mechatronics 5(4) (1995) 385-400.
.. [4] S. W. Dyer, J. Ni, J. Shi, K.-K. Shin, "Robust optimal influence-coefficient
   control of multiple-plane active rotor balancing systems", ASME J. Dyn. Syst. Meas.
   Control 124 (2002), doi:10.1115/1.1435622 (abstract read).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from amb_controller.errors import ControllerValueError, PeriodSequenceError
from amb_controller.fourier_basis import complex_from_real, real_from_complex
from amb_controller.transient import ControlStep

__all__ = ["InfluenceCoefficientController"]


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
