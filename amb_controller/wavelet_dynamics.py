"""
Wavelet-domain dynamics G_{p,q,a,b}(z) and G^0_{p,q}(z) of a modal model (thesis chapter 6).

Numerical route (any orthogonal wavelet)
----------------------------------------
The plant ``x' = A x + B f``, ``y = C x`` (e.g. the PID-levitated rotor of
:mod:`amb_plant_sim`, forces per bearing axis in N, displacements per sensor in m) is
driven, over period 0, by the force waveform of one control coefficient (zero-order
hold of its sample weights, :func:`amb_controller.basis.control_basis`, as the amplifier
applies it) and its response is projected on the measured wavelets of periods
0, 1, 2, ... (eq. 6.13-6.15). The result is the Markov series of eq. 6.34 directly:

    G(z) = sum_{m >= 0} A^(m) z^-m,   A^(m)[i, j] = coefficient i of period m per unit
                                       control coefficient j applied over period 0.

``projection="sampled"`` projects the samples ``y(n h)`` (what the filterbank measures);
``projection="continuous"`` projects the continuous response, ``(1/h) int y(t) w(t) dt``
with the piecewise-constant weights ``w`` (the thesis's integrals of eq. 6.13 with
weights normalised to the orthonormal samples, so both projections share units and
converge as ``samples_per_rev`` grows). Discretisation is exact (matrix exponentials of
augmented matrices, Van Loan), computed once.

Closed form for piecewise-constant waveforms (Haar, eq. 6.22-6.33 re-derived)
-------------------------------------------------------------------------------
For one mode ``lambda`` with residue ``r = C v (V^-1 B)_l`` (eq. 6.9), an input
coefficient whose force is ``sum_i f_i`` on ``[a_i, b_i)`` of period 0 leaves the state
``x(T) = sum_i f_i e^{lambda T} (e^{-lambda a_i} - e^{-lambda b_i}) / lambda``; a
measured coefficient with weights ``w_j`` on ``[c_j, d_j)`` of period m >= 1 then reads

    A^(m) = sum_l r_l X_l P_l e^{lambda_l (m-1) T},
    X_l = sum_i f_i e^{lambda_l T}(e^{-lambda_l a_i} - e^{-lambda_l b_i}) / lambda_l,
    P_l = (1/h) sum_j w_j (e^{lambda_l d_j} - e^{lambda_l c_j}) / lambda_l,

so ``G(z) = A^(0) + sum_l r_l X_l P_l / (z - e^{lambda_l T})``. For Haar input (level a,
start t0, length L_a, amplitude s_a = 2^{-j_a/2}) and output (level p, start s0, length
M_p, amplitude s_p):

    X_l = s_a e^{lambda T} e^{-lambda t0} (1 - e^{-lambda L_a/2})^2 / lambda      ("R_1")
    P_l = -(s_p / h) e^{lambda s0} (e^{lambda M_p/2} - 1)^2 / lambda               ("R_2")

Differences from the printed eq. 6.22-6.33 (typos): the pole is ``e^{+lambda T}``, not
``e^{-2 lambda T}``; there is no ``z(z+1)`` factor (eq. 6.17's ``(z^2 - 1)`` does not
follow from 6.15) and no ``|p|^{-1/2}``; the delays ``r_i(a, b)`` of eq. 6.26 are
``t0``, ``t0 + L_a/2``, ``t0 + L_a`` (``L_a = T / 2^(a-1)``); and the same-period term
``A^(0)`` (dropped by the thesis's "k <= m - 1") is kept, from the double integral
``int_c^d int_a^{min(t,b)} e^{lambda (t - tau)} dtau dt`` in closed form.
``G^0_{p,q}`` (eq. 6.33) is the same with the input the constant unit force over the
period (the period average, one piece).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy import linalg

from amb_controller.basis import BasisSet
from amb_controller.errors import ControllerValueError, ShapeError


@dataclass(frozen=True)
class ZohDiscretisation:
    """
    Exact sample-interval matrices of ``x' = A x + B f`` with zero-order-hold input.

    Attributes
    ----------
    ad : numpy.ndarray
        ``e^{A h}``.
    bd : numpy.ndarray
        ``int_0^h e^{A s} ds B``.
    e1 : numpy.ndarray
        ``int_0^h e^{A s} ds`` (state part of the interval integral of ``x``).
    e2 : numpy.ndarray
        ``int_0^h int_0^tau e^{A s} ds dtau B`` (input part).
    h : float
        Sample interval in s.

    """

    ad: np.ndarray
    bd: np.ndarray
    e1: np.ndarray
    e2: np.ndarray
    h: float


def discretise(a: np.ndarray, b: np.ndarray, h: float) -> ZohDiscretisation:
    """
    Discretise with a zero-order hold, with the interval integrals (Van Loan).

    Parameters
    ----------
    a : numpy.ndarray
        State matrix (1/s), shape ``(n, n)``.
    b : numpy.ndarray
        Input matrix, shape ``(n, m)``.
    h : float
        Sample interval in s.

    Returns
    -------
    ZohDiscretisation

    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    n = a.shape[0]
    big = np.zeros((3 * n, 3 * n))
    big[:n, :n] = a
    big[:n, n : 2 * n] = np.eye(n)
    big[n : 2 * n, 2 * n :] = np.eye(n)
    e = linalg.expm(big * h)
    ad, e1, e2 = e[:n, :n], e[:n, n : 2 * n], e[:n, 2 * n :]
    return ZohDiscretisation(ad, e1 @ b, e1, e2 @ b, float(h))


