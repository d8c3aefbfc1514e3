"""
Level indexing, pseudo-frequencies and delays of the dyadic filterbank.

With speed-synchronous sampling, ``samples_per_rev = 2**R`` samples per revolution and
``fs = samples_per_rev * omega / (2 pi)`` (Hz). Filterbank level ``level = j``
(``j = 1`` is the first, finest split, figure 4.3) down-samples by ``2**j`` (dyadic
sampling, figure 4.4), so one coefficient of level ``j`` is produced every ``2**j``
samples and its (Haar) wavelet spans ``2**j`` samples. The thesis names levels by their
pseudo-frequency (section 5.3: 8, 4, 2, 1, 0.5 x running speed; chapters 7-8:
:math:`x_{1,1}` at 1 x, :math:`x_{2,1}` at 2 x, :math:`x_{3,1}` at 4 x). The mapping
used throughout this project is

====================  =========================================================
level ``j``           pseudo-frequency ``fs / 2**j`` (Hz)
                      = ``samples_per_rev / 2**j`` x running speed
thesis level ``p``    ``p = R - j + 1``: ``p = 1`` is the level whose wavelet spans
                      one revolution (``j = R``, 1 x), ``p = 2`` is 2 x, ``p = 3`` 4 x
translation ``q``     ``q = 1 .. 2**(p - 1)`` numbers the level-``j`` wavelets that
                      complete inside one control period (one revolution)
====================  =========================================================

Levels ``j > R`` (pseudo-frequency below 1 x, e.g. 0.5 x in section 5.3) exist in the
filterbank but have ``p <= 0``: the thesis counts them in the period average
:math:`x^0(kT)` (text after eq. 6.24), so the period-sampled form of eq. 6.2-6.3 uses
``1 <= p <= R`` only.

The pseudo-frequency ``fs / 2**j`` is the nominal one the thesis uses: one cycle of the
Haar wavelet per ``2**j`` samples. The level-``j`` detail band is the octave
``[fs / 2**(j + 1), fs / 2**j]``; PyWavelets' ``pywt.scale2frequency`` gives the centre
frequency of a particular wavelet instead (e.g. 0.67 ``fs / 2**j`` for ``db2``).

Timing (causal filterbank, filters of length ``L``): the coefficient with translation
index ``m`` at level ``j`` is completed by sample ``2**j (m + 1) - 1`` and its support
(the samples it depends on) spans ``(2**j - 1)(L - 1) + 1`` samples ending there. It is
emitted on the very sample that completes it (no extra latency); its support centre lies
``(2**j - 1)(L - 1) / 2`` samples before that.
"""

from __future__ import annotations

from amb_wavelet.errors import LevelError

__all__ = [
    "check_level",
    "completion_sample_index",
    "harmonic_of_level",
    "level_count_for",
    "level_from_thesis_p",
    "pseudo_frequency",
    "revolution_level",
    "support_first_sample_index",
    "support_length",
    "synthesis_delay",
    "thesis_p",
]


def _check_int(name: str, value: object, minimum: int) -> int:
    if isinstance(value, bool) or not isinstance(value, int | float) or int(value) != value:
        raise LevelError(f"{name} must be an integer, got {value!r}")
    if value < minimum:
        raise LevelError(f"{name} must be >= {minimum}, got {value}")
    return int(value)


def revolution_level(samples_per_rev: int) -> int:
    """
    Return ``R = log2(samples_per_rev)``, the level whose wavelet spans one revolution.

    Parameters
    ----------
    samples_per_rev : int
        Samples per revolution, a power of two >= 2.

    Returns
    -------
    int
        ``R``; level ``R`` has pseudo-frequency 1 x running speed (thesis ``p = 1``).

    Raises
    ------
    LevelError
        If ``samples_per_rev`` is not a power of two >= 2.
    """
    n = _check_int("samples_per_rev", samples_per_rev, 2)
    if n & (n - 1):
        raise LevelError(
            f"samples_per_rev must be a power of two (dyadic levels map onto multiples of "
            f"the running speed), got {n}; use {1 << (n.bit_length() - 1)} or "
            f"{1 << n.bit_length()}"
        )
    return n.bit_length() - 1


def check_level(level: int, samples_per_rev: int | None = None, extra_octaves: int = 1) -> int:
    """
    Validate a number of decomposition levels.

    Parameters
    ----------
    level : int
        Number of levels ``J >= 1`` (levels ``1 .. J`` are computed).
    samples_per_rev : int, optional
        If given, also require ``J <= log2(samples_per_rev) + extra_octaves``.
    extra_octaves : int
        Octaves allowed below 1 x running speed (section 5.3 uses one: 0.5 x).

    Returns
    -------
    int
        ``level`` as an int.

    Raises
    ------
    LevelError
        If the level is not an integer in the allowed range.
    """
    j = _check_int("level", level, 1)
    if samples_per_rev is not None:
        r = revolution_level(samples_per_rev)
        top = r + _check_int("extra_octaves", extra_octaves, 0)
        if j > top:
            raise LevelError(
                f"level {j} is too deep for samples_per_rev={samples_per_rev}: expected "
                f"level <= log2(samples_per_rev) + extra_octaves = {r} + {extra_octaves} = "
                f"{top} (level {top} has pseudo-frequency "
                f"{harmonic_of_level(top, samples_per_rev):g} x running speed); lower the "
                "level or raise samples_per_rev"
            )
    return j


