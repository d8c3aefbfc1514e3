"""
What a scenario's events put into the samples of :class:`~amb_plant_sim.simulator.PlantSimulator`.

:class:`EventInputs` is mixed into the simulator. For the sample starting at ``t`` it collects,
from the events active then, the held inputs (synchronous forces at angle 0, step forces, base
acceleration, bearing centre offsets of a misalignment) and the fault states (sensor offset,
noise, stuck and zeroed channels, AMB channel modes), caches them while they stay the same,
and says how many samples from ``t`` the inputs stay fixed (the length of a linear chunk).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import NDArray

from amb_common.names import AXIS_NAMES
from amb_plant_sim import amb as amb_law
from amb_plant_sim.errors import SimulationError
from amb_plant_sim.events import Event, base_acceleration, misalignment_offset, sensor_channel


class EventInputs:
    """
    The per-sample inputs and fault states from the events (mixed into ``PlantSimulator``).

    Uses the simulator's ``rig``, ``rotor``, ``scenario`` and ``fs``, its event list
    ``_events``, the stuck values ``_stuck`` and the input cache ``_inp_key``/``_inp`` (emptied
    by ``reset`` and ``inject``), and the layout set up in its ``__init__`` (``_n_force``,
    ``_clear_nodes``, ``_clear_tags``, ``_nodes_bearing``, ``_C_s``, ``_inner_channels``).
    """

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
