"""
Trip levels with hysteresis per sensor plane: radial displacement and 1 x (synchronous) amplitude.

A plane trips when its quantity exceeds its ``level`` and clears when it falls below
``level * (1 - hysteresis)``. Two quantities, as vibration protection equipment reports:

- displacement: the instantaneous radial displacement ``hypot(x, y)`` of the plane, m;
- 1 x amplitude: the semi-major axis of the synchronous orbit over the last revolution,
  ``a = (|X + iY| + |X - iY|) / 2`` with ``X = (2 / N) sum x_n exp(-i theta_n)`` (and ``Y``
  likewise) the one-revolution DFT at the running speed of the ``N = samples_per_rev`` latest
  samples, ``theta_n`` the rotor angle from the keyphasor. ``|X + iY| / 2`` and ``|X - iY| / 2``
  are the forward and backward whirl radii, so ``a`` is the largest 1 x excursion whatever
  the orbit's shape (a circle of radius A and a line of half-length A both give ``a = A``).

Default levels come from the clearances in ``config/rig.yaml`` (:func:`clearance_levels`): each
sensor plane takes the radial clearance of the clearance bearing nearest it along the shaft,
times a fraction (one source for the rig's numbers).
"""

from __future__ import annotations

import cmath
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from amb_common.faults import FaultEvent, FaultType
from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["PlaneTrips", "SynchronousAmplitude", "TripMonitor", "clearance_levels"]


def clearance_levels(rig: Any, fraction: float) -> np.ndarray:
    """
    Trip level per sensor plane: ``fraction`` of the nearest clearance bearing's clearance.

    Parameters
    ----------
    rig : amb_common.rig.Rig
        Uses ``plane_clearance_bearings`` and ``clearance_bearings[].radial_clearance`` (m).
    fraction : float
        Share of the radial clearance, in (0, 1].

    Returns
    -------
    numpy.ndarray
        (4,) levels, m, planes 1..4 in the order of ``rig.sensor_planes``.

    Raises
    ------
    FaultMonitorError
        If ``fraction`` is outside (0, 1] or the rig has no clearance bearing.
    """
    if not 0 < fraction <= 1:
        raise FaultMonitorError(f"clearance fraction must be in (0, 1], got {fraction}")
    clear = rig.clearance_bearings
    if not clear:
        raise FaultMonitorError(
            "the rig file has no clearance_bearings; set the trip levels explicitly"
        )
    rc = np.array([c.radial_clearance for c in clear])
    return fraction * rc[np.array(rig.plane_clearance_bearings) - 1]


#: No plane (what :meth:`TripMonitor.update` returns when nothing trips or clears).
_NONE = np.flatnonzero(np.zeros(4, dtype=bool))
_NONE.flags.writeable = False


def _levels(level: float | ArrayLike) -> np.ndarray:
    lv = np.broadcast_to(np.asarray(level, dtype=float), (4,)).copy()
    if np.any(~np.isfinite(lv)) or np.any(lv < 0):
        raise FaultMonitorError(f"trip levels must be finite and >= 0 m (0 = off), got {lv}")
    return lv


def _hysteresis(hysteresis: float) -> float:
    if not 0 <= hysteresis < 1:
        raise FaultMonitorError(f"hysteresis must be in [0, 1), got {hysteresis}")
    return float(hysteresis)


class TripMonitor:
    """
    Trip per plane with hysteresis on any non-negative per-plane quantity.

    Parameters
    ----------
    level : float or array_like
        m, trip level, scalar or one per plane (4,); 0 disables a plane.
    hysteresis : float
        Fraction in [0, 1) below ``level`` at which a trip clears.
    """

    def __init__(self, level: float | ArrayLike, hysteresis: float = 0.1) -> None:
        self.hysteresis = _hysteresis(hysteresis)
        self.level = _levels(level)
        self.tripped = np.zeros(4, dtype=bool)
        self._tripped_any = False
        self.peak = np.zeros(4)
        self.value = np.zeros(4)

    def set_level(self, level: float | ArrayLike) -> None:
        """Change the trip levels (m); validated as in the constructor."""
        self.level = _levels(level)

    def reset(self) -> None:
        """Clear trips and peaks."""
        self.tripped[:] = False
        self._tripped_any = False
        self.peak[:] = 0.0
        self.value[:] = 0.0

    def update(self, value: ArrayLike) -> tuple[np.ndarray, np.ndarray]:
        """
        Update with the per-plane quantity ``(4,)`` m.

        Returns
        -------
        tripped_now, cleared_now : numpy.ndarray
            0-based planes that tripped / cleared at this update.
        """
        r = np.asarray(value, dtype=float)
        self.value = r
        np.maximum(self.peak, r, out=self.peak)
        over = r > self.level
        # the usual sample: nothing can change (count_nonzero: a third of ndarray.any's cost)
        if not (self._tripped_any or np.count_nonzero(over)):
            return _NONE, _NONE
        on = self.level > 0
        new = over & ~self.tripped & on
        clear = self.tripped & ((r < self.level * (1.0 - self.hysteresis)) | ~on)
        self.tripped = (self.tripped | new) & ~clear
        self._tripped_any = bool(np.count_nonzero(self.tripped))
        return np.flatnonzero(new), np.flatnonzero(clear)

    def step(self, displacement: ArrayLike) -> np.ndarray:
        """Update with one displacement sample ``(8,)`` m; return the planes that tripped now."""
        d = np.asarray(displacement, dtype=float)
        return self.update(np.hypot(d[0::2], d[1::2]))[0]


