"""
Validation of incoming messages: what a node accepts from the wire.

Each check raises :class:`~amb_tools.conversions.MessageError` (a ``ValueError``) with the
field, the expected and the actual value, so that a node counts and reports a bad message (on
``/diagnostics``) instead of letting it reach its core. :class:`SampleSequencer` orders a
node's input stream by sample index: repeats, stray indices and impossible stamps are refused,
a step back is a restart.
"""

from __future__ import annotations

import math

import numpy as np

from amb_common.names import N_AXES, N_SENSORS
from amb_tools.cdr import MeasurementView
from amb_tools.conversions import MessageError, check_finite, check_length, from_float_array

#: A stamp step may exceed the sample interval implied by the running speed by this factor
#: before the sample counts as "stamped in the future" (speed changes, clock jitter).
STAMP_TOLERANCE = 4.0
#: m, no displacement sensor of an AMB rig reads this far (clearances are ~1e-3 m): a larger
#: value is a corrupt message, and would overflow the filters' state.
MAX_DISPLACEMENT = 1.0
#: The array fields of a ``Measurement`` and their lengths, in message order.
MEASUREMENT_ARRAYS = (
    ("displacement", N_SENSORS),
    ("current", N_AXES),
    ("bearing_force", N_AXES),
    ("wavelet_force", N_AXES),
)
MEASUREMENT_VALUES = sum(n for _, n in MEASUREMENT_ARRAYS)


#: The last read-only measurement view that passed :func:`check_measurement`, and for which
#: samples per revolution: the nodes composed on one bus check the same view in turn.
_checked: tuple[MeasurementView | None, int] = (None, 0)


def check_measurement(msg, samples_per_rev: int) -> None:
    """Raise :class:`MessageError` unless a ``Measurement`` can be used.

    Checks the array lengths (8 displacements, 4 currents, forces and wavelet forces), that
    every value the consumers read is finite, that ``rotor_speed`` is > 0 rad/s (samples are
    taken speed-synchronously, so a sample at a standstill cannot exist), that
    ``samples_per_rev`` is the consumer's, that ``rotor_angle`` is in [0, 2 pi) (keyphasor
    angle, README "hardware interface") and that every displacement is within
    :data:`MAX_DISPLACEMENT`.

    Parameters
    ----------
    msg : amb_msgs.msg.Measurement
    samples_per_rev : int
        The consumer's samples per revolution.

    Raises
    ------
    MessageError
        Naming the field, the expected and the actual value.
    """
    global _checked
    passed, spr = _checked
    if passed is msg and spr == samples_per_rev and isinstance(msg, MeasurementView):
        return  # this read-only view passed already (composed nodes share one view)
    arrays = [from_float_array(getattr(msg, name)) for name, _ in MEASUREMENT_ARRAYS]
    # fast path (every sample of every consumer): one concatenation, one finiteness test; the
    # field-by-field checks below only run to name the culprit of a bad message
    try:
        joined = np.concatenate(arrays)
    except ValueError:  # not 1-D: the checks below report it
        joined = None
    if joined is None or joined.size != MEASUREMENT_VALUES or not np.isfinite(joined).all():
        for (name, expected), values in zip(MEASUREMENT_ARRAYS, arrays, strict=True):
            check_length(name, values, expected)
            check_finite(name, values)
    if msg.samples_per_rev != samples_per_rev:
        raise MessageError(
            f"field 'samples_per_rev' = {msg.samples_per_rev}, expected {samples_per_rev}"
        )
    speed = msg.rotor_speed
    if not (math.isfinite(speed) and speed > 0.0):
        raise MessageError(f"field 'rotor_speed' = {speed} rad/s, expected > 0")
    if not (0.0 <= msg.rotor_angle < 2.0 * np.pi):
        raise MessageError(f"field 'rotor_angle' = {msg.rotor_angle} rad, expected [0, 2 pi)")
    peak = float(np.abs(arrays[0]).max())
    if peak > MAX_DISPLACEMENT:
        raise MessageError(
            f"field 'displacement' reaches {peak:g} m, expected |x| <= {MAX_DISPLACEMENT} m"
        )
    if isinstance(msg, MeasurementView):
        _checked = (msg, samples_per_rev)


def stamp_step_error(
    previous: float, current: float, samples: int, omega: float, samples_per_rev: int
) -> str | None:
    """Return why a stamp step is impossible, or None if it is plausible.

    ``samples`` sample intervals of a speed-synchronous stream take
    ``samples * 2 pi / (samples_per_rev * omega)`` s. A stamp earlier than the previous one
    goes back in time; one more than :data:`STAMP_TOLERANCE` times the expected step later is
    from the future. Equal stamps are allowed (a bridge with a coarse clock, hand-made test
    streams).

    Parameters
    ----------
    previous, current : float
        s, stamps of the previous accepted sample and of this one.
    samples : int
        Index difference (>= 1).
    omega : float
        rad/s, running speed (> 0).
    samples_per_rev : int
        Samples per revolution.
    """
    step = current - previous
    if step < 0.0:
        return f"stamp {current:.9f} s before the previous sample's {previous:.9f} s"
    expected = samples * 2.0 * np.pi / (samples_per_rev * omega)
    if step > STAMP_TOLERANCE * expected + 1e-6:
        return (
            f"stamp {current:.9f} s is {step:.6f} s after the previous sample, expected "
            f"{expected:.6f} s for {samples} sample(s): from the future"
        )
    return None


