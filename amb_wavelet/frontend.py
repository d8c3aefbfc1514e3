"""
Channel front-end of the filterbank node: frames and even/odd (quadrature) channels.

Section 4.3: a wavelet evaluated at fixed translations returns zero for a signal 90 deg
out of phase with it (figure 4.6). Each channel is therefore analysed twice: the *even*
channel as measured and the *odd* channel delayed by a quarter period,
``x_odd[n] = x[n - quarter_delay]``. For a steady sinusoid whose quarter period is
exactly ``quarter_delay`` samples, every wavelet coefficient pair obeys
``d_even = Re(e^{i phi} Psi)``, ``d_odd = Im(e^{i phi} Psi)`` with
``Psi = sum_n psi[n] e^{i omega n}``, so ``hypot(d_even, d_odd) = |A Psi(omega)|`` does not
depend on the phase ``phi``. The default ``quarter_delay = samples_per_rev // 4`` is a
quarter revolution: exact for synchronous (1 x) vibration, the level ``p = 1`` of the
controller (:math:`x_{1,1}`); at other frequencies the pair magnitude still varies with
phase (a level at ``h`` x running speed needs ``samples_per_rev // (4 h)``).

The channel vector handed to :class:`~amb_wavelet.analysis.AnalysisFilterbank` is
ordered frame-major, then quadrature, then sensor channel::

    index = (frame_i * len(quadrature) + quad_i) * n_sensor_channels + channel

with labels such as ``"fixed/even/x1"`` or ``"rotating/odd/v3"``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from numpy.typing import ArrayLike

from amb_wavelet.frames import to_rotating_frame
from amb_wavelet.levels import revolution_level

__all__ = ["FRAMES", "QUADRATURES", "ChannelFrontEnd", "QuarterPeriodDelay"]

FRAMES = ("fixed", "rotating")
QUADRATURES = ("even", "odd")


class QuarterPeriodDelay:
    """
    Integer-sample delay line ``y[n] = x[n - delay]`` (zeros before the first sample).

    Parameters
    ----------
    delay : int
        Delay (samples, >= 0).
    n_channels : int
        Channels ``C``.
    """

    def __init__(self, delay: int, n_channels: int) -> None:
        if isinstance(delay, bool) or int(delay) != delay or delay < 0:
            raise ValueError(f"delay must be an int >= 0 samples, got {delay!r}")
        self._d = int(delay)
        self._C = int(n_channels)
        self._buf = np.zeros((max(self._d, 1), self._C))
        self._i = 0

    @property
    def delay(self) -> int:
        """Delay in samples."""
        return self._d

    def reset(self) -> None:
        """Clear the line (zeros)."""
        self._buf[...] = 0.0
        self._i = 0

    def step(self, v: np.ndarray) -> np.ndarray:
        """Push one sample ``(C,)``; return the sample ``delay`` steps old."""
        if self._d == 0:
            return np.array(v, dtype=float)
        out = self._buf[self._i].copy()
        self._buf[self._i] = v
        self._i += 1
        if self._i == self._d:
            self._i = 0
        return out

    def process_block(self, x: np.ndarray) -> np.ndarray:
        """Push ``(N, C)`` samples; return them delayed (same numbers as :meth:`step`)."""
        if self._d == 0:
            return np.array(x, dtype=float)
        hist = np.roll(self._buf, -self._i, axis=0)  # oldest first
        ext = np.concatenate([hist, x])
        n = x.shape[0]
        tail = ext[-self._d :]
        self._buf[...] = tail
        self._i = 0
        return ext[:n].copy()


class ChannelFrontEnd:
    """
    Build the analysed channel set from one sample of sensor displacements.

    Parameters
    ----------
    samples_per_rev : int
        Samples per revolution (power of two >= 4).
    frames : sequence of {"fixed", "rotating"}
        Reference frames to include (module :mod:`amb_wavelet.frames`).
    quadrature : sequence of {"even", "odd"}
        Quadrature channels to include (section 4.3).
    n_sensor_channels : int
        Sensor channels per sample, an even number of (x, y) pairs (8 on the rig).
    quarter_delay : int, optional
        Odd-channel delay (samples); default ``samples_per_rev // 4``.
    """

    def __init__(
        self,
        samples_per_rev: int,
        frames: Sequence[str] = FRAMES,
        quadrature: Sequence[str] = QUADRATURES,
        n_sensor_channels: int = 8,
        quarter_delay: int | None = None,
    ) -> None:
        if revolution_level(samples_per_rev) < 2:
            raise ValueError(
                f"samples_per_rev must be >= 4 for a quarter period, got {samples_per_rev}"
            )
        self._frames = self._check_names("frames", frames, FRAMES)
        self._quad = self._check_names("quadrature", quadrature, QUADRATURES)
        if n_sensor_channels < 2 or n_sensor_channels % 2:
            raise ValueError(
                f"n_sensor_channels must be an even number of (x, y) pairs, got {n_sensor_channels}"
            )
        self._S = int(n_sensor_channels)
        self._delay = QuarterPeriodDelay(
            samples_per_rev // 4 if quarter_delay is None else quarter_delay,
            len(self._frames) * self._S,
        )
        self._rot = "rotating" in self._frames
        self._fixed = "fixed" in self._frames
        self._even = "even" in self._quad
        self._odd = "odd" in self._quad

    @staticmethod
    def _check_names(what: str, given: Sequence[str], allowed: tuple[str, ...]) -> tuple[str, ...]:
        names = tuple(given)
        if not names or any(n not in allowed for n in names) or len(set(names)) != len(names):
            raise ValueError(
                f"{what} must be a non-empty selection of {allowed} without repeats, got {names}"
            )
        return tuple(n for n in allowed if n in names)  # canonical order

    @property
    def n_channels(self) -> int:
        """Channels produced per sample ``C = frames * quadratures * sensor channels``."""
        return len(self._frames) * len(self._quad) * self._S

    @property
    def quarter_delay(self) -> int:
        """Odd-channel delay (samples)."""
        return self._delay.delay

    @property
    def labels(self) -> list[str]:
        """Label of each output channel, e.g. ``"rotating/odd/v2"``."""
        out = []
        for frame in self._frames:
            axes = ("x", "y") if frame == "fixed" else ("u", "v")
            for quad in self._quad:
                out += [f"{frame}/{quad}/{axes[c % 2]}{c // 2 + 1}" for c in range(self._S)]
        return out

    def reset(self) -> None:
        """Clear the quarter-period delay line."""
        self._delay.reset()

    def _frames_of(self, xy: np.ndarray, angle: ArrayLike) -> np.ndarray:
        parts = []
        if self._fixed:
            parts.append(xy)
        if self._rot:
            parts.append(to_rotating_frame(xy, angle))
        return parts[0] if len(parts) == 1 else np.concatenate(parts, axis=-1)

    def _assemble(self, framed: np.ndarray, delayed: np.ndarray) -> np.ndarray:
        S, F = self._S, len(self._frames)
        parts = []
        for f in range(F):
            if self._even:
                parts.append(framed[..., f * S : (f + 1) * S])
            if self._odd:
                parts.append(delayed[..., f * S : (f + 1) * S])
        return np.concatenate(parts, axis=-1)

    def step(self, displacements: ArrayLike, angle: float) -> np.ndarray:
        """
        One sample in, the channel vector out.

        Parameters
        ----------
        displacements : array_like
            Shape ``(n_sensor_channels,)``, ``[x1, y1, ...]`` (m).
        angle : float
            Rotor angle (rad) at this sample.

        Returns
        -------
        numpy.ndarray
            Shape ``(n_channels,)``, ordered as :attr:`labels`.
        """
        xy = np.asarray(displacements, dtype=float)
        if xy.shape != (self._S,):
            raise ValueError(f"displacements must have shape ({self._S},), got {xy.shape}")
        # one sample of 8 channels: plain floats, each numpy call would cost more than the
        # arithmetic (the node calls this at the sample rate); the numbers are those of
        # to_rotating_frame: numpy's cos and sin of the angle, then float64 products and sums
        values = xy.tolist()
        framed = list(values) if self._fixed else []
        if self._rot:
            c, s = float(np.cos(angle)), float(np.sin(angle))
            for x, y in zip(values[0::2], values[1::2], strict=True):
                framed += (c * x + s * y, c * y - s * x)
        delayed = self._delay.step(np.array(framed)).tolist() if self._odd else framed
        S = self._S
        out = []
        for f in range(len(self._frames)):
            if self._even:
                out += framed[f * S : (f + 1) * S]
            if self._odd:
                out += delayed[f * S : (f + 1) * S]
        return np.array(out)

    def process_block(self, displacements: ArrayLike, angles: ArrayLike) -> np.ndarray:
        """
        Block form of :meth:`step` (same numbers, shared state).

        Parameters
        ----------
        displacements : array_like
            Shape ``(N, n_sensor_channels)`` (m).
        angles : array_like
            Shape ``(N,)`` (rad).

        Returns
        -------
        numpy.ndarray
            Shape ``(N, n_channels)``.
        """
        xy = np.asarray(displacements, dtype=float)
        if xy.ndim != 2 or xy.shape[1] != self._S:
            raise ValueError(f"displacements must have shape (N, {self._S}), got {xy.shape}")
        framed = self._frames_of(xy, angles)
        delayed = self._delay.process_block(framed) if self._odd else framed
        return self._assemble(framed, delayed)