class SynchronousAmplitude:
    """
    1 x orbit semi-major axis per plane over the last revolution (module docstring).

    Parameters
    ----------
    samples_per_rev : int
        ``N``, samples per revolution (the DFT window).

    Notes
    -----
    A running sum over a ring buffer of ``x_n exp(-i theta_n)``; O(8) per sample, the sum is
    recomputed from the buffer once per revolution so round-off does not accumulate.
    :attr:`ready` is False until a full revolution is in the window. The eight channels are
    Python complex numbers, not a numpy array: at this size each numpy call costs more than the
    arithmetic (about 1 us each; the node calls this at the sample rate, 2144 times a second at
    67 Hz x 32).
    """

    def __init__(self, samples_per_rev: int) -> None:
        spr = int(samples_per_rev)
        if spr < 4:
            raise FaultMonitorError(f"samples_per_rev must be >= 4, got {samples_per_rev}")
        self.samples_per_rev = spr
        self.reset()

    def reset(self) -> None:
        """Empty the window."""
        self._buf = [[0j] * 8 for _ in range(self.samples_per_rev)]
        self._sum = [0j] * 8
        self._pos = 0
        self._count = 0

    @property
    def ready(self) -> bool:
        """True once a whole revolution is in the window."""
        return self._count >= self.samples_per_rev

    def step(self, displacement: ArrayLike, angle: float) -> np.ndarray:
        """
        Add one sample; return the 1 x semi-major axis per plane (4,), m (zeros until ready).

        Parameters
        ----------
        displacement : array_like
            (8,) m, ``[x1, y1, ..., x4, y4]``.
        angle : float
            Rotor angle from the keyphasor, rad.
        """
        d = np.asarray(displacement, dtype=float)
        if d.shape != (8,):
            raise FaultMonitorError(f"displacement must have shape (8,), got {d.shape}")
        rot = cmath.exp(-1j * float(angle))
        v = [x * rot for x in d.tolist()]
        old = self._buf[self._pos]
        self._sum = [s + (a - b) for s, a, b in zip(self._sum, v, old, strict=True)]
        self._buf[self._pos] = v
        self._pos = (self._pos + 1) % self.samples_per_rev
        self._count += 1
        if self._pos == 0:
            self._sum = [sum(column) for column in zip(*self._buf, strict=True)]
        if not self.ready:
            return np.zeros(4)
        k = 2.0 / self.samples_per_rev
        ph = [k * s for s in self._sum]
        return np.array(
            [
                0.5 * (abs(x + 1j * y) + abs(x - 1j * y))
                for x, y in zip(ph[0::2], ph[1::2], strict=True)
            ]
        )


class PlaneTrips:
    """
    Both trips of the four sensor planes, fed sample by sample: the TRIP events they raise.

    The displacement trip sees every sample; the 1 x amplitude trip only once a whole
    revolution is in its window (:class:`SynchronousAmplitude`), so that a window still filling
    never trips. An event is raised when a plane trips, not while it stays tripped.

    Parameters
    ----------
    displacement_level : float or array_like
        m, trip level of the radial displacement, scalar or per plane (4,); 0 disables a plane.
    amplitude_level : float or array_like
        m, trip level of the 1 x amplitude, likewise.
    hysteresis : float
        Fraction in [0, 1) below a level at which a trip clears (both trips).
    samples_per_rev : int
        Samples per revolution (the 1 x window).

    Attributes
    ----------
    displacement, amplitude : TripMonitor
        The two trips (levels, state and peaks, for the node's status).
    window : SynchronousAmplitude
        The 1 x window; :meth:`SynchronousAmplitude.reset` it at a discontinuity of the stream.
    """

    def __init__(
        self,
        displacement_level: float | ArrayLike,
        amplitude_level: float | ArrayLike,
        hysteresis: float,
        samples_per_rev: int,
    ) -> None:
        self.displacement = TripMonitor(displacement_level, hysteresis)
        self.amplitude = TripMonitor(amplitude_level, hysteresis)
        self.window = SynchronousAmplitude(samples_per_rev)

    def set_hysteresis(self, hysteresis: float) -> None:
        """Change both trips' hysteresis (a fraction in [0, 1))."""
        self.displacement.hysteresis = self.amplitude.hysteresis = _hysteresis(hysteresis)

    def step(
        self, sample_index: int, displacement: ArrayLike, angle: float, omega: float
    ) -> list[FaultEvent]:
        """
        Add one sample; return the TRIP events of the planes that tripped at it.

        Parameters
        ----------
        sample_index : int
            The sample's index (the event's onset, detection and decision).
        displacement : array_like
            (8,) m, ``[x1, y1, ..., x4, y4]``.
        angle : float
            rad, rotor angle from the keyphasor.
        omega : float
            rad/s, running speed (carried by the event).
        """
        amp = self.window.step(displacement, angle)
        found = [
            ("displacement", p, self.displacement) for p in self.displacement.step(displacement)
        ]
        if self.window.ready:
            found += [("1x", p, self.amplitude) for p in self.amplitude.update(amp)[0]]
        n, spr = int(sample_index), self.window.samples_per_rev
        events = []
        for kind, plane, trip in found:
            r = float(trip.value[plane])
            level = float(trip.level[plane])
            what = "displacement" if kind == "displacement" else "1 x amplitude"
            events.append(
                FaultEvent(
                    FaultType.TRIP, n, n, n, spr, omega,
                    plane=int(plane) + 1,
                    severity=r,
                    confidence=1.0,
                    evidence={"quantity": kind, "trip_level_m": level, "value_m": r},
                    description=(
                        f"plane {plane + 1} {what} {r:.3g} m over the trip level {level:.3g} m"
                    ),
                )
            )  # fmt: skip
        return events
