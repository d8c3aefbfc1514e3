"""
How sinusoidal the change of the probe readings is over the last revolution.

A sudden mass loss adds a synchronous force ``B m e Omega**2 exp(j Omega t) H(t)`` (thesis
3.2.2, eq. 3.3 with a step; a contact is an impulse force, table 3.2): once the free response
of the first half revolution has died down, the change it makes at each probe is close to a
sinusoid at 1 x. A contact's impacts last a fraction of a revolution and recur at most once
per revolution, so the change they make carries the harmonics ``2 x, 3 x, ...`` of running
speed. With synchronous sampling (``spr`` samples per revolution) the DFT of one revolution of
samples has the harmonics as its bins, and the *harmonic ratio* of the change is

    h = sqrt( sum_c sum_{k >= 2} |E_c[k]|**2 / sum_c |E_c[1]|**2 ),

``E_c`` the DFT of channel ``c``'s change over the last revolution before the provisional
decision, summed over the channels in use. The change of sample ``n`` is its reading minus
the healthy reading at the same angle, ``x[n] - x[n - q spr]``, with ``q`` the smallest whole
number of revolutions that takes ``n - q spr`` before the episode's estimated onset (a
reference inside the episode would cancel part of the change it is compared with).

It is a property of the change's shape, not of a wavelet's filters. The monitor uses it for
one decision only: a provisional ``AUX_BEARING_CONTACT`` of the frame rule becomes
``MASS_LOSS`` when ``h <= provisional_harmonics``
(:func:`~amb_fault_monitor.classifier.classify_provisional`), which names the losses the frame
rule misses with long filters (db4) without calling any contact of the suites a loss; alone it
does not separate them (a loss's ratio grows with speed; the measured ratios are in
``docs/fault_monitor_notes.md``, "The change's harmonics").
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.names import N_SENSORS

__all__ = ["RevolutionChange"]


class RevolutionChange:
    """
    The probe readings of the last few revolutions and the harmonic ratio of their change.

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

    def harmonic_ratio(self, onset: int, now: int, mask: np.ndarray) -> float | None:
        """
        ``h`` of the change over samples ``now - spr + 1 .. now`` (module docstring).

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
            after the onset), when the revolution examined starts before ``onset`` or when no
            channel is in use.
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
        power = np.abs(np.fft.rfft(change, axis=0)) ** 2
        fundamental = float(power[1].sum())
        if not fundamental > 0:
            return None
        return math.sqrt(float(power[2:].sum()) / fundamental)
