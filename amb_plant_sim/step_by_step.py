"""
Step-by-step integration of one sample of :class:`~amb_plant_sim.simulator.PlantSimulator`.

:class:`StepByStepIntegration` is mixed into the simulator; it runs the samples the lifted
linear map cannot: contact, force saturation, the nonlinear AMB law, a lost AMB channel or a
stuck/zeroed PID sensor. The plant advances internal step by internal step (exact response to
held inputs), with ``contact.substeps`` sub-steps per internal step while a contact is active;
the contact force of each sub-step is linearly implicit (one Newton step on the force law at
the sub-step end, through the exact response of the journal to a held force), and the friction's
reaction spins the inner race of a rolling auxiliary bearing (``contact.race_step``). The PID
runs at the internal rate with conditional-integration anti-windup while a current saturates.
"""

from __future__ import annotations

import cmath
import math

import numpy as np
from numpy.typing import NDArray

from amb_plant_sim import amb as amb_law
from amb_plant_sim.contact import contact_at, race_speed_after
from amb_plant_sim.discretize import SpeedDiscretisation


class StepByStepIntegration:
    """
    The slow path of the simulator: one sample step by step (mixed into ``PlantSimulator``).

    Uses the simulator's ``rig``, its state ``_x`` (plant) and ``_xk`` (PID), which it
    advances, the contact-matrix cache ``_cmats`` and the layout set up in its ``__init__``
    (``_n_force``, ``_inner_channels``, ``_nodes_bearing``, ``_clear_nodes``, ``_clearance``,
    ``_contact_cols``, ``_contact_pos``, ``_contact_vel``, ``_C_in``, ``_C_i``, ``_C_b``,
    ``_i_max``).
    """

    def _contact_matrices(self, d: SpeedDiscretisation) -> tuple[NDArray, NDArray, NDArray]:
        """
        Return the response to contact forces held over one sub-step.

        State (nx, 2k), journal positions (2k, 2k) and velocities (2k, 2k) per unit force at
        the clearance bearings.
        """
        key = id(d)
        hit = self._cmats.get(key)
        if hit is None or hit[0] is not d:
            Gc = d.substep.Gf[:, self._contact_cols]
            hit = (d, Gc, self._contact_pos @ Gc, self._contact_vel @ Gc)
            self._cmats = {key: hit} if len(self._cmats) > 64 else {**self._cmats, key: hit}
        return hit[1], hit[2], hit[3]

    def _slow_sample(
        self,
        d: SpeedDiscretisation,
        inp: dict,
        i_w: NDArray,
        o_in: NDArray,
        n_pid: NDArray,
        theta: float,
    ) -> tuple[NDArray, NDArray]:
        """Integrate one sample step by step (nonlinear forces, saturation, contact)."""
        rig = self.rig
        st, sub, pd = d.step, d.substep, d.pid
        x, xk = self._x.copy(), self._xk.copy()
        W = inp["W0"] * np.exp(1j * theta)
        f_e0 = inp["static"][: self._n_force]
        a_b = inp["static"][self._n_force :]
        centre = inp["centre"]
        stuck_in = {k: v for k, v in inp["stuck"].items() if k in self._inner_channels}
        zero_in = inp["zero"][self._inner_channels]
        cols = np.array([2 * self._nodes_bearing[a // 2] + a % 2 for a in range(4)])
        contact_max = np.zeros(len(self._clear_nodes))
        i_first = None
        m = d.n_contact_sub
        idle = 0.0  # time out of contact not yet run down on the races (applied when needed)
        psi_w = None
        params, nb, clear = rig.contact, len(self._clear_nodes), self._clearance.tolist()
        cen, radius, rolling = centre.tolist(), self._race_radius.tolist(), self._rolling.tolist()
        for j in range(d.n_sub):
            y = self._C_in @ x + o_in + n_pid[4 * j : 4 * j + 4]
            for k, v in stuck_in.items():
                y[self._inner_channels.index(k)] = v
            y[zero_in] = 0.0
            i_raw = pd.C @ xk + pd.D @ y + i_w
            i_ref = np.clip(i_raw, -self._i_max, self._i_max)
            if i_first is None:
                i_first = i_ref.copy()
            xk_new = pd.A @ xk + pd.B @ y
            # anti-windup (conditional integration): a saturated axis keeps its integrator
            # when integrating would push it further into saturation (the current is
            # -K_I x_I / K_i, so x_I growing with the sign of i_raw deepens saturation)
            sat = np.abs(i_raw) > self._i_max
            if np.any(sat):
                grow = np.sign(xk_new[0::2] - xk[0::2]) == -np.sign(i_raw)
                hold = sat & grow
                xk_new[0::2] = np.where(hold, xk[0::2], xk_new[0::2])
            xk = xk_new
            i_act = self._C_i @ x if self._C_i is not None else i_ref
            xb = self._C_b @ x
            f_amb = amb_law.amb_force(rig.amb, i_act, xb, inp["ch_mode"])
            f_corr = f_amb - amb_law.linear_force(rig.amb, i_act, xb)
            f_e = f_e0.copy()
            f_e[cols] += f_corr
            rot = np.exp(1j * d.omega * j * st.h)
            base = st.Gi @ i_ref + st.Gf @ f_e + st.Ga @ a_b
            x_trial = st.Phi @ x + base + (st.Psi @ (W * rot)).real
            pos0 = (self._contact_pos @ x).reshape(-1, 2) - centre
            pos1 = (self._contact_pos @ x_trial).reshape(-1, 2) - centre
            near = np.any(np.hypot(pos0[:, 0], pos0[:, 1]) >= self._clearance) or np.any(
                np.hypot(pos1[:, 0], pos1[:, 1]) >= self._clearance
            )
            if not near:
                x = x_trial
                idle += st.h
                continue
            base_s = sub.Gi @ i_ref + sub.Gf @ f_e + sub.Ga @ a_b
            if psi_w is None:  # Psi (W e^{j theta}) = (Psi W) e^{j theta}: once per sample
                psi_w = sub.Psi @ W
            for q in range(m):
                rot_s = cmath.exp(1j * d.omega * (j * st.h + q * sub.h))
                x_free = sub.Phi @ x + base_s + (psi_w * rot_s).real
                pv = (self._contact_pv @ x_free).tolist()
                if idle:
                    self._race_coast(idle)
                    idle = 0.0
                race = self._race.tolist()
                hits = []
                for b in range(nb):
                    rx, ry = pv[2 * b] - cen[b][0], pv[2 * b + 1] - cen[b][1]
                    hit = contact_at(
                        rx, ry, pv[2 * nb + 2 * b], pv[2 * nb + 2 * b + 1], clear[b],
                        d.omega, params, race[b] * radius[b],
                    )  # fmt: skip
                    if hit is not None:
                        hits.append((b, rx, ry, hit))
                if not hits:
                    x = x_free
                    idle += sub.h
                    continue
                dx, f = self._implicit_contact(d, hits, contact_max)
                x = x_free + dx
                if any(rolling[b] for b, *_ in hits):
                    self._spin_races(hits, f, sub.h)
                else:
                    idle += sub.h
        self._race_coast(idle)
        self._x, self._xk = x, xk
        return i_first, contact_max

    def _active_matrices(self, d: SpeedDiscretisation, act: tuple[int, ...]) -> tuple:
        """
        Return (and cache) the sub-step's response to the forces at the bearings ``act``.

        ``(I, Gp, Gv, Gc)``: identity, journal positions and velocities at ``act`` per unit
        force at ``act`` (2a, 2a), and the state per unit force (nx, 2a).
        """
        key = (id(d), act)
        hit = self._amats.get(key)
        if hit is None or hit[0] is not d:
            Gc, Gp, Gv = self._contact_matrices(d)
            rows = (2 * np.array(act)[:, None] + np.arange(2)[None, :]).ravel()
            sub = np.ix_(rows, rows)
            hit = (d, np.eye(rows.size), Gp[sub], Gv[sub], np.ascontiguousarray(Gc[:, rows]))
            self._amats = {key: hit} if len(self._amats) > 256 else {**self._amats, key: hit}
        return hit[1:]

    def _implicit_contact(
        self, d: SpeedDiscretisation, hits: list, contact_max: NDArray
    ) -> tuple[NDArray, list[float]]:
        """
        Return the state change of the sub-step's linearly implicit contact forces, and them.

        ``hits`` are ``(bearing, r_x, r_y, BearingContact)`` at the free end of the sub-step.
        The force at the end is ``f = F(p_free) + dF/dp (p - p_free) + dF/dv (v - v_free)``
        with ``p = p_free + Gp f`` (one Newton step through the exact response of the
        journals to a held force); a bearing whose force points outwards is dropped (it cannot
        pull). The forces are ``[f_x, f_y]`` per hit, in the order of ``hits`` (N). Updates
        ``contact_max`` (the normal forces at the end, N) in place.
        """
        act = tuple(b for b, *_ in hits)
        eye, Gp, Gv, Gc = self._active_matrices(d, act)
        # block-diagonal Jacobians times the response: block row q is J_q @ G[2q:2q+2, :]
        nq = len(hits)
        dp = np.array([hit.d_position for *_, hit in hits])
        dv = np.array([hit.d_velocity for *_, hit in hits])
        kp_g = np.matmul(dp, Gp.reshape(nq, 2, -1)).reshape(2 * nq, -1)
        kv_g = np.matmul(dv, Gv.reshape(nq, 2, -1)).reshape(2 * nq, -1)
        rhs = [c for *_, hit in hits for c in hit.force]
        jac = eye - kp_g - kv_g
        if len(hits) == 1:  # Cramer's rule: a 2 x 2 solve costs less than LAPACK's call
            (a, b), (c, e) = jac.tolist()
            det = a * e - b * c
            f = [(e * rhs[0] - b * rhs[1]) / det, (a * rhs[1] - c * rhs[0]) / det]
        else:
            f = np.linalg.solve(jac, rhs).tolist()
        for q, (_, rx, ry, _) in enumerate(hits):
            if f[2 * q] * rx + f[2 * q + 1] * ry > 0.0:  # pointing outwards: no pull
                f[2 * q] = f[2 * q + 1] = 0.0
        fa = np.array(f)
        # the normal force at the sub-step's end position (p_free + Gp f)
        end = (Gp @ fa).tolist()
        for q, (b, rx, ry, _) in enumerate(hits):
            ex, ey = rx + end[2 * q], ry + end[2 * q + 1]
            nrm = max(math.hypot(ex, ey), 1e-12)
            f_n = -(f[2 * q] * ex + f[2 * q + 1] * ey) / nrm
            if f_n > contact_max[b]:
                contact_max[b] = f_n
        return Gc @ fa, f

    def _spin_races(self, hits: list, f: list[float], h: float) -> None:
        """
        Advance the rolling auxiliary bearings' races over a sub-step (``contact.race_step``).

        The friction (the tangential part of the implicit forces ``f`` of ``hits``) and the
        rolling speed are taken along the tangent at the sub-step's free position, which the
        journal leaves by at most the sub-step's penetration; a rolling race not touched runs
        down (the same implicit step without friction), the retainers have none.
        """
        params = self.rig.contact
        touched = {b: (q, hit) for q, (b, _, _, hit) in enumerate(hits)}
        race = self._race.tolist()
        for b, rolls in enumerate(self._rolling.tolist()):
            if not rolls:
                race[b] = 0.0
                continue
            r_r = float(self._race_radius[b])
            if b in touched:
                q, hit = touched[b]
                f_t = f[2 * q] * hit.tangent[0] + f[2 * q + 1] * hit.tangent[1]
                roll = hit.surface_speed / r_r
            else:
                f_t, roll = 0.0, 0.0
            race[b] = race_speed_after(race[b], f_t, roll, r_r, h, params)
        self._race = np.array(race)