def wavelet_markov(
    a: np.ndarray,
    b: np.ndarray,
    c: np.ndarray,
    period: float,
    control: BasisSet,
    measured: BasisSet,
    n_terms: int,
    projection: str = "sampled",
) -> np.ndarray:
    """
    Return the Markov parameters ``A^(0) .. A^(n_terms-1)`` of ``G_{p,q,a,b}(z)`` (eq. 6.19, 6.34).

    Parameters
    ----------
    a, b, c : numpy.ndarray
        Continuous plant ``x' = a x + b f``, ``y = c x``; ``b`` has one column per
        control axis (N), ``c`` one row per sensor channel (m).
    period : float
        Control period ``T`` in s (one revolution, ``2 pi / omega``).
    control : BasisSet
        Force waveforms of the control coefficients (``offset >= 0``).
    measured : BasisSet
        Analysis weights of the measured coefficients.
    n_terms : int
        Number of Markov parameters.
    projection : {"sampled", "continuous"}
        Project the samples (filterbank) or the continuous response (thesis integrals).

    Returns
    -------
    numpy.ndarray
        Shape ``(n_terms, measured.n_coefficients, control.n_coefficients)`` in measured
        coefficient per control coefficient (m/N for displacement per force).

    """
    a = np.asarray(a, dtype=float)
    b = np.asarray(b, dtype=float)
    c = np.asarray(c, dtype=float)
    n = a.shape[0]
    if a.shape != (n, n) or b.shape[0] != n or c.shape[1] != n:
        raise ShapeError(
            f"a, b, c must be (n, n), (n, m), (p, n); got {a.shape}, {b.shape}, {c.shape}"
        )
    if control.n_channels != b.shape[1] or measured.n_channels != c.shape[0]:
        raise ShapeError(
            f"control basis has {control.n_channels} axes for {b.shape[1]} force inputs and "
            f"measured basis {measured.n_channels} channels for {c.shape[0]} outputs"
        )
    if control.offset < 0:
        raise ControllerValueError("control waveforms must start in their own period (offset >= 0)")
    if projection not in ("sampled", "continuous"):
        raise ControllerValueError(
            f"projection must be 'sampled' or 'continuous', got {projection!r}"
        )
    n_per = measured.weights.shape[2] + measured.offset  # samples per period (window end)
    h = period / n_per
    disc = discretise(a, b, h)
    n_in = control.n_coefficients
    n_samples = n_terms * n_per
    forces = np.zeros((n_samples, b.shape[1], n_in))
    length_in = min(control.weights.shape[2], n_samples - control.offset)
    forces[control.offset : control.offset + length_in] = control.weights[
        :, :, :length_in
    ].transpose(2, 1, 0)
    x = np.zeros((n, n_in))
    pad = -min(measured.offset, 0)
    y = np.zeros((pad + n_samples, c.shape[0], n_in))
    continuous = projection == "continuous"
    for s in range(n_samples):
        if continuous:
            y[pad + s] = c @ (disc.e1 @ x + disc.e2 @ forces[s]) / h
        else:
            y[pad + s] = c @ x
        x = disc.ad @ x + disc.bd @ forces[s]
    idx = (
        pad
        + measured.offset
        + np.arange(n_terms)[:, None] * n_per
        + np.arange(measured.weights.shape[2])
    )
    return np.einsum("ict,mtcj->mij", measured.weights, y[idx])


