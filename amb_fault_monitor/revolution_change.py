"""
What a sinusoid at 1 x and a straight line leave of the probe readings' last revolution of change.

A sudden mass loss adds a synchronous force ``B m e Omega**2 exp(j Omega t) H(t)`` (thesis
3.2.2, eq. 3.3 with a step); a contact is an impulse force (table 3.2). Half a revolution
after a loss, the change it has made at a probe is the forced response, a sinusoid at 1 x,
plus the free response of the rotor's modes, which within one revolution is a slow drift for
the modes below running speed. A contact's impacts last a fraction of a revolution: they
leave a change that neither a sinusoid at 1 x nor a straight line describes. Per channel
``c`` in use, the change of the last revolution before the provisional decision, ``d_c`` (one
sample per ``2 pi / spr`` of rotor angle, synchronous sampling), is fitted by least squares
with

    d_c[j] ~ a_c cos(theta_j) + b_c sin(theta_j) + p_c + q_c (j - (spr - 1) / 2) / spr,
    theta_j = 2 pi j / spr,  j = 0 .. spr - 1,

and the *residual ratio* is

    rho = sqrt( sum_c |d_c - fit_c|**2 / sum_c |a_c cos + b_c sin|**2 ),

what the fit leaves over its 1 x part, summed over the channels. The change of sample ``n`` is
its reading minus the healthy reading at the same angle, ``x[n] - x[n - k spr]``, ``k`` the
smallest whole number of revolutions that takes ``n - k spr`` before the episode's estimated
onset (a reference inside the episode would cancel part of the change it is compared with).

It is a property of the change's shape, the same for every wavelet but for the onset estimate
the window hangs on; the monitor's provisional class of a change in both frames is
``MASS_LOSS`` for ``rho <= provisional_residual``, else ``AUX_BEARING_CONTACT``
(:func:`~amb_fault_monitor.classifier.classify_provisional`; the measured ratios and what was
tried before are in ``docs/fault_monitor_notes.md``, "The change's shape").
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.names import N_SENSORS

__all__ = ["RevolutionChange"]


class RevolutionChange:
    """
    The probe readings of the last few revolutions and the residual ratio of their change.

    Parameters
    ----------
    config : MonitorConfig
        Or anything with its ``samples_per_rev`` and ``provisional_revs`` (how far after an
        onset the ratio is asked for): that long, one revolution of healthy reference before
        it and one more of margin are kept. Setting another config that needs other sizes
        forgets the readings.
    """

    def __init__(self, config) -> None:
        self._size = 0
        self.config = config

    @property
    def config(self):
        """The parameters (``samples_per_rev``, ``provisional_revs``)."""
        return self._config

    @config.setter
    def config(self, config) -> None:
        self._config = config
        self.samples_per_rev = int(config.samples_per_rev)
        size = self.samples_per_rev * (math.ceil(config.provisional_revs) + 3)
        j = np.arange(self.samples_per_rev)
        theta = 2 * np.pi * j / self.samples_per_rev
        ramp = (j - (self.samples_per_rev - 1) / 2) / self.samples_per_rev
        self._basis = np.column_stack([np.cos(theta), np.sin(theta), np.ones_like(theta), ramp])
        self._solve = np.linalg.pinv(self._basis)  # least squares, computed once
        if size != self._size:
            self._size = size
            self._x = np.zeros((size, N_SENSORS))
            self._n = np.full(size, -1, dtype=np.int64)

    def reset(self) -> None:
        """Forget the readings (a restart of the stream)."""
        self._n[:] = -1

    def add(self, n: int, displacement: np.ndarray) -> None:
        """Keep sample ``n``'s probe readings (8,), m, ``[x1, y1, ..., x4, y4]``."""
        slot = n % self._size
        self._x[slot] = displacement
        self._n[slot] = n

    def residual_ratio(self, onset: int, now: int, mask: np.ndarray) -> float | None:
        """
        ``rho`` of the change over samples ``now - spr + 1 .. now`` (module docstring).

        Parameters
        ----------
        onset : int
            The episode's estimated onset sample: the reference readings lie before it.
        now : int
            The last sample of the revolution examined.
        mask : numpy.ndarray
            Channels in use (8,), bool.

        Returns
        -------
        float or None
            None when a reading the ratio needs is not kept (a gap in the stream, too long
            after the onset), when the revolution examined starts before ``onset``, when no
            channel is in use or when the change has no 1 x part.
        """
        spr = self.samples_per_rev
        n = np.arange(now - spr + 1, now + 1)
        if n[0] < onset:
            return None
        ref = n - ((n - onset) // spr + 1) * spr
        wanted = np.concatenate([n, ref])
        slots = wanted % self._size
        if not np.array_equal(self._n[slots], wanted):
            return None
        change = self._x[slots[:spr]][:, mask] - self._x[slots[spr:]][:, mask]
        coef = self._solve @ change  # (4, channels): a, b, p, q
        synchronous = self._basis[:, :2] @ coef[:2]
        residual = change - self._basis @ coef
        fundamental = float(np.sum(synchronous**2))
        if not fundamental > 0:
            return None
        return math.sqrt(float(np.sum(residual**2)) / fundamental)
