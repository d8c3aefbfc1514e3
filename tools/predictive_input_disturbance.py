"""
Experiment (not a shipped controller): the predictive law with an input-disturbance estimator.

:mod:`amb_controller.predictive` estimates the disturbance as a step at the measured
coefficients (P1). Here it is a step of an equivalent control input ``w`` instead (offset-free
MPC with an input disturbance model, Pannocchia and Rawlings 2003): the state
``x = (v[k-1] .. v[k-M], w)``, ``v = u + w``, with ``q[k] = sum_j A_j v[k-j]`` and ``w`` a random
walk, is estimated by the steady-state Kalman filter (process noise ``I`` on ``w``,
measurement noise ``(noise * sigma_max(G(1)))^2 I``); the prediction (P2) holds ``w`` constant,
so it anticipates how the disturbance's response still grows through the plant's dynamics
(a mass loss is a step of unbalance force, whose response builds up over revolutions). The
cost (P3) and the receding horizon are those of the module. ``tools/predictive_sweep.py
--input-noise NOISE`` runs it in place of the shipped law; what it gave and why it is not
shipped: docs/controller_notes.md, "Predictive controller".
"""

import numpy as np
from scipy import linalg

from amb_controller.inverse import dc_gain
from amb_controller.lti import DiscreteStateSpace
from amb_controller.transient import ControlStep


def _qp_first(phi, free, pick, n_u, p, c, rho, sigma):
    diff = np.eye(c * n_u) - np.eye(c * n_u, k=-n_u)
    held = np.ones(c)
    held[-1] = p - c + 1
    lhs = phi.T @ phi + rho**2 * diff.T @ diff + sigma**2 * np.kron(np.diag(held), np.eye(n_u))
    rhs = rho**2 * diff.T @ pick - phi.T @ free
    return np.linalg.solve(lhs, rhs)[:n_u]