def harmonic_of_level(level: int, samples_per_rev: int) -> float:
    """
    Return the pseudo-frequency of a level as a multiple of the running speed.

    Parameters
    ----------
    level : int
        Filterbank level ``j >= 1``.
    samples_per_rev : int
        Samples per revolution (power of two).

    Returns
    -------
    float
        ``samples_per_rev / 2**level`` (e.g. 1.0 for ``level = log2(samples_per_rev)``).
    """
    revolution_level(samples_per_rev)
    j = _check_int("level", level, 1)
    return samples_per_rev / 2.0**j


def pseudo_frequency(level: int, fs: float) -> float:
    """
    Return the nominal pseudo-frequency of a level.

    Parameters
    ----------
    level : int
        Filterbank level ``j >= 1``.
    fs : float
        Sample rate (Hz).

    Returns
    -------
    float
        ``fs / 2**level`` (Hz).
    """
    j = _check_int("level", level, 1)
    if not fs > 0:
        raise LevelError(f"fs must be > 0 Hz, got {fs!r}")
    return float(fs) / 2.0**j


def thesis_p(level: int, samples_per_rev: int) -> int:
    """
    Return the thesis level index ``p`` of chapters 6-8 (``p = 1`` at 1 x running speed).

    Parameters
    ----------
    level : int
        Filterbank level ``j``.
    samples_per_rev : int
        Samples per revolution (power of two).

    Returns
    -------
    int
        ``p = log2(samples_per_rev) - level + 1``; ``p <= 0`` for levels below 1 x.
    """
    return revolution_level(samples_per_rev) - _check_int("level", level, 1) + 1


def level_from_thesis_p(p: int, samples_per_rev: int) -> int:
    """
    Return the filterbank level ``j`` of thesis level ``p`` (inverse of :func:`thesis_p`).

    Parameters
    ----------
    p : int
        Thesis level, ``1 <= p <= log2(samples_per_rev)``.
    samples_per_rev : int
        Samples per revolution (power of two).

    Returns
    -------
    int
        ``j = log2(samples_per_rev) - p + 1``.

    Raises
    ------
    LevelError
        If ``p`` is outside ``1 .. log2(samples_per_rev)``.
    """
    r = revolution_level(samples_per_rev)
    p = _check_int("p", p, 1)
    if p > r:
        raise LevelError(
            f"thesis level p={p} needs wavelets of {2 ** (r - p + 1)} sample(s) or fewer; "
            f"expected 1 <= p <= log2(samples_per_rev) = {r}; raise samples_per_rev"
        )
    return r - p + 1


def support_length(level: int, filter_length: int) -> int:
    """
    Return the number of input samples one level-``level`` coefficient depends on.

    Parameters
    ----------
    level : int
        Filterbank level ``j >= 1``.
    filter_length : int
        Filter length ``L``.

    Returns
    -------
    int
        ``(2**j - 1)(L - 1) + 1``.
    """
    j = _check_int("level", level, 1)
    return (2**j - 1) * (_check_int("filter_length", filter_length, 2) - 1) + 1


def completion_sample_index(level: int, translation_index: int) -> int:
    """
    Return the sample index that completes coefficient ``translation_index`` of a level.

    Parameters
    ----------
    level : int
        Filterbank level ``j >= 1``.
    translation_index : int
        Translation index ``m`` (row of ``pywt.wavedec(..., mode='zero')`` output).

    Returns
    -------
    int
        ``2**j (m + 1) - 1``, the last sample of the support.
    """
    return 2 ** _check_int("level", level, 1) * (int(translation_index) + 1) - 1


def support_first_sample_index(level: int, translation_index: int, filter_length: int) -> int:
    """
    Return the first sample index of the support (negative during start-up).

    Parameters
    ----------
    level : int
        Filterbank level ``j >= 1``.
    translation_index : int
        Translation index ``m``.
    filter_length : int
        Filter length ``L``.

    Returns
    -------
    int
        ``completion_sample_index - support_length + 1``.
    """
    return (
        completion_sample_index(level, translation_index) - support_length(level, filter_length) + 1
    )


def synthesis_delay(level: int, filter_length: int) -> int:
    """
    Return the delay of causal analysis followed by causal synthesis over ``level`` levels.

    The reconstruction is ``y[n] = x[n - D]`` with ``D = (2**J - 1)(L - 1)``: the
    approximation and the deepest detail at level ``J`` each depend on
    ``(2**J - 1)(L - 1) + 1`` samples, so sample ``n - D`` is the last one whose every
    basis function (eq. 4.15) has been completed by sample ``n``. Haar: ``2**J - 1``,
    the thesis's polyphase causality delay ``N - 1`` with ``N = 2**J`` (section 4.2.4).

    Parameters
    ----------
    level : int
        Number of levels ``J``.
    filter_length : int
        Filter length ``L``.

    Returns
    -------
    int
        ``D`` (samples).
    """
    return support_length(level, filter_length) - 1


def level_count_for(n_samples: int, level: int) -> int:
    """
    Return the number of level-``level`` coefficients completed by ``n_samples`` samples.

    Parameters
    ----------
    n_samples : int
        Samples since index 0.
    level : int
        Filterbank level ``j >= 1``.

    Returns
    -------
    int
        ``n_samples // 2**level`` (the first that many rows of ``pywt.wavedec``).
    """
    return int(n_samples) >> _check_int("level", level, 1)