class SampleSequencer:
    """Keep a measurement stream consecutive; reject repeats, outliers and impossible stamps.

    A message that continues the stream (``sample_index`` one more than the last accepted,
    plausible stamp) is accepted at once. A repeat of the last accepted index is rejected. Any
    other index (a jump forward, a step back) is held as a *candidate*: if the next message
    continues the candidate, the stream really jumped (samples lost) or restarted (a plant
    restarted from 0), both are accepted with ``reset = True`` so that the consumer restarts
    its filters there; if the next message continues the old stream instead, the candidate was
    a stray message and is rejected. One bad message therefore never derails the stream, and a
    real discontinuity costs one sample of latency.

    A jump forward the caller knows to be real, because its own reader dropped the samples
    between to catch up (``gap_known``, :class:`amb_tools.backlog.BacklogReader`), is accepted
    at once as a gap when its stamp is plausible: held as a candidate, the newest sample of a
    stream that ends there would never be confirmed (the end of a ``realtime`` run behind the
    plant: the node's last sample stays short of the plant's, and ``amb-run`` waits out its drain
    timeout).

    Attributes
    ----------
    counts : dict
        ``repeat``, ``stray`` (discontinuities not confirmed), ``stamp`` (impossible stamps),
        ``gap`` (confirmed jumps forward), ``restart`` (confirmed steps back).
    """

    def __init__(self, samples_per_rev: int) -> None:
        self.samples_per_rev = int(samples_per_rev)
        self.counts = dict.fromkeys(("repeat", "stray", "stamp", "gap", "restart"), 0)
        self.last_reason = ""
        self.reset()

    def reset(self) -> None:
        """Forget the stream (the next message starts a new one); counts are kept."""
        self._last: tuple[int, float] | None = None
        self._candidate: tuple[int, float, float, object] | None = None

    @property
    def last_index(self) -> int | None:
        """Index of the last accepted sample (None before the first)."""
        return None if self._last is None else self._last[0]

    @property
    def pending_index(self) -> int | None:
        """Index of the candidate waiting for confirmation (None if there is none)."""
        return None if self._candidate is None else self._candidate[0]

    def push(
        self, index: int, stamp_s: float, omega: float, payload: object, gap_known: bool = False
    ) -> list:
        """Offer one message; return the ``(reset, payload)`` pairs to process, in order.

        Parameters
        ----------
        index : int
            ``sample_index`` of the message.
        stamp_s : float
            s, its ``header.stamp``.
        omega : float
            rad/s, its ``rotor_speed`` (> 0, see :func:`check_measurement`).
        payload : object
            What to hand back (the message).
        gap_known : bool
            The caller's reader dropped messages just before this one (class notes): a jump
            forward with a plausible stamp is a gap, accepted at once.

        Returns
        -------
        list of (bool, object)
            Empty if the message was rejected or is held as a candidate.
        """
        if self._last is None:
            self._last = (index, stamp_s)
            return [(True, payload)]
        last_index, last_stamp = self._last
        if index == last_index + 1:
            why = stamp_step_error(last_stamp, stamp_s, 1, omega, self.samples_per_rev)
            if why is not None:
                return self._reject("stamp", f"sample {index}: {why}")
            if self._candidate is not None:
                self._reject("stray", f"sample {self._candidate[0]} after {last_index}: stray")
                self._candidate = None
            self._last = (index, stamp_s)
            return [(False, payload)]
        if index == last_index and self._candidate is None:
            return self._reject("repeat", f"sample {index} repeated")
        if gap_known and index > last_index + 1:
            why = stamp_step_error(
                last_stamp, stamp_s, index - last_index, omega, self.samples_per_rev
            )
            if why is None:
                if self._candidate is not None:
                    self.counts["stray"] += 1  # superseded: the reader dropped past it
                    self._candidate = None
                self.counts["gap"] += 1
                self.last_reason = (
                    f"sample {index} after {last_index}: gap (the reader dropped the samples "
                    "between to catch up), filters reset"
                )
                self._last = (index, stamp_s)
                return [(True, payload)]
        cand = self._candidate
        if cand is not None and index == cand[0] + 1:
            why = stamp_step_error(cand[1], stamp_s, 1, omega, self.samples_per_rev)
            if why is None:
                kind = "gap" if cand[0] > last_index else "restart"
                self.counts[kind] += 1
                self.last_reason = f"sample {cand[0]} after {last_index}: {kind}, filters reset"
                self._candidate = None
                self._last = (index, stamp_s)
                return [(True, cand[3]), (False, payload)]
        if cand is not None:
            self._reject("stray", f"sample {cand[0]} after {last_index}: not confirmed, dropped")
        self._candidate = (index, stamp_s, omega, payload)
        return []

    def _reject(self, kind: str, reason: str) -> list:
        self.counts[kind] += 1
        self.last_reason = reason
        return []


def check_command(msg, samples_per_period: int, num_axes: int = N_AXES) -> np.ndarray:
    """Return the force of a ``ControlCommand`` as ``(samples_per_period, num_axes)`` N.

    Raises
    ------
    MessageError
        If ``samples_per_period`` or ``start_sample_index`` disagree with ``period_index``,
        ``based_on_period`` is not before ``period_index``, or the force has the wrong
        length or a non-finite value.
    """
    k = msg.period_index
    if msg.samples_per_period != samples_per_period or msg.start_sample_index != k * (
        samples_per_period
    ):
        raise MessageError(
            f"command for period {k}: samples_per_period {msg.samples_per_period} / start "
            f"{msg.start_sample_index}, expected {samples_per_period} / {k * samples_per_period}"
        )
    if k < 0 or msg.based_on_period >= k:
        raise MessageError(
            f"command for period {k} based on period {msg.based_on_period}: expected "
            "0 <= based_on_period < period_index"
        )
    force = from_float_array(msg.force)
    check_length("force", force, num_axes * samples_per_period)
    check_finite("force", force)
    return force.reshape(num_axes, samples_per_period).T
