"""
Truncated pseudo-inverse series ``(G B_u)^* = sum_k B^(k) z^-k`` (thesis eq. 6.35).

The thesis says only that the ``B^(k)`` "are derived from sets of linear equations" and
truncates the series after 5 or 10 terms (figures 6.3-6.7). We pose those equations as
the least-squares left inverse in the ring of power series in ``z^-1``: with the Markov
parameters ``A^(0) .. A^(M)`` of ``G B_u`` (shape n_y x n_u, eq. 6.34), choose
``B^(0) .. B^(K)`` (n_u x n_y) to minimise

    sum_{k=0}^{H-1} || sum_j B^(j) A^(k-j) - delta_{k,lead} I ||_F^2  +  rho^2 sum_j ||B^(j)||_F^2

over the horizon ``H = K + M + 1`` (every term of the product). ``G`` has more sensors
than control axes, so ``(G B_u)^* G B_u ~ I`` (a left inverse) is the only meaningful
least-squares inverse; ``G B_u (G B_u)^*`` is then a projection, not ``I`` (the
residual of eq. 8.4 that section 8.2 warns may destabilise the loop; check with
:mod:`amb_controller.stability`). ``lead`` (default 0) lets the inverse target
``z^-lead I`` when the first Markov parameters are negligible; the loop delay then
grows by ``lead`` periods. ``rho`` (Tikhonov) limits the inverse's gain on noisy
identified models.

Rank-deficient models (decision)
--------------------------------
With ``rank_rtol > 0`` the inverse is the truncated-SVD (Moore-Penrose) one: the steady-state
gain ``G(1) = U S V^T`` is split at ``s_i > rank_rtol * s_1``, the series is posed on the
reduced model ``U_r^T A^(k) V_r`` (square, full rank) and mapped back,
``B^(k) = V_r B_r^(k) U_r^T``; the steady-state condition becomes ``B(1) G(1) = V_r V_r^T``
(Penrose's ``G B G = G``) instead of the unreachable ``B(1) G(1) = I``. It is needed at
levels p >= 2 with both quadratures: the odd control waveform is the even one advanced by
a quarter period (:func:`amb_controller.basis.control_basis`), so per axis the level-2
waveforms span 3 dimensions, not 4, and at level 3 the odd waveforms repeat the even ones
of translations ``q +- 2`` (4 of 8). ``G_{p,q,p,q} B_u`` then has exact null directions
(4 of 16 at p = 2, 16 of 32 at p = 3, for every ``A^(k)`` and every sensor: the waveforms
themselves are dependent), and the plain least-squares inverse with the ``B(1) G(1) = I``
rows inverts rounding noise (the FE model's figures: ``docs/controller_notes.md``,
"Truncated-SVD inverse at p >= 2"). Directions dropped are those no control coefficient can
move, so nothing observable is lost.

Indexing: ``A^(0)`` is the response, within the same period, of the coefficients
measured over a period to the control coefficients applied over that period. Eq. 6.34
starts at k = 1 because the thesis labels both sequences at the period's end and drops
the same-period term; we keep it (it is not zero for a force applied in the period) and
start both series at k = 0.
"""

from __future__ import annotations

import numpy as np

from amb_controller.errors import ControllerValueError, ShapeError


