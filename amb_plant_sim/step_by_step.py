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

import numpy as np
from numpy.typing import NDArray

from amb_plant_sim import amb as amb_law
from amb_plant_sim.contact import contact_forces, race_step
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
            Gc, Gp, Gv = self._contact_matrices(d)
            for q in range(m):
                rot_s = np.exp(1j * d.omega * (j * st.h + q * sub.h))
                x_free = sub.Phi @ x + base_s + (sub.Psi @ (W * rot_s)).real
                p_free = (self._contact_pos @ x_free).reshape(-1, 2)
                v_free = (self._contact_vel @ x_free).reshape(-1, 2)
                if idle:
                    self._race_coast(idle)
                    idle = 0.0
                u_r = self._race * self._race_radius
                cr = contact_forces(
                    p_free, v_free, centre, self._clearance, d.omega, rig.contact, u_r
                )
                if not np.any(cr.in_contact):
                    x = x_free
                    idle += sub.h
                    continue
                # linearly implicit contact force at the end of the sub-step:
                # f = F(p_free) + dF/dp (p - p_free) + dF/dv (v - v_free), p = p_free + Gp f
                act = np.flatnonzero(cr.in_contact)
                rows = (2 * act[:, None] + np.arange(2)[None, :]).ravel()
                na = rows.size
                kp = np.zeros((na, na))
                kv = np.zeros((na, na))
                for q_, a_ in enumerate(act):
                    kp[2 * q_ : 2 * q_ + 2, 2 * q_ : 2 * q_ + 2] = cr.d_position[a_]
                    kv[2 * q_ : 2 * q_ + 2, 2 * q_ : 2 * q_ + 2] = cr.d_velocity[a_]
                sub_p = Gp[np.ix_(rows, rows)]
                sub_v = Gv[np.ix_(rows, rows)]
                fa = np.linalg.solve(np.eye(na) - kp @ sub_p - kv @ sub_v, cr.force.ravel()[rows])
                fk = np.zeros_like(cr.force)
                fk[act] = fa.reshape(-1, 2)
                # the bearing cannot pull: drop a contact whose force points outwards
                rel = p_free - centre
                pull = np.sum(fk * rel, axis=1) > 0.0
                fk[pull] = 0.0
                x = x_free + Gc @ fk.ravel()
                r_end = (self._contact_pos @ x).reshape(-1, 2) - centre
                nrm = np.hypot(r_end[:, 0], r_end[:, 1])
                f_n = -np.sum(fk * r_end, axis=1) / np.maximum(nrm, 1e-12)
                contact_max = np.maximum(contact_max, f_n)
                if np.any(self._rolling[act]):
                    self._spin_races(cr, fk, sub.h)
                else:
                    idle += sub.h
        self._race_coast(idle)
        self._x, self._xk = x, xk
        return i_first, contact_max

    def _spin_races(self, cr, fk: NDArray, h: float) -> None:
        """
        Advance the rolling auxiliary bearings' races over a sub-step (``contact.race_step``).

        The friction (the tangential part of the implicit force ``fk``) and the rolling speed
        are taken along the tangent at the sub-step's free position (``cr``), which the journal
        leaves by at most the sub-step's penetration.
        """
        f_t = np.where(self._rolling, np.sum(fk * cr.tangent, axis=1), 0.0)
        rolling_speed = cr.surface_speed / self._race_radius
        new = race_step(self._race, f_t, rolling_speed, self._race_radius, h, self.rig.contact)
        self._race = np.where(self._rolling, new, 0.0)
