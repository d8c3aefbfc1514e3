"""
Time simulation of the rig: rotor + AMBs + local PID + faults, sampled speed-synchronously.

Timing contract. Sample ``n`` is taken at ``t_n`` (``n / fs`` at constant speed), at rotor
angle ``theta_n = 2 pi n / samples_per_rev`` (keyphasor at 0). The measurement of sample ``n``
is taken BEFORE the force of sample ``n`` is applied: ``displacement[n]`` is the rotor state at
``t_n``; the wavelet force ``wavelet_force[n]`` is then held (zero-order hold) over
``[t_n, t_{n+1})``. ``current[n]`` and ``bearing_force[n]`` are the values applied from ``t_n``
(PID output at ``t_n`` plus the wavelet current, after saturation).

Internally the plant is integrated exactly (matrix exponential, cached per speed) at
``n_sub`` internal steps per sample (``>= simulation.internal_rate_min``, 5 kHz); the PID runs
discretised (ZOH) at that internal rate. Linear samples use the lifted one-sample map of
:mod:`amb_plant_sim.discretize`; samples with contact, force saturation, the nonlinear AMB
law, a lost AMB channel or a stuck/zeroed PID sensor are integrated step by step, with
``contact.substeps`` sub-steps per internal step while a contact is active; the contact force
of each sub-step is linearly implicit (one Newton step on the force law at the sub-step end,
through the exact response of the journal to a held force), which stays stable for the stiff
Hertzian contact at the short overhung ends. While a current saturates, the PID integrator is
frozen in the direction that deepens saturation (conditional-integration anti-windup; the
thesis does not say what the rig's controller did). Events act from the first sample instant
at or after their onset time.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from amb_common.names import AXIS_NAMES
from amb_common.rig import Rig
from amb_plant_sim import amb as amb_law
from amb_plant_sim.closed_loop import build_plant
from amb_plant_sim.contact import contact_forces
from amb_plant_sim.discretize import SpeedDiscretisation, discretise
from amb_plant_sim.errors import SimulationError
from amb_plant_sim.events import (
    Event,
    base_acceleration,
    event_from_dict,
    misalignment_offset,
    sensor_channel,
)
from amb_plant_sim.pid import pid_state_space
from amb_plant_sim.rotor import build_rotor
from amb_plant_sim.scenario import Scenario


@dataclass
class MeasurementBlock:
    """
    Samples produced by one :meth:`PlantSimulator.advance` call (``n`` samples).

    Attributes
    ----------
    sample_index : ndarray (n,) int64
    time : ndarray (n,)
        Sample instants, s.
    angle : ndarray (n,)
        Rotor angle from the keyphasor, rad in [0, 2 pi).
    omega : ndarray (n,)
        Running speed, rad/s.
    displacement : ndarray (n, 8)
        Sensor readings [x1, y1, ..., x4, y4], m (with sensor faults and noise).
    current : ndarray (n, 4)
        Control current per axis [b1x, b1y, b2x, b2y], A (PID + wavelet, after saturation).
    bearing_force : ndarray (n, 4)
        Control force ``K_i i`` per axis, N (PID + wavelet, after saturation).
    truth : dict of ndarray
        Simulator-only data, never to be published: ``true_displacement`` (n, 8) m,
        ``journal_displacement`` (n, k, 2) m at the clearance bearings,
        ``amb_force`` (n, 4) N (physical AMB force incl. negative stiffness),
        ``contact_force`` (n, k) N (largest normal force in the sample at each clearance
        bearing, order of ``rig.clearance_bearings``), ``contact`` (n, k) bool,
        ``step_by_step`` (n,) bool, ``events_active`` (n, m) bool and ``event_kinds`` (m,).
    """

    sample_index: NDArray[np.int64]
    time: NDArray[np.float64]
    angle: NDArray[np.float64]
    omega: NDArray[np.float64]
    displacement: NDArray[np.float64]
    current: NDArray[np.float64]
    bearing_force: NDArray[np.float64]
    truth: dict[str, NDArray] = field(default_factory=dict)


class PlantSimulator:
    """
    The rig in simulation (ROS-free core of the ``plant_sim`` node).

    Parameters
    ----------
    rig : Rig
        Rig description (``load_rig``).
    scenario : Scenario
        Speed, duration and events (``load_scenario``); roles are resolved here if needed.
    samples_per_rev : int
        Samples per revolution (power of two).
    seed : int
        Seed of the noise generator (runs are repeatable).
    internal_rate_min : float, optional
        Override of ``rig.simulation.internal_rate_min`` (Hz).
    elements : int, optional
        Override of the shaft element count.
    """

    def __init__(
        self,
        rig: Rig,
        scenario: Scenario,
        samples_per_rev: int = 64,
        seed: int = 0,
        internal_rate_min: float | None = None,
        elements: int | None = None,
    ) -> None:
        spr = int(samples_per_rev)
        if spr < 2 or spr & (spr - 1):
            raise SimulationError(
                f"samples_per_rev must be a power of two >= 2, got {samples_per_rev}"
            )
        self.rig = rig
        self.scenario = scenario if scenario.speed_hz is not None else scenario.resolved(rig)
        self.samples_per_rev = spr
        self.seed = int(seed)
        self.internal_rate_min = (
            rig.simulation.internal_rate_min if internal_rate_min is None else internal_rate_min
        )
        self.rotor = build_rotor(rig, elements)
        self._pid_ct = pid_state_space(rig.pid, rig.amb.Ki)
        self._cache: OrderedDict[int, SpeedDiscretisation] = OrderedDict()
        z0 = build_plant(rig, 0.0, rotor=self.rotor)
        self._nx = z0.n_states
        self._nk = self._pid_ct.A.shape[0]
        self._nodes_sensor = z0.sensor_nodes
        self._nodes_bearing = z0.bearing_nodes
        self._C_s = z0.C_s
        self._C_b = z0.C_b
        self._C_i = z0.C_i
        self._C_in = z0.C_in
        clear = rig.clearance_bearings
        self._clear_nodes = [self.rotor.node_at(c.z) for c in clear]
        self._clearance = np.array([c.radial_clearance for c in clear])
        self._clearance2 = self._clearance[None] ** 2
        self._no_contact = np.zeros(len(clear))
        self._max_chunk = 4096
        self._contact_cols = np.array(
            [[2 * nd, 2 * nd + 1] for nd in self._clear_nodes], dtype=int
        ).ravel()
        self._cmats: dict[int, tuple] = {}
        self._clear_tags = [c.tag for c in clear]
        self._contact_pos = z0.position_rows(self._clear_nodes)
        self._contact_vel = z0.velocity_rows(self._clear_nodes)
        self._n_force = 2 * self.rotor.n_nodes
        feed = [rig.bearings[b].sensor_plane - 1 for b in range(2)]
        self._inner_channels = [2 * feed[0], 2 * feed[0] + 1, 2 * feed[1], 2 * feed[1] + 1]
        self._i_max = amb_law.current_limit(rig.amb)
        self.reset()

    # ------------------------------------------------------------------ public API
    @property
    def omega(self) -> float:
        """Running speed at the current sample, rad/s."""
        return 2 * math.pi * self._speed_hz(self._t)

    @property
    def fs(self) -> float:
        """Sample rate at the current running speed, Hz."""
        return self.samples_per_rev * self._speed_hz(self._t)

    @property
    def sample_index(self) -> int:
        """Index of the next sample to be produced."""
        return self._n

    @property
    def time(self) -> float:
        """Simulated time of the next sample, s."""
        return self._t

    def reset(self) -> None:
        """Back to t = 0 with the rotor at rest on its axis; injected events are dropped."""
        self._x = np.zeros(self._nx)
        self._xk = np.zeros(self._nk)
        self._n = 0
        self._t = 0.0
        self._events: list[Event] = list(self.scenario.events)
        self._stuck: dict[int, float] = {}
        self._rng = np.random.default_rng(self.seed)
        self._inp_key = None
        self._inp: dict | None = None
        self._chunk_hint = 64  # samples per linear chunk: a reset run repeats the first exactly

    def inject(self, event: Event | dict) -> Event:
        """
        Add a fault/disturbance event at run time (fault-injection service).

        An onset time in the past means "from the next sample".

        Returns
        -------
        Event
            The validated event.
        """
        ev = event_from_dict(event)
        self._events.append(ev)
        self._inp_key = None
        return ev

    def advance(
        self, n_samples: int, wavelet_force: NDArray[np.float64] | None = None
    ) -> MeasurementBlock:
        """
        Simulate ``n_samples`` samples.

        Parameters
        ----------
        n_samples : int
            Number of samples (>= 1).
        wavelet_force : ndarray (n_samples, 4), optional
            Wavelet control force per axis [b1x, b1y, b2x, b2y], N, held over each sample
            and added in parallel with the PID (as a current ``f / K_i``).

        Returns
        -------
        MeasurementBlock
        """
        n = int(n_samples)
        if n < 1:
            raise SimulationError(f"n_samples must be >= 1, got {n_samples}")
        if wavelet_force is None:
            wf = np.zeros((n, 4))
        else:
            wf = np.asarray(wavelet_force, float)
            if wf.shape != (n, 4):
                raise SimulationError(
                    f"wavelet_force must have shape ({n}, 4) [b1x, b1y, b2x, b2y] N, got {wf.shape}"
                )
            if not np.all(np.isfinite(wf)):
                raise SimulationError("wavelet_force contains NaN or inf")
        k = len(self._clear_nodes)
        ne = len(self._events)
        rec = {
            "x": np.zeros((n, self._nx)),
            "i": np.zeros((n, 4)),
            "time": np.zeros(n),
            "angle": np.zeros(n),
            "omega": np.zeros(n),
            "noise": np.zeros((n, 8)),
            "contact_force": np.zeros((n, k)),
            "step_by_step": np.zeros(n, dtype=bool),
            "inp": [],
        }
        first = self._n
        s = 0
        while s < n:
            s += self._advance_some(s, n - s, wf, rec)
        X = rec["x"]
        true_y = X @ self._C_s.T
        xb = X @ self._C_b.T
        i_pub = X @ self._C_i.T if self._C_i is not None else rec["i"]
        y = true_y + rec["noise"]
        ch_mode = np.zeros((n, 4), dtype=int)
        active = np.zeros((n, ne), dtype=bool)
        for s, inp in enumerate(rec["inp"]):
            if inp["faulty"]:
                y[s] += inp["offset"]
                for ch, v in inp["stuck"].items():
                    y[s, ch] = v
                y[s, inp["zero"]] = 0.0
                ch_mode[s] = inp["ch_mode"]
            active[s] = inp["active"][:ne]
        truth = {
            "true_displacement": true_y,
            "journal_displacement": (X @ self._contact_pos.T).reshape(n, -1, 2),
            "amb_force": amb_law.amb_force(self.rig.amb, i_pub, xb, ch_mode),
            "contact_force": rec["contact_force"],
            "contact": rec["contact_force"] > 0,
            "step_by_step": rec["step_by_step"],
            "events_active": active,
            "event_kinds": np.array([e.kind for e in self._events[:ne]]),
        }
        return MeasurementBlock(
            sample_index=np.arange(first, first + n, dtype=np.int64),
            time=rec["time"],
            angle=rec["angle"],
            omega=rec["omega"],
            displacement=y,
            current=i_pub,
            bearing_force=self.rig.amb.Ki * i_pub,
            truth=truth,
        )

    # ------------------------------------------------------------------ internals
    def _speed_hz(self, t: float) -> float:
        return self.scenario.speed_at(t)

    def _disc(self, speed_hz: float) -> SpeedDiscretisation:
        q = self.rig.simulation.speed_quantum
        key = max(1, round(speed_hz / q))
        d = self._cache.get(key)
        if d is None:
            omega = 2 * math.pi * key * q
            plant = build_plant(self.rig, omega, rotor=self.rotor)
            d = discretise(
                plant,
                self._pid_ct,
                self.samples_per_rev,
                self.internal_rate_min,
                self._contact_pos,
                self.rig.contact.substeps,
                lifted=not self.scenario.profile_hz,
            )
            self._cache[key] = d
            while len(self._cache) > self.rig.simulation.cache_size:
                self._cache.popitem(last=False)
        else:
            self._cache.move_to_end(key)
        return d

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

    def _node_of(self, ev: Event) -> int:
        if "disk" in ev.params:
            tags = {b.tag: b for b in self.rig.rigid_bodies}
            if ev.get("disk") not in tags:
                raise SimulationError(
                    f"event {ev.kind}: unknown disk {ev.get('disk')!r}; expected one of "
                    f"{sorted(tags)}"
                )
            return self.rotor.node_at(tags[ev.get("disk")].z)
        if "bearing" in ev.params and ev.kind in ("step_force", "sync_force"):
            return self._nodes_bearing[int(ev.get("bearing")) - 1]
        return int(np.argmin(np.abs(self.rotor.z - float(ev.get("z")))))

    def _sample_inputs(self, t: float, omega: float, x0: NDArray) -> dict:
        """
        Held inputs and fault states of the sample starting at ``t``.

        Synchronous forces are returned for angle 0 (``W0``; the sample's ``W`` is
        ``W0 e^{j theta}``). The result is cached while the set of active events and the speed
        stay the same (misalignment offsets included) and no base motion is active.
        """
        flags = tuple(
            misalignment_offset(ev, t) if ev.kind == "misalignment" else ev.active(t)
            for ev in self._events
        )
        key = (flags, omega)
        if self._inp_key == key and self._inp is not None:
            return self._inp
        inp = self._collect_inputs(t, omega, x0)
        varying = any(
            f is True and ev.kind == "base_motion"
            for f, ev in zip(flags, self._events, strict=True)
        )
        self._inp_key = None if varying else key
        self._inp = inp
        return inp

    def _collect_inputs(self, t: float, omega: float, x0: NDArray) -> dict:
        nf = self._n_force
        W = np.zeros(nf, dtype=complex)
        f_e = np.zeros(nf)
        a_b = np.zeros(2)
        centre = np.zeros((len(self._clear_nodes), 2))
        ch_mode = np.zeros(4, dtype=int)
        offset = np.zeros(8)
        extra_sigma = np.zeros(8)
        stuck: dict[int, float] = {}
        zero = np.zeros(8, dtype=bool)
        active = np.zeros(len(self._events), dtype=bool)
        for idx, ev in enumerate(self._events):
            if ev.kind == "misalignment":
                if t >= ev.time:
                    ci = self._clear_tags.index(ev.get("bearing"))
                    centre[ci] += misalignment_offset(ev, t)
                    active[idx] = any(centre[ci] != 0.0)
                continue
            if not ev.active(t):
                continue
            active[idx] = True
            if ev.kind in ("unbalance", "mass_loss", "sync_force"):
                node = self._node_of(ev)
                amp = ev.get("me") * omega**2 if ev.kind != "sync_force" else ev.get("amplitude")
                c = amp * np.exp(1j * ev.get("angle"))
                W[2 * node] += c
                W[2 * node + 1] += -1j * c
            elif ev.kind == "step_force":
                node = self._node_of(ev)
                f_e[2 * node] += ev.get("fx")
                f_e[2 * node + 1] += ev.get("fy")
            elif ev.kind == "base_motion":
                a_b[0 if ev.get("direction") == "x" else 1] += base_acceleration(ev, t)
            elif ev.kind == "sensor_fault":
                ch = sensor_channel(ev.get("plane"), ev.get("axis"))
                mode = ev.get("mode")
                if mode == "offset":
                    offset[ch] += ev.get("value")
                elif mode == "noise":
                    extra_sigma[ch] = math.hypot(extra_sigma[ch], ev.get("value"))
                elif mode == "zero":
                    zero[ch] = True
                else:  # stuck at the value read at onset
                    if idx not in self._stuck:
                        self._stuck[idx] = float(self._C_s[ch] @ x0 + offset[ch])
                    stuck[ch] = self._stuck[idx]
            elif ev.kind == "amb_channel_loss":
                ch_mode[AXIS_NAMES.index(ev.get("axis"))] = amb_law.CHANNEL_MODES[ev.get("coils")]
        lay_static = np.concatenate([f_e, a_b])
        sigma = np.hypot(self.scenario.measurement_noise, extra_sigma)
        inner_override = any(c in self._inner_channels for c in stuck) or bool(
            np.any(zero[self._inner_channels])
        )
        return {
            "o_in": offset[self._inner_channels],
            "noisy": bool(np.any(sigma > 0)),
            "nonlinear": bool(
                self.rig.amb.law != "linear" or np.any(ch_mode != 0) or inner_override
            ),
            "faulty": bool(np.any(offset != 0) or stuck or np.any(zero) or np.any(ch_mode)),
            "W0": W,
            "static": lay_static,
            "f_e": f_e,
            "a_b": a_b,
            "centre": centre,
            "ch_mode": ch_mode,
            "offset": offset,
            "sigma": sigma,
            "stuck": stuck,
            "zero": zero,
            "active": active,
        }

    def _one_sample(
        self, s: int, wforce: NDArray, rec: dict, noise: tuple[NDArray, NDArray] | None = None
    ) -> None:
        t = self._t
        speed = self._speed_hz(t)
        if not speed > 0:
            raise SimulationError(f"running speed must stay > 0 Hz, got {speed} at t = {t} s")
        d = self._disc(speed)
        omega = d.omega
        theta = 2 * math.pi * (self._n % self.samples_per_rev) / self.samples_per_rev
        x0 = self._x
        inp = self._sample_inputs(t, omega, x0)
        W = inp["W0"] * np.exp(1j * theta)
        if noise is not None:
            n_pid, n_pub = noise
            rec["noise"][s] = n_pub
        elif inp["noisy"]:
            n_pid, n_pub = self._draw_noise(1, d.n_sub, inp["sigma"])
            n_pid, n_pub = n_pid[0], n_pub[0]
            rec["noise"][s] = n_pub
        else:
            n_pid = np.zeros(4 * d.n_sub)
        i_w = wforce / self.rig.amb.Ki
        o_in = inp["o_in"]
        slow = inp["nonlinear"] or d.L is None
        contact_max = self._no_contact
        if not slow:
            v = np.concatenate([x0, self._xk, i_w, inp["static"], o_in, W.real, W.imag, n_pid])
            res = d.L @ v
            ns = self._nx + self._nk
            mon = res[ns:]
            cur = mon[d.cur_idx]
            pos = mon[d.pos_idx] - inp["centre"]
            gap_ok = np.all(pos[..., 0] ** 2 + pos[..., 1] ** 2 < self._clearance2)
            sat_ok = np.all(np.abs(cur) <= self._i_max)
            if gap_ok and sat_ok:
                i0 = cur[0]
                self._x = res[: self._nx]
                self._xk = res[self._nx : ns]
            else:
                slow = True
        if slow:
            i0, contact_max = self._slow_sample(d, inp, i_w, o_in, n_pid, theta)
        rec["x"][s] = x0
        rec["i"][s] = i0
        rec["time"][s] = t
        rec["angle"][s] = theta
        rec["omega"][s] = omega
        rec["contact_force"][s] = contact_max
        rec["step_by_step"][s] = slow
        rec["inp"].append(inp)
        self._n += 1
        self._t = self._next_time(t, d.period)

    def _next_time(self, t: float, period: float) -> float:
        """Time of the next sample: ``n / fs`` at constant speed, accumulated on a profile."""
        if self.scenario.profile_hz:
            return t + period
        return self._n * period

    def _draw_noise(self, count: int, n_sub: int, sigma: NDArray) -> tuple[NDArray, NDArray]:
        """
        Noise of ``count`` samples: PID input noise (count, 4 n_sub) and published (count, 8).

        One draw of ``4 n_sub + 8`` normals per sample, in sample order, so that chunked and
        sample-by-sample runs consume the generator identically. The PID sees, at each internal
        step, independent noise of the inner channels' standard deviation; the published inner
        channels carry the noise of the first internal step (what the PID saw at ``t_n``).
        """
        z = self._rng.standard_normal((count, 4 * n_sub + 8))
        n_pid = z[:, : 4 * n_sub] * np.tile(sigma[self._inner_channels], n_sub)
        n_pub = z[:, 4 * n_sub :] * sigma
        n_pub[:, self._inner_channels] = n_pid[:, :4]
        return n_pid, n_pub

    def _chunk_limit(self, t: float) -> int | None:
        """
        How many samples from ``t`` can run as one linear chunk (events fixed), or ``None``.

        ``None`` when a speed profile, an active base motion or a misalignment ramp makes the
        inputs vary from sample to sample.
        """
        if self.scenario.profile_hz:
            return None
        boundary = math.inf
        for ev in self._events:
            if ev.kind == "base_motion" and ev.active(t):
                return None
            times = [ev.time]
            if ev.duration is not None:
                times.append(ev.time + ev.duration)
            if ev.kind == "misalignment":
                r, h, q = ev.get("ramp"), ev.get("hold"), ev.get("return_time")
                seg = [(ev.time, ev.time + r)]
                if q > 0:
                    seg.append((ev.time + r + h, ev.time + r + h + q))
                for a, b in seg:
                    if a - 1e-12 <= t < b - 1e-12:
                        return None
                    times += [a, b]
            for tb in times:
                if tb - 1e-12 > t:
                    boundary = min(boundary, tb)
        if boundary == math.inf:
            return 1 << 30
        period = 1.0 / self.fs
        return max(1, math.ceil((boundary - 1e-12 - t) / period - 1e-9))

    def _advance_some(self, s: int, remaining: int, wf: NDArray, rec: dict) -> int:
        """Advance one chunk (linear, fixed events) or one sample; returns samples done."""
        t = self._t
        limit = self._chunk_limit(t)
        if limit is None or remaining == 1:
            self._one_sample(s, wf[s], rec)
            return 1
        d = self._disc(self._speed_hz(t))
        x0 = self._x
        inp = self._sample_inputs(t, d.omega, x0)
        if inp["nonlinear"]:
            self._one_sample(s, wf[s], rec)
            return 1
        L = int(min(remaining, limit, self._chunk_hint))
        lay = d.layout
        spr = self.samples_per_rev
        n0 = self._n
        theta = 2 * math.pi * ((n0 + np.arange(L)) % spr) / spr
        W = inp["W0"][None, :] * np.exp(1j * theta)[:, None]
        if inp["noisy"]:
            n_pid, n_pub = self._draw_noise(L, d.n_sub, inp["sigma"])
        else:
            n_pid, n_pub = np.zeros((L, 4 * d.n_sub)), np.zeros((L, 8))
        U = np.empty((L, lay.size))
        U[:, lay.i_w] = wf[s : s + L] / self.rig.amb.Ki
        U[:, lay.f_e.start : lay.a_b.stop] = inp["static"]
        U[:, lay.o] = inp["o_in"]
        U[:, lay.w_re] = W.real
        U[:, lay.w_im] = W.imag
        U[:, lay.noise] = n_pid
        cols = np.flatnonzero(np.any(U != 0.0, axis=0))  # most inputs are zero: skip them
        Uc = U[:, cols]
        GU = Uc @ d.G[:, cols].T
        ns = self._nx + self._nk
        S = np.empty((L + 1, ns))
        S[0, : self._nx] = x0
        S[0, self._nx :] = self._xk
        F = d.F
        for k in range(L):
            S[k + 1] = F @ S[k] + GU[k]
        mon = S[:L] @ d.Ms.T + Uc @ d.Mu[:, cols].T
        cur = mon[:, d.cur_idx]  # (L, n_sub, 4)
        pos = mon[:, d.pos_idx] - inp["centre"]  # (L, n_sub + 1, k, 2)
        bad = np.any(np.abs(cur) > self._i_max, axis=(1, 2)) | np.any(
            pos[..., 0] ** 2 + pos[..., 1] ** 2 >= self._clearance2, axis=(1, 2)
        )
        k_bad = int(np.argmax(bad)) if np.any(bad) else L
        if k_bad > 0:
            sl = slice(s, s + k_bad)
            rec["x"][sl] = S[:k_bad, : self._nx]
            rec["i"][sl] = cur[:k_bad, 0, :]
            rec["angle"][sl] = theta[:k_bad]
            rec["omega"][sl] = d.omega
            rec["noise"][sl] = n_pub[:k_bad]
            rec["contact_force"][sl] = 0.0
            rec["step_by_step"][sl] = False
            rec["inp"].extend([inp] * k_bad)
            times = (n0 + np.arange(k_bad)) * d.period
            rec["time"][sl] = times
            self._n = n0 + k_bad
            self._t = self._n * d.period
            self._x = S[k_bad, : self._nx].copy()
            self._xk = S[k_bad, self._nx :].copy()
        if k_bad < L:
            # contact or saturation: shorter chunks until the loop is linear again
            self._chunk_hint = max(2, k_bad)
            self._one_sample(s + k_bad, wf[s + k_bad], rec, (n_pid[k_bad], n_pub[k_bad]))
            return k_bad + 1
        self._chunk_hint = min(self._max_chunk, 2 * self._chunk_hint)
        return L

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
                continue
            base_s = sub.Gi @ i_ref + sub.Gf @ f_e + sub.Ga @ a_b
            Gc, Gp, Gv = self._contact_matrices(d)
            for q in range(m):
                rot_s = np.exp(1j * d.omega * (j * st.h + q * sub.h))
                x_free = sub.Phi @ x + base_s + (sub.Psi @ (W * rot_s)).real
                p_free = (self._contact_pos @ x_free).reshape(-1, 2)
                v_free = (self._contact_vel @ x_free).reshape(-1, 2)
                cr = contact_forces(p_free, v_free, centre, self._clearance, d.omega, rig.contact)
                if not np.any(cr.in_contact):
                    x = x_free
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
        self._x, self._xk = x, xk
        return i_first, contact_max
