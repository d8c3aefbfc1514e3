"""
Thresholds calibrated automatically from a healthy window (robust statistics).

Every detection feature (a non-negative magnitude, one per level, frame and sensor plane) is
collected over the calibration window and its threshold set to

.. math::

    \\theta = \\max\\left(\\operatorname{median}(c) + k \\cdot 1.4826
    \\operatorname{MAD}(c),\\; \\theta_{\\min}\\right),

where MAD is the median absolute deviation from the median and ``1.4826`` makes
``1.4826 MAD`` equal to the standard deviation for Gaussian data. Median and MAD ignore up to
half the window being outliers, so a short disturbance inside the calibration window does not
inflate the threshold the way a mean and standard deviation would.

Choice of ``k`` (documented, not tuned per scenario): the plane features are magnitudes of two
(nearly) Gaussian components, i.e. Rayleigh distributed with scale ``s``; then
``median = 1.177 s`` and ``1.4826 MAD = 0.664 s``, so ``k = 8`` puts the threshold at
``6.5 s``, exceeded with probability ``exp(-6.5**2 / 2) = 7e-10`` per coefficient: below one
false crossing in 10 simulated minutes at 67 Hz with 32 samples/rev, 6 levels, 2 frames and
4 planes (``about 1e8`` tests). Crossings must further be confirmed (see
:mod:`amb_fault_monitor.monitor`). The floor ``theta_min`` (m) covers noise-free
signals, where MAD is 0 and any round-off would otherwise cross.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from amb_fault_monitor.errors import FaultMonitorError

__all__ = ["MAD_TO_SIGMA", "robust_threshold"]

MAD_TO_SIGMA = 1.4826


def robust_threshold(samples: ArrayLike, k: float, floor: float, axis: int = 0) -> np.ndarray:
    """
    Threshold ``max(median + k * 1.4826 * MAD, floor)`` along ``axis``.

    Parameters
    ----------
    samples : array_like
        Healthy values of the feature(s), e.g. shape ``(N, 4)`` for 4 planes (m).
    k : float
        Number of robust standard deviations above the median (> 0).
    floor : float
        Smallest threshold (same unit as ``samples``, >= 0).
    axis : int
        Axis holding the observations.

    Returns
    -------
    numpy.ndarray
        Threshold per remaining index.

    Raises
    ------
    FaultMonitorError
        If there are fewer than 8 observations, ``k <= 0`` or ``floor < 0``.
    """
    a = np.asarray(samples, dtype=float)
    if a.ndim == 0 or a.shape[axis] < 8:
        raise FaultMonitorError(
            f"calibration needs >= 8 healthy observations per feature, got shape {a.shape}; "
            "lengthen the calibration window"
        )
    if not k > 0:
        raise FaultMonitorError(f"k must be > 0, got {k}")
    if not floor >= 0:
        raise FaultMonitorError(f"floor must be >= 0, got {floor}")
    med = np.median(a, axis=axis)
    mad = np.median(np.abs(a - np.expand_dims(med, axis)), axis=axis)
    return np.maximum(med + k * MAD_TO_SIGMA * mad, floor)
