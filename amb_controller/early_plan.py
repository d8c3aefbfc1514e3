"""
The early action's force against an estimated change ((E2)-(E4), :mod:`.early_action`).

A steady 1 x forward-whirl force at the bearings that cancels the change's steady response
(E2), a transient force over the first ``M`` samples that damps what the change excited before
the force could act (E3), both within the force budget, made smoother (a ladder of smoothings)
or scaled until no step per sample exceeds the amplifiers' slew budget (E4). The matrices are
computed once from the model (:class:`PlanMaker`); a plan costs a few matrix products.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from amb_controller.early_config import EarlyActionConfig
from amb_controller.early_model import EarlyActionModel

__all__ = ["Plan", "PlanMaker", "block_toeplitz", "periodic", "step_limit"]


@dataclass
class Plan:
    """
    An accepted change's force, N.

    ``steady`` ``(N, 4)`` in every period from the first, plus ``transient`` blocks ``(N, 4)``
    by period; the smoothing and the largest step per sample it got from (E3)-(E4).
    """

    steady: np.ndarray
    transient: dict[int, np.ndarray] = field(default_factory=dict)
    smoothing: float = 0.0
    largest_step: float = 0.0


def _forward_whirl(n: int, N: int) -> np.ndarray:
    """Force patterns (n, 4 axes, 4 weights) of a 1 x forward whirl at both bearings."""
    phi = 2.0 * math.pi * np.arange(n) / N
    c, s = np.cos(phi), np.sin(phi)
    r = np.zeros((n, 4, 4))
    for b in (0, 1):  # x = Re(D e^{i phi}), y = Re(-i D e^{i phi}) (eq. 3.3's convention)
        r[:, 2 * b, 2 * b], r[:, 2 * b, 2 * b + 1] = c, -s
        r[:, 2 * b + 1, 2 * b], r[:, 2 * b + 1, 2 * b + 1] = s, c
    return r


def block_toeplitz(h: np.ndarray, n_in: int, n_out: int) -> np.ndarray:
    """Block Toeplitz ``(n_out n_s, n_in 4)``: outputs 0..n_out-1 of forces at 0..n_in-1."""
    L, n_s, n_a = h.shape
    t = np.zeros((n_out, n_s, n_in, n_a))
    for j in range(n_in):
        ln = min(n_out - j, L)
        if ln > 0:
            t[j : j + ln, :, j, :] = h[:ln]
    return t.reshape(n_out * n_s, n_in * n_a)


def periodic(period: np.ndarray, span: int) -> np.ndarray:
    """``period`` (one period of samples along axis 0) repeated over ``span`` samples (a copy)."""
    return np.tile(period, (-(-span // period.shape[0]), *(1,) * (period.ndim - 1)))[:span]


def _smoothing_ladder(first: float) -> tuple[float, ...]:
    """The smoothings (E3) tried in turn when a plan steps faster than the amplifiers can."""
    return (first, *(mu for mu in (0.25, 0.5, 1.0, 2.0, 4.0, 8.0, 16.0) if mu > first))


def _largest_step(steady: np.ndarray, transient: np.ndarray) -> float:
    """Largest sample-to-sample step of the added force from ``k0`` on, N (from zero before).

    ``steady`` ``(N, 4)`` repeats every period; ``transient`` ``(M, 4)`` adds to its first
    ``M`` samples; a period more than ``M`` covers the steady force's own steps.
    """
    m = transient.shape[0]
    force = periodic(steady, m + steady.shape[0])
    force[:m] += transient
    return float(np.max(np.abs(np.diff(force, axis=0, prepend=0.0))))


def step_limit(model: EarlyActionModel, config: EarlyActionConfig) -> float:
    """
    The plan's largest step per sample, N (E4).

    ``slew_budget`` of the amplifiers' slew over one sample at the model's speed; inf when
    the model has no slew rate or no speed.
    """
    if math.isinf(model.slew_rate) or model.omega <= 0.0:
        return math.inf
    sample_time = 2.0 * math.pi / (model.omega * model.samples_per_rev)
    return config.slew_budget * model.slew_rate * sample_time


class PlanMaker:
    """
    (E2)-(E4) for one model and configuration, the matrices computed once.

    Parameters
    ----------
    model : EarlyActionModel
    config : EarlyActionConfig
    horizon : int
        ``L``, samples of the predicted response the plan is made against.

    Attributes
    ----------
    M : int
        Samples of the transient force.
    step_limit : float
        The plan's largest step per sample, N (:func:`step_limit`).
    """

    def __init__(self, model: EarlyActionModel, config: EarlyActionConfig, horizon: int) -> None:
        self.config = config
        N = model.samples_per_rev
        h = model.bearing_markov
        L = int(horizon)
        n_s = h.shape[1]
        self.N, self.L = N, L
        self._scale = 1.0 - config.gain_margin**2
        # rows of the plan's objective: the objective sensors at every horizon sample
        obj = np.zeros((L, n_s), dtype=bool)
        obj[:, list(model.objective)] = True
        obj = obj.ravel()
        # (E2): steady forward-whirl force from k0 against the horizon's last two periods
        fw = _forward_whirl(L, N)
        hz = block_toeplitz(h, L, L)
        self._c = np.stack([hz @ fw[:, :, u].ravel() for u in range(4)], axis=1)  # (L n_s, 4)
        tail = np.zeros(L * n_s, dtype=bool)
        tail[(L - 2 * N) * n_s :] = True
        self._tail = tail & obj
        self._steady_gain = -np.linalg.pinv(self._c[self._tail])
        self._steady_pattern = fw[:N]  # (N, 4, 4)
        # (E3): transient force over M samples, for each smoothing of the ladder
        M = config.transient_samples
        self.M = M
        self.step_limit = step_limit(model, config)
        if M:
            hm = block_toeplitz(h, M, L)
            self._h_m = hm.astype(np.float32)  # the residual check only
            ho = hm[obj]
            self._ho_t = ho.T.astype(np.float32)
            scale = np.linalg.norm(ho, 2)
            lam = config.transient_weight * scale
            # first differences of the added force per axis over the M samples, from zero
            # before k0 (row 0) to the steady force after them (row M)
            d = np.kron(np.eye(M + 1, M) - np.eye(M + 1, M, -1), np.eye(4))
            self._d_t = d.T
            gram = ho.T @ ho + lam**2 * np.eye(M * 4)
            dd = d.T @ d
            mu0 = config.transient_smoothing
            ladder = (mu0,) if math.isinf(self.step_limit) else _smoothing_ladder(mu0)
            self._ladder = [
                (mu, (mu * scale) ** 2, np.linalg.inv(gram + (mu * scale) ** 2 * dd))
                for mu in ladder
            ]
            self._obj = obj

    def make(self, yd: np.ndarray, first: int, force_limit: float) -> tuple[Plan, np.ndarray]:
        """
        The plan against ``yd``, the change's predicted response from ``k0`` (``(L n_s,)``, m).

        ``first`` is the plan's first period, ``force_limit`` the per-axis limit of the
        wavelet force (N; ``config.force_budget`` of it). Returns the plan and the residual it
        predicts from ``k0``, ``(L, n_s)``, m.
        """
        N = self.N
        w_full = self._steady_gain @ yd[self._tail]  # (E2) before the robust scale
        w = self._scale * w_full
        steady = np.einsum("nau,u->na", self._steady_pattern, w)
        df = np.zeros((self.M, 4))
        if self.M:
            free = (yd + self._c @ w_full)[self._obj]
            pulled = self._scale * (self._ho_t @ free.astype(np.float32)).astype(float)
            # the steady force's own steps: switched on at k0, then sample to sample
            tiled = np.concatenate([np.zeros((1, 4)), periodic(steady, self.M + 1)])
            jumps = np.diff(tiled, axis=0).ravel()
            budget = self.config.force_budget * force_limit
            room = max(budget - float(np.max(np.abs(steady))), 0.0)
            for mu, weight, inverse in self._ladder:  # (E3), smoothest last
                smoothing = mu
                df = -(inverse @ (pulled + weight * (self._d_t @ jumps))).reshape(self.M, 4)
                peak = float(np.max(np.abs(df)))
                if peak > room:
                    df *= room / peak
                step = _largest_step(steady, df)
                if step <= self.step_limit:
                    break
        else:
            smoothing, step = 0.0, _largest_step(steady, df)
        if step > self.step_limit:  # even the smoothest: the whole plan scaled down (E4)
            shrink = self.step_limit / step
            w, steady, df, step = shrink * w, shrink * steady, shrink * df, self.step_limit
        plan = Plan(steady=steady, smoothing=float(smoothing), largest_step=float(step))
        residual = yd + self._c @ w
        if self.M:
            residual += (self._h_m @ df.ravel().astype(np.float32)).astype(float)
            for j in range(0, self.M, N):
                block = np.zeros((N, 4))
                part = df[j : j + N]
                block[: len(part)] = part
                plan.transient[first + j // N] = block
        return plan, residual.reshape(self.L, -1)