class InputDisturbanceController:
    """The predictive law of amb_controller.predictive on a Kalman input-disturbance estimate.

    Same interface as :class:`~amb_controller.predictive.PredictiveController`; ``noise`` is the
    dimensionless measurement noise of the module docstring (small: fast estimate).
    """

    tracks_applied = True

    def __init__(
        self, markov, delay, horizon=20, moves=3, move_weight=0.25, input_weight=0.03, noise=0.3
    ):
        A = np.asarray(markov, float)
        n_terms, n_y, n_u = A.shape
        M, i, p, c = n_terms - 1, int(delay), int(horizon), int(moves)
        self.delay, self.n_outputs, self.n_inputs = i, n_u, n_y
        self.M = M
        nv = M * n_u
        n = nv + n_u
        # state x = (v[k-1..k-M], w)
        F = np.zeros((n, n))
        G = np.zeros((n, n_u))
        if M:
            F[:n_u, nv:] = np.eye(n_u)  # v[k] = u[k] + w[k]
            G[:n_u] = np.eye(n_u)
            F[n_u:nv, : nv - n_u] = np.eye(nv - n_u)
        F[nv:, nv:] = np.eye(n_u)
        H = np.zeros((n_y, n))
        for j in range(1, M + 1):
            H[:, (j - 1) * n_u : j * n_u] = A[j]
        H[:, nv:] = A[0]
        scale = np.linalg.norm(dc_gain(A), 2)
        Q = np.zeros((n, n))
        Q[nv:, nv:] = np.eye(n_u)
        R = (noise * scale) ** 2 * np.eye(n_y)
        P = linalg.solve_discrete_are(F.T, H.T, Q, R)
        L = P @ H.T @ np.linalg.inv(H @ P @ H.T + R)
        self.F, self.G, self.H, self.L, self.A0 = F, G, H, L, A[0]
        # prediction over horizon: z = (xf (n), u[k+i-1..k] (i n_u))
        nz = n + i * n_u

        def ublk(t_minus_k):  # u[k + t] for 0 <= t < i, row i-1-t
            r = i - 1 - t_minus_k
            return slice(n + r * n_u, n + (r + 1) * n_u)

        wsl = slice(nv, n)
        phi = np.zeros((p * n_y, c * n_u))
        free = np.zeros((p * n_y, nz))
        for h in range(p):
            rows = slice(h * n_y, (h + 1) * n_y)
            for j in range(n_terms):
                t = i + h - j  # v[k + t]
                if t >= i:
                    mv = min(t - i, c - 1)
                    phi[rows, mv * n_u : (mv + 1) * n_u] += A[j]
                    free[rows, wsl] += A[j]
                elif t >= 0:
                    free[rows, ublk(t)] += A[j]
                    free[rows, wsl] += A[j]
                else:  # v[k+t], t<0: state block -t-1
                    b = -t - 1
                    free[rows, b * n_u : (b + 1) * n_u] += A[j]
        pick = np.zeros((c * n_u, nz))
        pick[:n_u, ublk(i - 1)] = np.eye(n_u)
        self.K = _qp_first(phi, free, pick, n_u, p, c, move_weight * scale, input_weight * scale)
        self.n = n
        self.reset()

    def reset(self):
        """Forget the estimate and the applied inputs."""
        self._xp = np.zeros(self.n)
        self._applied = {}
        self._last = None

    def get_state(self):
        """Return a copy of the state."""
        return (self._xp.copy(), {k: v.copy() for k, v in self._applied.items()}, self._last)

    def set_state(self, s):
        """Restore a state of :meth:`get_state`."""
        self._xp, self._applied, self._last = (
            s[0].copy(),
            {k: v.copy() for k, v in s[1].items()},
            s[2],
        )

    def skip(self, k):
        """Mark period k consumed."""
        self._last = int(k)

    def record_applied(self, p, u):
        """Record what the plant applies over period p."""
        self._applied[int(p)] = np.array(u, float)

    def step(self, k, q):
        """Kalman update with q[k], then the command for k + i."""
        q = np.asarray(q, float)
        k = int(k)
        i = self.delay
        zero = np.zeros(self.n_outputs)
        uk = self._applied.get(k, zero)
        xf = self._xp + self.L @ (q - self.H @ self._xp - self.A0 @ uk)
        us = [self._applied.get(k + i - 1 - r, zero) for r in range(i)]
        cmd = self.K @ np.concatenate([xf, *us])
        self._applied[k + i] = cmd
        self._xp = self.F @ xf + self.G @ uk
        for old in [p for p in self._applied if p <= k]:
            del self._applied[old]
        self._last = k
        return ControlStep(k + i, k, cmd)

    def state_space(self):
        """Realisation from measured to applied coefficients (for the own-model radius)."""
        n, nu, ny, i = self.n, self.n_outputs, self.n_inputs, self.delay
        ns = n + i * nu
        a = np.zeros((ns, ns))
        b = np.zeros((ns, ny))
        c = np.zeros((nu, ns))
        last = slice(n + (i - 1) * nu, n + i * nu)  # u[k]
        ILH = np.eye(n) - self.L @ self.H
        # xf = ILH xp + L q - L A0 u[k]
        xf_x = np.zeros((n, ns))
        xf_x[:, :n] = ILH
        xf_x[:, last] -= self.L @ self.A0
        xf_q = self.L
        # z = (xf, u[k+i-1..k]) ; u blocks in state are rows n.. in the same order
        z_x = np.vstack([xf_x, np.hstack([np.zeros((i * nu, n)), np.eye(i * nu)])])
        z_q = np.vstack([xf_q, np.zeros((i * nu, ny))])
        cmd_x, cmd_q = self.K @ z_x, self.K @ z_q
        # xp' = F xf + G u[k]
        a[:n] = self.F @ xf_x
        a[:n, last] += self.G
        b[:n] = self.F @ xf_q
        # new u blocks: (cmd, u[k+i-1], ..., u[k+1])
        a[n : n + nu] = cmd_x
        b[n : n + nu] = cmd_q
        if i > 1:
            a[n + nu :, n : n + (i - 1) * nu] = np.eye((i - 1) * nu)
        c[:, last] = np.eye(nu)
        return DiscreteStateSpace(a, b, c, np.zeros((nu, ny)))
