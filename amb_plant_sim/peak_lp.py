r"""
The smallest peak a force sequence can give a sampled linear system: a linear program.

The system is known only through responses, which is all a linear time-invariant sampled
system needs: the free response ``Y0[n]`` of every constrained output (what happens with no
added force) and the Markov parameters ``M[l]`` (the response at lag ``l`` to a unit force held
over one sample). The added force ``u_j`` (``m`` channels) is free from sample ``k0`` on; the
output is, by superposition,

.. math::

    y[n] = Y_0[n] + \sum_{k_0 \le j \le n} M[n - j] \, u_j .

Formulation
-----------
Decision variables: ``u_j`` for ``j = k0 .. k0 + D - 1`` (``D = R N``: ``R`` revolutions of
``N`` samples), the force after them repeating the last revolution (``u_j = u_{j-N}`` for
``j >= k0 + D``: under a synchronous disturbance a periodic force gives a periodic steady
state, so the tail neither grows nor is left to chance), and the peak ``t``. The outputs are
evaluated on the window ``n_a <= n < K`` with ``K = k0 + D + R_tail N``::

    minimise    t
    subject to  -t <= y_d[n]_c <= t                   every objective channel c, n_a <= n < K
                |y_f[n]_c| <= F_max                   total (feedback + added) force, k0 <= n < K
                |d_q . p_b[n]| <= r_b cos(pi / 8)     clearance b, 4 directions q, n_a <= n < K
                |u_j,c| <= F_add                      added force

with ``y = Y0 + T u`` and ``T`` the block-Toeplitz matrix of the ``M[l]`` (the tail folded
onto the last revolution's columns). The clearance rows keep each journal inside the octagon
inscribed in its clearance circle (``d_q`` at 0, 45, 90, 135 degrees; conservative by at most
``1 - cos(pi/8)`` = 7.6 % of the clearance). All constraints are linear in ``(u, t)``, so the
problem is a linear program (solved by HiGHS through :func:`scipy.optimize.linprog`).

Most clearance rows are slack at the optimum. The objective and force rows are in the program
from the start; the rows of a family marked ``cut`` (the clearances) are added when violated,
after each solve (cutting planes), until none is violated by more than its tolerance; the
final ``(u, t)`` is then optimal for the full problem (it is optimal for a relaxation and
satisfies every row). HiGHS's interior-point method with crossover is used: on these dense
rows it is several times faster than its simplex.

Second objective. With the peak fixed at its optimum ``t*`` (times ``1 + slack``), the fewest
revolutions ``r`` after which every objective output stays within a level (``|y_d[n]| <=
level`` for ``n >= n_a + r N``) is found by bisection on the feasibility of the same program.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.sparse
from numpy.typing import NDArray

from amb_plant_sim.errors import BoundExceededError, SimulationError

#: octagon directions of the clearance rows (unit vectors at 0, 45, 90, 135 degrees)
OCTAGON = np.array([[1.0, 0.0], [0.5**0.5, 0.5**0.5], [0.0, 1.0], [-(0.5**0.5), 0.5**0.5]])


@dataclass(frozen=True)
class Family:
    """
    One family of constrained outputs: free response, Markov parameters and the bound.

    Attributes
    ----------
    name : str
        Reported name (``objective``, ``force``, ``clearance``).
    free : ndarray (K, p)
        Free response ``Y0[n]`` (no added force) from sample 0, in the family's unit.
    markov : ndarray (K, p, m)
        ``M[l]`` for ``l = 0 .. K - 1``.
    bound : ndarray (p,) or None
        ``|y[n]_c| <= bound_c``; ``None`` for the objective family (``|y| <= t``).
    start : int
        First constrained sample.
    tol : float
        Violation tolerated before a row is added, in the family's unit.
    cut : bool
        Rows enter by cutting planes (mostly slack, e.g. clearances) instead of all at once.
    """

    name: str
    free: NDArray[np.float64]
    markov: NDArray[np.float64]
    bound: NDArray[np.float64] | None
    start: int
    tol: float
    cut: bool = False


@dataclass
class PeakSolution:
    """
    Result of :meth:`PeakProgram.solve`.

    Attributes
    ----------
    peak : float
        The peak of the objective outputs over the window under ``force`` (objective unit):
        the smallest possible one unless a settling level or ``least_force`` was asked.
    force : ndarray (K - k0, m)
        Added force from ``k0`` to the window end (tail included).
    outputs : dict of ndarray (K, p)
        Every family's output under that force.
    rows : dict of int
        Rows of each family in the last linear program.
    iterations : int
        Linear programs solved.
    """

    peak: float
    force: NDArray[np.float64]
    outputs: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    rows: dict[str, int] = field(default_factory=dict)
    iterations: int = 0


def toeplitz_lift(
    markov: NDArray[np.float64], k0: int, n_dec: int, period: int, start: int, end: int
) -> NDArray[np.float64]:
    """
    The matrix ``T`` of ``y[start:end] - Y0[start:end] = T u``.

    Rows are ordered ``(n, c)`` (sample, output channel), columns ``(j, i)`` (decision sample,
    input channel).

    Parameters
    ----------
    markov : ndarray (K, p, m)
        Markov parameters, ``K >= end``.
    k0 : int
        First sample of the added force.
    n_dec : int
        Decision samples (a multiple of ``period``); the force from ``k0 + n_dec`` to ``end``
        repeats the last ``period`` decisions.
    period : int
        Samples of the repeated tail's period.
    start, end : int
        Output rows ``start <= n < end``.

    Returns
    -------
    ndarray ((end - start) p, n_dec m)
    """
    p, m = markov.shape[1:]
    n = np.arange(start, end)
    j = np.arange(k0, end)
    lag = n[:, None] - j[None, :]
    blocks = np.where((lag >= 0)[..., None, None], markov[np.clip(lag, 0, None)], 0.0)
    dec = np.arange(j.size) - n_dec  # >= 0: the tail
    col = np.where(dec < 0, np.arange(j.size), n_dec - period + np.mod(dec, period))
    folded = np.zeros((n.size, n_dec, p, m))
    np.add.at(folded, (slice(None), col), blocks)
    return folded.transpose(0, 2, 1, 3).reshape(n.size * p, n_dec * m)


class PeakProgram:
    """
    The linear program of the module docstring, lifted once and solved by cutting planes.

    Parameters
    ----------
    families : list of Family
        Exactly one family with ``bound=None`` (the objective), any number of bounded ones;
        all with the same number of inputs ``m`` and covering the window.
    k0 : int
        First sample the added force can act on.
    revolutions, tail_revolutions : int
        ``R`` (free decisions) and ``R_tail`` (periodic tail) in periods of ``period`` samples.
    period : int
        Samples per revolution ``N``.
    added_limit : float
        ``F_add``: bound on each added-force channel.

    Raises
    ------
    SimulationError
        Inconsistent families.
    BoundExceededError
        A bound already exceeded before ``k0`` (infeasible whatever the force).
    """

    def __init__(
        self,
        families: list[Family],
        k0: int,
        revolutions: int,
        tail_revolutions: int,
        period: int,
        added_limit: float,
    ) -> None:
        objective = [f for f in families if f.bound is None]
        if len(objective) != 1:
            raise SimulationError("PeakProgram needs exactly one objective family (bound=None)")
        self.k0, self.period = int(k0), int(period)
        self.n_dec = int(revolutions) * self.period
        self.tail = int(tail_revolutions)
        self.end = self.k0 + self.n_dec + self.tail * self.period
        self.m = families[0].markov.shape[2]
        for f in families:
            if f.free.shape[0] < self.end or f.markov.shape[0] < self.end:
                raise SimulationError(
                    f"family {f.name}: responses of {f.free.shape[0]} samples and Markov "
                    f"parameters {f.markov.shape} do not cover the window to sample {self.end}"
                )
            if f.markov.shape[2] != self.m:
                raise SimulationError(f"family {f.name}: {f.markov.shape[2]} inputs, not {self.m}")
            if f.bound is not None and f.start < self.k0:
                before = np.abs(f.free[f.start : self.k0]) > f.bound[None, :] + f.tol
                if np.any(before):
                    n_over = int(np.argmax(np.any(before, axis=1))) + f.start
                    raise BoundExceededError(
                        f"{f.name} bound already exceeded at sample {n_over}, before the first "
                        f"sample the added force can act on ({self.k0}): no force sequence meets it"
                    )
        self.families = families
        self.objective = objective[0]
        self._T = [
            toeplitz_lift(f.markov, self.k0, self.n_dec, self.period, f.start, self.end)
            for f in families
        ]
        self._y0 = [f.free[f.start : self.end].ravel() for f in families]
        self._limit = [
            None if f.bound is None else np.tile(f.bound, self.end - f.start) for f in families
        ]
        ob = self._ob = families.index(self.objective)
        #: the objective rows no force reaches (zero rows of T: before k0, and k0 itself where
        #: M[0] = 0) keep their free response: t >= their largest |y0|
        free_rows = ~np.any(self._T[ob], axis=1)
        self.floor = float(np.abs(self._y0[ob][free_rows]).max()) if free_rows.any() else 0.0
        self.added_limit = float(added_limit)

    def solve(
        self,
        cap: float | None = None,
        level: float = math.inf,
        settle_from: int | None = None,
        least_force: bool = False,
        max_iterations: int = 30,
    ) -> PeakSolution | None:
        """
        Minimise the peak, or the added force under a capped peak and a settling requirement.

        Parameters
        ----------
        cap : float, optional
            Upper bound on ``t``.
        level, settle_from : float, int, optional
            Every objective output from sample ``settle_from`` on within ``level``.
        least_force : bool
            Minimise ``sum |u_j,c|`` (the least added force meeting the rows) instead of ``t``:
            among the many forces that reach the optimal peak, the one a person would apply.
        max_iterations : int
            Cutting-plane rounds before giving up.

        Returns
        -------
        PeakSolution or None
            ``None`` when the constraints cannot be met (infeasible).
        """
        n_u = self.n_dec * self.m
        if cap is not None and cap < self.floor:
            return None
        n_s = n_u if least_force else 0
        c = np.zeros(n_u + 1 + n_s)
        if least_force:
            c[n_u + 1 :] = 1.0
        else:
            c[n_u] = 1.0
        bounds = [(-self.added_limit, self.added_limit)] * n_u + [(self.floor, cap)]
        bounds += [(0.0, None)] * n_s
        active = [
            np.ones(T.shape[0], bool) if not f.cut else np.zeros(T.shape[0], bool)
            for f, T in zip(self.families, self._T, strict=True)
        ]
        ob = self.objective
        dense, rhs = [], []
        if settle_from is not None:  # |y| <= level for the objective from settle_from on
            first = max(0, settle_from - ob.start) * ob.free.shape[1]
            Tc, yc = self._T[self._ob][first:], self._y0[self._ob][first:]
            zc = np.zeros((Tc.shape[0], 1))
            dense += [np.hstack([Tc, zc]), np.hstack([-Tc, zc])]
            rhs += [level - yc, level + yc]
        sparse_rows = []
        if least_force:  # s >= |u|: u - s <= 0, -u - s <= 0
            eye = scipy.sparse.eye_array(n_u, format="csr")
            zc = scipy.sparse.csr_array((n_u, 1))
            sparse_rows = [
                scipy.sparse.hstack([eye, zc, -eye]),
                scipy.sparse.hstack([-eye, zc, -eye]),
            ]
        iterations = 0
        while True:
            iterations += 1
            if iterations > max_iterations:
                raise SimulationError(f"cutting planes did not converge in {max_iterations} rounds")
            A_parts, b_parts = list(dense), list(rhs)
            for f, T, y0, lim, rows in zip(
                self.families, self._T, self._y0, self._limit, active, strict=True
            ):
                if not rows.any():
                    continue
                Tr, yr = T[rows], y0[rows]
                # |y| <= t for the objective (t's column -1, bound 0), |y| <= lim otherwise
                col = np.full((Tr.shape[0], 1), -1.0 if f.bound is None else 0.0)
                bound = 0.0 if f.bound is None else lim[rows]
                A_parts += [np.hstack([Tr, col]), np.hstack([-Tr, col])]
                b_parts += [bound - yr, bound + yr]
            A = scipy.sparse.csr_array(np.vstack(A_parts))
            if least_force:
                A = scipy.sparse.vstack(
                    [
                        scipy.sparse.hstack([A, scipy.sparse.csr_array((A.shape[0], n_s))]),
                        *sparse_rows,
                    ],
                    format="csr",
                )
                b_parts.append(np.zeros(2 * n_u))
            res = scipy.optimize.linprog(
                c, A_ub=A, b_ub=np.concatenate(b_parts), bounds=bounds, method="highs-ipm"
            )
            if res.status == 2:
                return None
            if res.status != 0:
                raise SimulationError(f"linear program failed: {res.message}")
            u = res.x[:n_u]
            added = False
            for f, T, y0, lim, rows in zip(
                self.families, self._T, self._y0, self._limit, active, strict=True
            ):
                if not f.cut:
                    continue
                new = (np.abs(y0 + T @ u) - lim > f.tol) & ~rows
                if new.any():
                    rows |= new
                    added = True
            if not added:
                break
        force = u.reshape(self.n_dec, self.m)
        outputs = {}
        for f, T, y0 in zip(self.families, self._T, self._y0, strict=True):
            full = f.free[: self.end].copy()
            full[f.start : self.end] = (y0 + T @ u).reshape(self.end - f.start, -1)
            outputs[f.name] = full
        return PeakSolution(
            peak=float(np.abs(outputs[ob.name][ob.start : self.end]).max()),
            force=np.vstack([force, np.tile(force[-self.period :], (self.tail, 1))]),
            outputs=outputs,
            rows={f.name: int(r.sum()) for f, r in zip(self.families, active, strict=True)},
            iterations=iterations,
        )

    def settle(self, peak: float, level: float, slack: float = 1e-6) -> tuple[int, PeakSolution]:
        """
        Fewest revolutions, from the objective's start, after which the output stays in ``level``.

        The peak stays at most ``peak (1 + slack)`` (lexicographic second objective); the
        revolutions are found by bisection on feasibility (more revolutions only loosen it).

        Returns
        -------
        revolutions : int
            From the objective family's ``start``; the window's length when never met.
        solution : PeakSolution
            A force meeting it (the peak-optimal one when never met).
        """
        ob = self.objective
        n_rev = (self.end - ob.start) // self.period
        cap = peak * (1 + slack)
        best = None
        lo, hi = 0, n_rev
        while lo < hi:
            mid = (lo + hi) // 2
            sol = self.solve(
                cap=cap, level=level, settle_from=ob.start + mid * self.period, least_force=True
            )
            if sol is None:
                lo = mid + 1
            else:
                hi, best = mid, sol
        if best is None:
            return n_rev, self.solve(cap=cap, least_force=True)
        return lo, best


def octagon_bound(radius: float) -> float:
    """Apothem of the octagon inscribed in a circle of ``radius`` (the clearance rows' bound)."""
    return radius * math.cos(math.pi / 8)
