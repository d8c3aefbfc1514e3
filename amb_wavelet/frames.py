r"""
Fixed and synchronously rotating reference frames (thesis eq. 2.22-2.26, 5.1-5.2).

This is the one place in the project where sensor displacements are transformed to the
rotating frame. Per sensor plane, with the rotor angle :math:`\theta` (rad, from the
once-per-revolution keyphasor, positive in the direction of rotation from +x towards +y):

.. math::

    \begin{bmatrix} u \\ v \end{bmatrix} =
    \begin{bmatrix} \cos\theta & \sin\theta \\ -\sin\theta & \cos\theta \end{bmatrix}
    \begin{bmatrix} x \\ y \end{bmatrix},
    \qquad u + i v = e^{-i\theta} (x + i y).

The matrix is :math:`\mathbf{T}(t)` of eq. 2.26 with :math:`\Omega t = \theta`.
Decision (thesis ambiguity): eq. 2.22 writes :math:`\mathbf{x} = \mathbf{T}\mathbf{r}`,
which with eq. 2.26 would make a forward synchronous orbit rotate at :math:`2\Omega` in
the "rotating" frame; eq. 5.1-5.2 (:math:`f_x + i f_y = m e \Omega^2 e^{i\Omega t}` and
:math:`f_u + i f_v = m e \Omega^2`) fix the intended transform as
:math:`u + iv = e^{-i\Omega t}(x + iy)`, i.e. :math:`\mathbf{r} = \mathbf{T}\mathbf{x}`.
We follow eq. 5.1-5.2, so that a steady forward circular (unbalance) orbit is constant in
(u, v) and its wavelet details vanish (eq. 5.4).

Channels are interleaved per plane, ``[x1, y1, x2, y2, ...] -> [u1, v1, u2, v2, ...]``.
"""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["to_fixed_frame", "to_rotating_frame"]


def _rotate(xy: ArrayLike, angle: ArrayLike, sign: float) -> np.ndarray:
    a = np.asarray(xy, dtype=float)
    th = np.asarray(angle, dtype=float)
    if a.ndim == 0 or a.shape[-1] % 2:
        raise ValueError(
            f"last axis must hold (x, y) pairs per plane, i.e. an even length, got shape {a.shape}"
        )
    if th.shape != a.shape[:-1]:
        raise ValueError(
            f"angle must have shape {a.shape[:-1]} (one rotor angle per sample), got {th.shape}"
        )
    c = np.cos(th)[..., None]
    s = sign * np.sin(th)[..., None]
    x = a[..., 0::2]
    y = a[..., 1::2]
    out = np.empty_like(a)
    out[..., 0::2] = c * x + s * y
    out[..., 1::2] = c * y - s * x
    return out


def to_rotating_frame(xy: ArrayLike, angle: ArrayLike) -> np.ndarray:
    r"""
    Transform fixed-frame (x, y) pairs into the synchronously rotating frame (u, v).

    Parameters
    ----------
    xy : array_like
        Shape ``(..., 2P)``: ``[x1, y1, ..., xP, yP]`` per sample (m, or any unit).
    angle : array_like
        Rotor angle :math:`\theta` (rad), shape ``xy.shape[:-1]`` (a scalar for one
        sample).

    Returns
    -------
    numpy.ndarray
        ``[u1, v1, ..., uP, vP]``, same shape and unit, ``u + iv = e^{-i theta}(x + iy)``.
    """
    return _rotate(xy, angle, 1.0)


def to_fixed_frame(uv: ArrayLike, angle: ArrayLike) -> np.ndarray:
    """
    Transform rotating-frame (u, v) pairs back to the fixed frame (inverse of the above).

    Parameters
    ----------
    uv : array_like
        Shape ``(..., 2P)``: ``[u1, v1, ...]`` (e.g. control forces in N).
    angle : array_like
        Rotor angle (rad), shape ``uv.shape[:-1]``.

    Returns
    -------
    numpy.ndarray
        ``[x1, y1, ...]`` with ``x + iy = e^{i theta}(u + iv)``.
    """
    return _rotate(uv, angle, -1.0)