def pseudo_inverse_series(
    markov: np.ndarray,
    order: int,
    *,
    lead: int = 0,
    regularisation: float = 0.0,
    dc_weight: float = 0.0,
    rank_rtol: float = 0.0,
) -> np.ndarray:
    """
    Return ``B^(0) .. B^(order)`` of the truncated least-squares inverse (eq. 6.35).

    Parameters
    ----------
    markov : numpy.ndarray
        Markov parameters ``A^(0) .. A^(M)`` of ``G B_u``, shape ``(M+1, n_y, n_u)``
        (measured coefficient per control coefficient).
    order : int
        Truncation order K (the thesis uses 5 and 10), >= 0.
    lead : int
        Target delay of the product ``B * A`` (0 = identity at k = 0).
    regularisation : float
        Tikhonov weight ``rho`` >= 0 (same units as ``A``), 0 for plain least squares.
    dc_weight : float
        Weight >= 0 of the extra equations ``B(1) G(1) = I`` (steady-state gain of the
        product, with ``G(1) = sum_k A^(k)``). Truncation leaves ``B(1) G(1) != I``; the
        steady-state predictor of eq. 7.6 needs it, so use e.g. 10 there. 0 = off.
    rank_rtol : float
        Relative singular-value cutoff (>= 0, < 1) of ``G(1)``: directions below
        ``rank_rtol * s_max`` are dropped (truncated-SVD inverse, module docstring); e.g.
        1e-8 for an FE model, larger for an identified one. 0 = off (full rank assumed).

    Returns
    -------
    numpy.ndarray
        Shape ``(order + 1, n_u, n_y)`` (control coefficient per measured coefficient).

    """
    markov = np.asarray(markov, dtype=float)
    if markov.ndim != 3:
        raise ShapeError(f"markov must have shape (M+1, n_y, n_u), got {markov.shape}")
    if int(order) != order or order < 0:
        raise ControllerValueError(f"order must be an integer >= 0, got {order}")
    if lead < 0 or lead > order + markov.shape[0] - 1:
        raise ControllerValueError(
            f"lead must lie in [0, {order + markov.shape[0] - 1}], got {lead}"
        )
    if regularisation < 0:
        raise ControllerValueError(f"regularisation must be >= 0, got {regularisation}")
    if not 0.0 <= rank_rtol < 1.0:
        raise ControllerValueError(f"rank_rtol must lie in [0, 1), got {rank_rtol}")
    if dc_weight < 0:
        raise ControllerValueError(f"dc_weight must be >= 0, got {dc_weight}")
    if rank_rtol > 0:
        u, sv, vt = np.linalg.svd(dc_gain(markov))
        rank = int(np.count_nonzero(sv > rank_rtol * sv[0])) if sv[0] > 0 else 0
        if rank == 0:
            raise ControllerValueError(
                "G(1) is zero: no steady-state gain to invert; check the model (Markov "
                "parameters) or use rank_rtol = 0"
            )
        u_r, v_r = u[:, :rank], vt[:rank].T
        reduced = np.einsum("ya,kyu,ub->kab", u_r, markov, v_r)
        b_r = pseudo_inverse_series(
            reduced, order, lead=lead, regularisation=regularisation, dc_weight=dc_weight
        )
        return np.einsum("ua,kab,yb->kuy", v_r, b_r, u_r)
    n_terms, n_y, n_u = markov.shape
    horizon = order + n_terms
    # X = [B0 .. BK] (n_u x (K+1) n_y);  X T = E, T block (j, k) = A^(k-j).
    big_t = np.zeros(((order + 1) * n_y, horizon * n_u))
    for j in range(order + 1):
        for m in range(n_terms):
            k = j + m
            big_t[j * n_y : (j + 1) * n_y, k * n_u : (k + 1) * n_u] = markov[m]
    target = np.zeros((n_u, horizon * n_u))
    target[:, lead * n_u : (lead + 1) * n_u] = np.eye(n_u)
    lhs = big_t.T
    rhs = target.T
    if dc_weight > 0:
        # (sum_j B_j) G(1) = I  ->  X [G(1); G(1); ...] = I
        gdc = np.tile(markov.sum(axis=0), (order + 1, 1))
        lhs = np.vstack([lhs, dc_weight * gdc.T])
        rhs = np.vstack([rhs, dc_weight * np.eye(n_u)])
    if regularisation > 0:
        n_unknown = lhs.shape[1]
        lhs = np.vstack([lhs, regularisation * np.eye(n_unknown)])
        rhs = np.vstack([rhs, np.zeros((n_unknown, n_u))])
    solution, *_ = np.linalg.lstsq(lhs, rhs, rcond=None)
    return solution.T.reshape(n_u, order + 1, n_y).transpose(1, 0, 2)


def series_product(left: np.ndarray, right: np.ndarray) -> np.ndarray:
    """
    Return the power-series product ``(sum_j L_j z^-j)(sum_k R_k z^-k)``.

    Parameters
    ----------
    left : numpy.ndarray
        Shape ``(J, a, b)``.
    right : numpy.ndarray
        Shape ``(K, b, c)``.

    Returns
    -------
    numpy.ndarray
        Shape ``(J + K - 1, a, c)``.

    """
    left = np.asarray(left)
    right = np.asarray(right)
    out = np.zeros((left.shape[0] + right.shape[0] - 1, left.shape[1], right.shape[2]))
    for j in range(left.shape[0]):
        out[j : j + right.shape[0]] += np.einsum("ab,kbc->kac", left[j], right)
    return out


def dc_gain(markov: np.ndarray) -> np.ndarray:
    """
    Return ``G(1) = sum_k A^(k)``, the steady-state gain of a Markov series.

    Parameters
    ----------
    markov : numpy.ndarray
        Shape ``(M+1, n_y, n_u)``.

    Returns
    -------
    numpy.ndarray
        Shape ``(n_y, n_u)``.

    """
    return np.asarray(markov).sum(axis=0)
