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

This module holds the simulator's set-up, its public API and the linear (lifted, chunked) path;
what the events put into each sample is in :mod:`amb_plant_sim.event_inputs`, the step-by-step
path in :mod:`amb_plant_sim.step_by_step`.
"""

from __future__ import annotations

import math
from collections import OrderedDict
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray

from amb_common.rig import Rig
from amb_plant_sim import amb as amb_law
from amb_plant_sim.closed_loop import build_plant
from amb_plant_sim.discretize import SpeedDiscretisation, discretise
from amb_plant_sim.errors import SimulationError
from amb_plant_sim.event_inputs import EventInputs
from amb_plant_sim.events import Event, event_from_dict
from amb_plant_sim.pid import pid_state_space
from amb_plant_sim.rotor import build_rotor
from amb_plant_sim.scenario import Scenario
from amb_plant_sim.step_by_step import StepByStepIntegration


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
        Control current per axis [b1x, b1y, b2x, b2y], A, as the current sensors read it (half
        the difference of the two coils' currents): the demand (PID + wavelet, after
        saturation) unless a coil or amplifier channel is lost (:func:`amb.measured_current`).
    bearing_force : ndarray (n, 4)
        Control force ``K_i i`` per axis from the demanded current, N (PID + wavelet, after
        saturation): the force the controller asked for.
    truth : dict of ndarray
        Simulator-only data, never to be published: ``true_displacement`` (n, 8) m,
        ``journal_displacement`` (n, k, 2) m at the clearance bearings,
        ``amb_force`` (n, 4) N (physical AMB force incl. negative stiffness),
        ``contact_force`` (n, k) N (largest normal force in the sample at each clearance
        bearing, order of ``rig.clearance_bearings``), ``contact`` (n, k) bool,
        ``race_speed`` (n, k) rad/s (inner race of a rolling auxiliary bearing at the end of
        the sample; 0 for a retainer),
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


class PlantSimulator(EventInputs, StepByStepIntegration):
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
        # rolling auxiliary bearings: their inner race turns (contact.race_step)
        self._rolling = np.array([c.kind == "auxiliary" for c in clear], dtype=bool) & (
            rig.contact.race_inertia > 0.0
        )
        self._race_radius = rig.contact.rotor_radius + self._clearance
        self._no_contact = np.zeros(len(clear))
        self._max_chunk = 4096
        self._contact_cols = np.array(
            [[2 * nd, 2 * nd + 1] for nd in self._clear_nodes], dtype=int
        ).ravel()
        self._cmats: dict[int, tuple] = {}
        self._clear_tags = [c.tag for c in clear]
        self._contact_pos = z0.position_rows(self._clear_nodes)
        self._contact_vel = z0.velocity_rows(self._clear_nodes)
        self._contact_pv = np.vstack([self._contact_pos, self._contact_vel])
        self._amats: dict[tuple, tuple] = {}
        self._n_force = 2 * self.rotor.n_nodes
        self._inner_channels = rig.feedback_channels
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
        self._race = np.zeros(len(self._clearance))
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

    def pulse_responses(self, n_samples: int) -> list[MeasurementBlock]:
        """
        The loop's responses to 1 N held over sample 0 on each bearing axis in turn.

        Each is ``n_samples`` samples from :meth:`reset` (the Markov parameters of the wavelet
        force's path on a linear rig, with the scenario's events if it has any); the simulator
        is left after the last one.

        Returns
        -------
        list of MeasurementBlock
            One per axis [b1x, b1y, b2x, b2y].
        """
        blocks = []
        for axis in range(4):
            force = np.zeros((int(n_samples), 4))
            force[0, axis] = 1.0
            self.reset()
            blocks.append(self.advance(n_samples, force))
        return blocks

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
            "race_speed": np.zeros((n, k)),
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
            "race_speed": rec["race_speed"],
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
            current=amb_law.measured_current(self.rig.amb, i_pub, ch_mode),
            bearing_force=self.rig.amb.Ki * i_pub,
            truth=truth,
        )

    def samples_before(self, t_end: float) -> int:
        """
        How many samples from the next one have their instants before ``t_end``.

        Parameters
        ----------
        t_end : float
            Simulated time, s.

        Returns
        -------
        int
            ``n`` such that ``advance(n)`` ends with the last sample before ``t_end``: at
            constant speed ``ceil(t_end / period) - sample_index``; on a speed profile the instants
            accumulated as :meth:`advance` does (each sample's period from the quantised speed at
            its instant), without simulating.
        """
        n, t = self._n, self._t
        if not self.scenario.profile_hz:  # instants n * period
            return max(0, math.ceil(t_end / self._period(self._speed_hz(t)) - 1e-9) - n)
        count = 0
        while t < t_end - 1e-12:
            count += 1
            n += 1
            t = t + self._period(self._speed_hz(t))
        return count

    # ------------------------------------------------------------------ internals
    def _speed_hz(self, t: float) -> float:
        return self.scenario.speed_at(t)

    def _speed_key(self, speed_hz: float) -> int:
        """The discretisation cache's key: the speed in quanta (``simulation.speed_quantum``)."""
        return max(1, round(speed_hz / self.rig.simulation.speed_quantum))

    def _period(self, speed_hz: float) -> float:
        """Sample period at ``speed_hz`` as the discretisation has it (quantised speed), s."""
        omega = 2 * math.pi * self._speed_key(speed_hz) * self.rig.simulation.speed_quantum
        return 2 * math.pi / (omega * self.samples_per_rev)

    def _disc(self, speed_hz: float) -> SpeedDiscretisation:
        q = self.rig.simulation.speed_quantum
        key = self._speed_key(speed_hz)
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
                self._race_coast(d.period)
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
        rec["race_speed"][s] = self._race
        rec["step_by_step"][s] = slow
        rec["inp"].append(inp)
        self._n += 1
        self._t = self._next_time(t, d.period)

    def _race_run_down(self, dt: NDArray) -> NDArray:
        """Race speeds (len(dt), k) after running down out of contact for ``dt`` s."""
        c = self.rig.contact
        if c.race_inertia == 0.0:
            return np.zeros((len(dt), len(self._race)))
        return self._race[None, :] * np.exp(-c.race_drag * dt / c.race_inertia)[:, None]

    def _race_coast(self, dt: float) -> None:
        """Let the races of rolling auxiliary bearings run down over ``dt`` s out of contact."""
        if np.any(self._race):
            self._race = self._race_run_down(np.array([dt]))[0]

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
            drawn_from = self._rng.bit_generator.state
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
            rec["race_speed"][sl] = self._race_run_down(d.period * np.arange(1, k_bad + 1))
            rec["step_by_step"][sl] = False
            rec["inp"].extend([inp] * k_bad)
            times = (n0 + np.arange(k_bad)) * d.period
            rec["time"][sl] = times
            self._n = n0 + k_bad
            self._t = self._n * d.period
            self._x = S[k_bad, : self._nx].copy()
            self._xk = S[k_bad, self._nx :].copy()
            self._race_coast(k_bad * d.period)
        if k_bad < L:
            # contact or saturation: shorter chunks until the loop is linear again
            self._chunk_hint = max(2, k_bad)
            if inp["noisy"]:
                # give back the draws of the samples not taken (after k_bad + 1): the noise of
                # each sample must not depend on how the caller splits its advance calls
                self._rng.bit_generator.state = drawn_from
                self._draw_noise(k_bad + 1, d.n_sub, inp["sigma"])
            self._one_sample(s + k_bad, wf[s + k_bad], rec, (n_pid[k_bad], n_pub[k_bad]))
            return k_bad + 1
        self._chunk_hint = min(self._max_chunk, 2 * self._chunk_hint)
        return L