def modal_residues(a: np.ndarray, b: np.ndarray, c: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """
    Return the poles and residue matrices ``C V_l (V^-1 B)_l`` of eq. 6.9.

    Parameters
    ----------
    a, b, c : numpy.ndarray
        Continuous plant matrices.

    Returns
    -------
    poles : numpy.ndarray of complex
        ``lambda_l`` (1/s), shape ``(n,)``.
    residues : numpy.ndarray of complex
        Shape ``(n, p, m)``; ``c (sI - a)^-1 b = sum_l residues[l] / (s - poles[l])``.

    """
    poles, v = linalg.eig(a)
    w = linalg.solve(v, np.asarray(b, dtype=complex))
    cv = np.asarray(c) @ v
    return poles, np.einsum("pl,lm->lpm", cv, w)


def _double_integral(lam: np.ndarray, a0, b0, c0, d0) -> np.ndarray:
    """``int_c^d int_a^{min(t, b)} e^{lam (t - tau)} dtau dt`` (0 where t < a), per lam."""
    out = np.zeros_like(lam, dtype=complex)
    t1, t2 = max(c0, a0), min(d0, b0)
    if t2 > t1:  # t inside the input piece
        out += ((np.exp(lam * (t2 - a0)) - np.exp(lam * (t1 - a0))) / lam - (t2 - t1)) / lam
    t3 = max(c0, b0)
    if d0 > t3:  # t after the input piece
        out += (
            (np.exp(-lam * a0) - np.exp(-lam * b0)) * (np.exp(lam * d0) - np.exp(lam * t3)) / lam**2
        )
    return out


@dataclass(frozen=True)
class Pieces:
    """
    Piecewise-constant waveform: ``values[i]`` on ``[starts[i], ends[i])`` (s, period start 0).

    Attributes
    ----------
    starts, ends, values : numpy.ndarray
        Shape ``(n_pieces,)`` each; times from the period start in s.

    """

    starts: np.ndarray
    ends: np.ndarray
    values: np.ndarray

    @classmethod
    def from_samples(cls, weights: np.ndarray, h: float, offset: int = 0) -> Pieces:
        """Zero-order-hold pieces of a sample vector (sample n on ``[n h, (n+1) h)``)."""
        weights = np.asarray(weights, dtype=float)
        n = np.flatnonzero(weights)
        return cls((n + offset) * h, (n + offset + 1) * h, weights[n])


def haar_pieces(samples_per_rev: int, period: float, p: int, q: int) -> Pieces:
    """
    Return the Haar wavelet ``psi_{p,q}`` of eq. 6.20 as two pieces (sample-orthonormal).

    Parameters
    ----------
    samples_per_rev : int
        Samples per period ``N``.
    period : float
        ``T`` in s.
    p : int
        Thesis level (1 = one wavelet per period, 1 x).
    q : int
        Translation ``1 .. 2^(p-1)``.

    Returns
    -------
    Pieces
        ``+s`` on the first half of ``[t0, t0 + L)``, ``-s`` on the second, with
        ``L = T / 2^(p-1)``, ``t0 = (q - 1) L``, ``s = (2^(p-1) / N)^(1/2)``.

    """
    length = period / 2 ** (p - 1)
    t0 = (q - 1) * length
    s = np.sqrt(2 ** (p - 1) / samples_per_rev)
    return Pieces(
        np.array([t0, t0 + length / 2]), np.array([t0 + length / 2, t0 + length]), np.array([s, -s])
    )


@dataclass(frozen=True)
class ModalTransferFunction:
    """
    ``G(z) = direct + sum_l gains[l] / (z - z_poles[l])`` of one coefficient pair.

    Attributes
    ----------
    direct : numpy.ndarray
        ``A^(0)``, shape ``(p, m)`` (same-period term).
    z_poles : numpy.ndarray of complex
        ``e^{lambda_l T}``.
    gains : numpy.ndarray of complex
        ``r_l X_l P_l``, shape ``(n, p, m)``.

    """

    direct: np.ndarray
    z_poles: np.ndarray
    gains: np.ndarray

    def markov(self, n_terms: int) -> np.ndarray:
        """Return ``A^(0) .. A^(n_terms-1)`` (real), shape ``(n_terms, p, m)``."""
        m = np.arange(1, n_terms)
        powers = self.z_poles[None, :] ** (m[:, None] - 1)
        tail = np.einsum("kl,lpm->kpm", powers, self.gains).real
        return np.concatenate([self.direct[None].real, tail])

    def evaluate(self, z) -> np.ndarray:
        """Return ``G(z)`` at complex points, shape ``(len(z), p, m)``."""
        z = np.atleast_1d(np.asarray(z, dtype=complex))
        return self.direct[None] + np.einsum(
            "fl,lpm->fpm", 1.0 / (z[:, None] - self.z_poles), self.gains
        )


def piecewise_transfer_function(
    poles: np.ndarray,
    residues: np.ndarray,
    period: float,
    h: float,
    force: Pieces,
    weights: Pieces,
) -> ModalTransferFunction:
    """
    Closed-form ``G(z)`` for piecewise-constant force and analysis waveforms (module doc).

    Parameters
    ----------
    poles, residues : numpy.ndarray
        From :func:`modal_residues`.
    period : float
        ``T`` in s.
    h : float
        Sample interval in s (normalisation ``1/h`` of the continuous projection).
    force : Pieces
        Force per unit control coefficient over period 0 (must lie in ``[0, T]``).
    weights : Pieces
        Analysis weights relative to the start of the measured period (``[0, T]``).

    Returns
    -------
    ModalTransferFunction

    """
    lam = np.asarray(poles, dtype=complex)
    if np.any(np.abs(lam) * period < 1e-12):
        raise ControllerValueError("a pole at s = 0 has no closed form here; use wavelet_markov")
    x_t = sum(
        f * np.exp(lam * period) * (np.exp(-lam * a0) - np.exp(-lam * b0)) / lam
        for a0, b0, f in zip(force.starts, force.ends, force.values, strict=True)
    )
    proj = sum(
        w * (np.exp(lam * d0) - np.exp(lam * c0)) / lam / h
        for c0, d0, w in zip(weights.starts, weights.ends, weights.values, strict=True)
    )
    same = sum(
        f * w * _double_integral(lam, a0, b0, c0, d0) / h
        for a0, b0, f in zip(force.starts, force.ends, force.values, strict=True)
        for c0, d0, w in zip(weights.starts, weights.ends, weights.values, strict=True)
    )
    direct = np.einsum("l,lpm->pm", same, residues)
    gains = (x_t * proj)[:, None, None] * residues
    return ModalTransferFunction(direct, np.exp(lam * period), gains)


def haar_transfer_function(
    poles: np.ndarray,
    residues: np.ndarray,
    samples_per_rev: int,
    period: float,
    p: int,
    q: int,
    a: int | None,
    b: int | None,
) -> ModalTransferFunction:
    """
    Closed-form Haar ``G_{p,q,a,b}(z)`` (eq. 6.32 corrected), or ``G^0_{p,q}(z)`` (eq. 6.33).

    Parameters
    ----------
    poles, residues : numpy.ndarray
        From :func:`modal_residues` (sensor channels x force axes).
    samples_per_rev : int
        Samples per period ``N``.
    period : float
        ``T`` in s.
    p, q : int
        Measured level and translation.
    a, b : int or None
        Control level and translation; ``None`` for ``G^0`` (unit constant force over
        the period, the input average ``f^0`` of eq. 6.2).

    Returns
    -------
    ModalTransferFunction

    """
    h = period / samples_per_rev
    lam = np.asarray(poles, dtype=complex)
    if a is None:
        force = Pieces(np.array([0.0]), np.array([period]), np.array([1.0]))
        x_t = np.exp(lam * period) * (1.0 - np.exp(-lam * period)) / lam
    else:
        force = haar_pieces(samples_per_rev, period, a, b)
        s_a, t0, la = force.values[0], force.starts[0], 2 * (force.ends[0] - force.starts[0])
        x_t = (
            s_a * np.exp(lam * period) * np.exp(-lam * t0) * (1 - np.exp(-lam * la / 2)) ** 2 / lam
        )
    weights = haar_pieces(samples_per_rev, period, p, q)
    s_p, s0, mp = weights.values[0], weights.starts[0], 2 * (weights.ends[0] - weights.starts[0])
    proj = -(s_p / h) * np.exp(lam * s0) * (np.exp(lam * mp / 2) - 1) ** 2 / lam
    same = piecewise_transfer_function(poles, residues, period, h, force, weights).direct
    return ModalTransferFunction(same, np.exp(lam * period), (x_t * proj)[:, None, None] * residues)
