"""
The ``WaveletCoefficients`` messages of the ``fault_monitor`` node: their check and conversion.

:func:`check_coefficients` refuses a message the monitor cannot use (the node's module notes,
"Bad input"); :func:`record_from_msg` converts an accepted one into the core's
:class:`~amb_fault_monitor.records.SampleCoefficients`. ``KIND``, ``FRAME`` and ``QUAD`` map
the message codes onto the core's names.

A message the filterbank serialised in this process (the nodes composed on one
:class:`~amb_tools.local_bus.LocalBus`) comes as a view that carries the filterbank's records
(:class:`amb_wavelet.messages.LocalRecords`): its levels, codes, supports, lengths and finite
values are the filterbank's own, so only what depends on the monitor's configuration
(``samples_per_rev``) is checked; a message from DDS is checked field by field.
"""

from __future__ import annotations

import numpy as np
from amb_msgs.msg import CoefficientSet as CoefficientSetMsg
from amb_msgs.msg import WaveletCoefficients

from amb_common.names import N_SENSORS
from amb_fault_monitor.records import CoefficientSet, SampleCoefficients
from amb_tools.conversions import MessageError, check_finite, check_length, from_float_array
from amb_wavelet.levels import revolution_level

KIND = {CoefficientSetMsg.KIND_DETAIL: "detail", CoefficientSetMsg.KIND_APPROXIMATION: "approx"}
FRAME = {CoefficientSetMsg.FRAME_FIXED: "fixed", CoefficientSetMsg.FRAME_ROTATING: "rotating"}
QUAD = {CoefficientSetMsg.QUADRATURE_EVEN: "even", CoefficientSetMsg.QUADRATURE_ODD: "odd"}
#: Deepest level the filterbank can publish: ``log2(samples_per_rev) + 1`` (0.5 x, section 5.3);
#: its approximation counts one level deeper in the monitor.
EXTRA_OCTAVES = 1


def check_coefficients(msg: WaveletCoefficients, samples_per_rev: int) -> None:
    """
    Raise :class:`~amb_tools.conversions.MessageError` unless a coefficient message can be used.

    Parameters
    ----------
    msg : amb_msgs.msg.WaveletCoefficients
    samples_per_rev : int
        The monitor's samples per revolution; levels 1 .. ``log2(samples_per_rev) + 1`` exist.

    Raises
    ------
    MessageError
        Naming the field, the expected and the actual value: ``samples_per_rev`` differs, no
        set, an unknown level, kind, frame or quadrature code, a support that does not end at
        ``sample_index`` or starts after it ends, a set without 8 values, a non-finite value.
    """
    if msg.samples_per_rev != samples_per_rev:
        raise MessageError(
            f"field 'samples_per_rev' = {msg.samples_per_rev}, expected {samples_per_rev}"
        )
    if not msg.sets:
        raise MessageError("field 'sets' is empty: a coefficient message carries at least one")
    if getattr(msg, "records", None) is not None:
        return  # serialised in this process by the filterbank from its own records (module notes)
    deepest = revolution_level(samples_per_rev) + EXTRA_OCTAVES
    n = msg.sample_index
    for s in msg.sets:
        if not 1 <= s.level <= deepest:
            raise MessageError(f"field 'sets[].level' = {s.level}, expected 1..{deepest}")
        for name, value, codes in (
            ("kind", s.kind, KIND),
            ("frame", s.frame, FRAME),
            ("quadrature", s.quadrature, QUAD),
        ):
            if value not in codes:
                raise MessageError(
                    f"field 'sets[].{name}' = {value}, expected one of {list(codes)}"
                )
        if s.last_sample_index != n or s.first_sample_index > s.last_sample_index:
            raise MessageError(
                f"field 'sets[]' support [{s.first_sample_index}, {s.last_sample_index}], "
                f"expected to end at sample_index {n}"
            )
        check_length("sets[].values", from_float_array(s.values), N_SENSORS)
    check_finite("sets[].values", np.concatenate([from_float_array(s.values) for s in msg.sets]))


def filterbank_restarted(msg: WaveletCoefficients) -> bool:
    """Whether the filterbank restarted its filters shortly before this message.

    True if a finest-level (level 1) set is not ``settled``: its support reaches back past the
    filterbank's start or reset (start-up zeros). A jump of the coefficient stream to such a
    message is the filterbank's own gap (it reset on a gap of its measurement stream, possibly
    one its reader dropped to catch up, which this node cannot see), not a stray message, so
    it is accepted at once (:meth:`amb_tools.validation.SampleSequencer.push`, ``gap_known``):
    held for confirmation, the last message of a stream that ends there would never be
    processed.
    """
    return any(s.level == 1 and not s.settled for s in msg.sets)


def record_from_msg(msg: WaveletCoefficients, omega: float) -> SampleCoefficients:
    """Convert a ``WaveletCoefficients`` message (checked by :func:`check_coefficients`)."""
    sets = tuple(
        CoefficientSet(
            int(s.level),
            "detail" if s.kind == CoefficientSetMsg.KIND_DETAIL else "approximation",
            FRAME[s.frame],
            QUAD[s.quadrature],
            int(s.translation_index),
            int(s.first_sample_index),
            int(s.last_sample_index),
            from_float_array(s.values),
            bool(s.settled),
        )
        for s in msg.sets
    )
    return SampleCoefficients(int(msg.sample_index), float(omega), sets, str(msg.wavelet))
