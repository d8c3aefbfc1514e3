"""
Small discrete-time state-space toolkit for the wavelet-domain loop.

The wavelet-domain plant, the controller and their interconnection are all
discrete-time systems in the control-period index k (one period T per step). This
module holds the minimum needed to realise them and to compute exact closed-loop
poles: a state-space container, realisations of FIR (Markov-parameter) and SISO
rational filters, series connection and the feedback interconnection.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from amb_controller.errors import ControllerValueError, ShapeError


@dataclass(frozen=True)
class DiscreteStateSpace:
    """
    Discrete-time system ``x[k+1] = a x[k] + b u[k]``, ``y[k] = c x[k] + d u[k]``.

    Parameters
    ----------
    a : numpy.ndarray
        State matrix, shape ``(n, n)``.
    b : numpy.ndarray
        Input matrix, shape ``(n, m)``.
    c : numpy.ndarray
        Output matrix, shape ``(p, n)``.
    d : numpy.ndarray
        Feed-through, shape ``(p, m)``.

    """

    a: np.ndarray
    b: np.ndarray
    c: np.ndarray
    d: np.ndarray

    def __post_init__(self) -> None:
        a = np.atleast_2d(np.asarray(self.a))
        d = np.atleast_2d(np.asarray(self.d))
        n = a.shape[0] if a.size else 0
        p, m = d.shape
        a = a.reshape(n, n)
        b = np.asarray(self.b).reshape(n, m)
        c = np.asarray(self.c).reshape(p, n)
        for name, value in (("a", a), ("b", b), ("c", c), ("d", d)):
            object.__setattr__(self, name, value)

    @property
    def n_states(self) -> int:
        """Number of states."""
        return self.a.shape[0]

    @property
    def n_inputs(self) -> int:
        """Number of inputs."""
        return self.d.shape[1]

    @property
    def n_outputs(self) -> int:
        """Number of outputs."""
        return self.d.shape[0]

    def poles(self) -> np.ndarray:
        """Return the eigenvalues of ``a`` (the poles, z-plane)."""
        if self.n_states == 0:
            return np.zeros(0, dtype=complex)
        return linalg.eigvals(self.a)

    def markov(self, n_terms: int) -> np.ndarray:
        """
        Return the Markov parameters ``d, c b, c a b, ...``.

        Parameters
        ----------
        n_terms : int
            Number of terms.

        Returns
        -------
        numpy.ndarray
            Shape ``(n_terms, p, m)``; term k multiplies ``z^-k``.

        """
        out = np.empty(
            (n_terms, self.n_outputs, self.n_inputs), dtype=np.result_type(self.a, self.d)
        )
        if n_terms == 0:
            return out
        out[0] = self.d
        ab = self.b
        for k in range(1, n_terms):
            out[k] = self.c @ ab
            ab = self.a @ ab
        return out

    def simulate(self, u: np.ndarray, x0: np.ndarray | None = None) -> np.ndarray:
        """
        Return the output sequence for the input sequence ``u`` (shape ``(K, m)``).

        Parameters
        ----------
        u : numpy.ndarray
            Inputs, one row per period.
        x0 : numpy.ndarray, optional
            Initial state (zero by default).

        Returns
        -------
        numpy.ndarray
            Outputs, shape ``(K, p)``.

        """
        u = np.asarray(u)
        x = np.zeros(self.n_states, dtype=np.result_type(self.a, u)) if x0 is None else np.array(x0)
        y = np.empty((u.shape[0], self.n_outputs), dtype=np.result_type(self.c, u))
        for k in range(u.shape[0]):
            y[k] = self.c @ x + self.d @ u[k]
            x = self.a @ x + self.b @ u[k]
        return y

    def frequency_response(self, z: np.ndarray) -> np.ndarray:
        """
        Return ``c (zI - a)^-1 b + d`` at the points ``z``, shape ``(len(z), p, m)``.

        Parameters
        ----------
        z : numpy.ndarray
            Complex points.

        Returns
        -------
        numpy.ndarray of complex

        """
        z = np.atleast_1d(np.asarray(z, dtype=complex))
        eye = np.eye(self.n_states)
        out = np.empty((z.size, self.n_outputs, self.n_inputs), dtype=complex)
        for i, zi in enumerate(z):
            if self.n_states:
                out[i] = self.c @ np.linalg.solve(zi * eye - self.a, self.b) + self.d
            else:
                out[i] = self.d
        return out


def fir_state_space(markov: np.ndarray) -> DiscreteStateSpace:
    """
    Realise ``sum_k M_k z^-k`` (an FIR matrix filter) as a shift register on the inputs.

    Parameters
    ----------
    markov : numpy.ndarray
        ``M_0 .. M_K``, shape ``(K + 1, p, m)``.

    Returns
    -------
    DiscreteStateSpace
        ``K m`` states holding ``u[k-1] .. u[k-K]``.

    """
    markov = np.asarray(markov)
    if markov.ndim != 3 or markov.shape[0] < 1:
        raise ShapeError(f"markov must have shape (K+1, p, m) with K >= 0, got {markov.shape}")
    n_terms, p, m = markov.shape
    order = n_terms - 1
    n = order * m
    a = np.zeros((n, n))
    b = np.zeros((n, m))
    if order:
        a[m:, :-m] = np.eye(n - m)
        b[:m] = np.eye(m)
    c = np.concatenate(list(markov[1:]), axis=1) if order else np.zeros((p, 0))
    return DiscreteStateSpace(a, b, c, markov[0])


def siso_filter_state_space(
    num: np.ndarray, den: np.ndarray, n_channels: int
) -> DiscreteStateSpace:
    """
    Realise ``num(z^-1)/den(z^-1)`` applied independently to ``n_channels`` channels.

    Parameters
    ----------
    num, den : numpy.ndarray
        Ascending coefficients in ``z^-1`` (``den[0] != 0``).
    n_channels : int
        Number of identical channels (block-diagonal realisation).

    Returns
    -------
    DiscreteStateSpace

    """
    num = np.asarray(num, dtype=float)
    den = np.asarray(den, dtype=float)
    n = max(num.size, den.size)
    num = np.pad(num, (0, n - num.size)) / den[0]
    den = np.pad(den, (0, n - den.size)) / den[0]
    order = n - 1
    # Observable canonical form of the transposed direct form II (same as scipy lfilter).
    a1 = np.zeros((order, order))
    if order:
        a1[:, 0] = -den[1:]
        a1[:-1, 1:] = np.eye(order - 1)
    b1 = (num[1:] - num[0] * den[1:]).reshape(order, 1)
    c1 = np.zeros((1, order))
    if order:
        c1[0, 0] = 1.0
    d1 = np.array([[num[0]]])
    eye = np.eye(n_channels)
    return DiscreteStateSpace(
        np.kron(eye, a1), np.kron(eye, b1), np.kron(eye, c1), np.kron(eye, d1)
    )


def delay_state_space(n_periods: int, n_channels: int) -> DiscreteStateSpace:
    """
    Realise the pure delay ``z^-n_periods`` on ``n_channels`` channels.

    Parameters
    ----------
    n_periods : int
        Delay, >= 0.
    n_channels : int
        Channel count.

    Returns
    -------
    DiscreteStateSpace

    """
    markov = np.zeros((n_periods + 1, n_channels, n_channels))
    markov[n_periods] = np.eye(n_channels)
    return fir_state_space(markov)


def series(first: DiscreteStateSpace, second: DiscreteStateSpace) -> DiscreteStateSpace:
    """
    Return the cascade ``second(first(u))``.

    Parameters
    ----------
    first, second : DiscreteStateSpace
        ``second.n_inputs`` must equal ``first.n_outputs``.

    Returns
    -------
    DiscreteStateSpace

    """
    if second.n_inputs != first.n_outputs:
        raise ShapeError(
            f"series: second system takes {second.n_inputs} inputs but the first gives "
            f"{first.n_outputs} outputs"
        )
    n1, n2 = first.n_states, second.n_states
    a = np.block(
        [
            [first.a, np.zeros((n1, n2))],
            [second.b @ first.c, second.a],
        ]
    )
    b = np.vstack([first.b, second.b @ first.d])
    c = np.hstack([second.d @ first.c, second.c])
    d = second.d @ first.d
    return DiscreteStateSpace(a, b, c, d)


def feedback(plant: DiscreteStateSpace, controller: DiscreteStateSpace) -> DiscreteStateSpace:
    """
    Close the loop ``u = controller(y) + r``, ``y = plant(u)`` (positive feedback form).

    The controller carries its own sign (the wavelet controllers return ``-L Q``). The
    closed loop maps the external input ``r`` (added to the plant input, e.g. the
    disturbance coefficients ``F`` of eq. 8.2) to ``y``.

    Parameters
    ----------
    plant : DiscreteStateSpace
        ``m`` inputs, ``p`` outputs.
    controller : DiscreteStateSpace
        ``p`` inputs, ``m`` outputs.

    Returns
    -------
    DiscreteStateSpace
        Closed loop from ``r`` to ``y``; its poles are the closed-loop poles.

    """
    if controller.n_inputs != plant.n_outputs or controller.n_outputs != plant.n_inputs:
        raise ShapeError(
            f"feedback: controller must map {plant.n_outputs} outputs to {plant.n_inputs} "
            f"inputs, got {controller.n_inputs} -> {controller.n_outputs}"
        )
    m = plant.n_inputs
    # u = Ck xk + Dk (Cp xp + Dp u) + r  ->  E u = Ck xk + Dk Cp xp + r
    e = np.eye(m) - controller.d @ plant.d
    try:
        e_inv = np.linalg.inv(e)
    except np.linalg.LinAlgError as exc:
        raise ControllerValueError(
            "feedback loop is algebraic and singular (I - Dk Dp not invertible); add a "
            "delay of at least one period in the controller"
        ) from exc
    u_x = e_inv @ np.hstack([controller.d @ plant.c, controller.c])  # u in terms of [xp, xk]
    u_r = e_inv
    a = np.vstack(
        [
            np.hstack([plant.a, np.zeros((plant.n_states, controller.n_states))]) + plant.b @ u_x,
            np.hstack([controller.b @ plant.c, controller.a]) + controller.b @ plant.d @ u_x,
        ]
    )
    b = np.vstack([plant.b @ u_r, controller.b @ plant.d @ u_r])
    c = np.hstack([plant.c, np.zeros((plant.n_outputs, controller.n_states))]) + plant.d @ u_x
    d = plant.d @ u_r
    return DiscreteStateSpace(a, b, c, d)


def block_diagonal(systems: list[DiscreteStateSpace]) -> DiscreteStateSpace:
    """
    Return the parallel, uncoupled stack of ``systems`` (block-diagonal matrices).

    Parameters
    ----------
    systems : list of DiscreteStateSpace
        Systems to stack; inputs and outputs are concatenated in order.

    Returns
    -------
    DiscreteStateSpace

    """
    return DiscreteStateSpace(
        linalg.block_diag(*[s.a for s in systems]),
        linalg.block_diag(*[s.b for s in systems]),
        linalg.block_diag(*[s.c for s in systems]),
        linalg.block_diag(*[s.d for s in systems]),
    )


def static_gain(gain: np.ndarray) -> DiscreteStateSpace:
    """Return the memoryless system ``y = gain u``."""
    gain = np.atleast_2d(np.asarray(gain, dtype=float))
    return DiscreteStateSpace(
        np.zeros((0, 0)), np.zeros((0, gain.shape[1])), np.zeros((gain.shape[0], 0)), gain
    )
