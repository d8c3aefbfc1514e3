"""The wavelet coefficient messages: filterbank records <-> ``amb_msgs/WaveletCoefficients``.

The ROS side of the wavelet part (beside :mod:`amb_wavelet.node`): the filterbank node publishes
what :func:`coefficients_bytes` writes, the in-process loop records what
:func:`coefficients_msg` builds (the same fields and values), and the consumers of the stream
(the controller node, tests) turn a message back into the core's records with
:func:`coefficient_records`. The generic array and stamp conversions and their checks are in
:mod:`amb_tools.conversions`.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np
from amb_msgs.msg import CoefficientSet, WaveletCoefficients

from amb_common.names import N_SENSORS, SENSOR_NAMES
from amb_tools.cdr import coefficients_cdr, frozen_values, header_view
from amb_tools.conversions import (
    MessageError,
    check_finite,
    check_length,
    from_float_array,
    to_float_array,
)
from amb_wavelet.analysis import APPROXIMATION, DETAIL, Coefficient
from amb_wavelet.levels import pseudo_frequency


def _coefficient_set_fields(coefficients, slots, samples_per_rev: int, rotor_speed: float):
    """Return the ``CoefficientSet`` fields of :func:`coefficients_msg` as tuples.

    ``(level, kind, frame, quadrature, translation_index, first_sample_index,
    last_sample_index, pseudo_frequency, settled, values)``, one per coefficient and slot, in
    message order (the layout :func:`amb_tools.cdr.coefficients_cdr` takes).
    """
    fs = samples_per_rev * rotor_speed / (2.0 * np.pi)
    n = N_SENSORS
    sets = []
    for c in coefficients:
        kind = (
            CoefficientSet.KIND_APPROXIMATION
            if c.kind == APPROXIMATION
            else CoefficientSet.KIND_DETAIL
        )
        f_level = pseudo_frequency(c.level, fs) if fs > 0 else 0.0
        for i, (frame, quad) in enumerate(slots):
            sets.append(
                (c.level, kind, frame, quad, c.translation_index, c.first_sample_index,
                 c.last_sample_index, f_level, bool(c.settled), c.values[i * n : (i + 1) * n])
            )  # fmt: skip
    return sets


def coefficients_msg(
    header,
    wavelet: str,
    samples_per_rev: int,
    samples_per_period: int,
    sample_index: int,
    rotor_speed: float,
    coefficients,
    slots,
):
    """Build the ``WaveletCoefficients`` message of the coefficients one sample completed.

    Parameters
    ----------
    header : std_msgs.msg.Header
        Header of the completing ``Measurement``.
    wavelet : str
        PyWavelets name.
    samples_per_rev, samples_per_period : int
        Sampling and control period.
    sample_index : int
        The completing sample.
    rotor_speed : float
        rad/s, for the levels' pseudo-frequencies.
    coefficients : list of amb_wavelet.analysis.Coefficient
        What the filterbank returned for the sample; ``values`` ordered (slot, sensor channel).
    slots : list of (frame, quadrature) codes
        ``CoefficientSet.FRAME_*`` and ``QUADRATURE_*`` of each block of 8 values, in the
        front end's channel order.

    Returns
    -------
    amb_msgs.msg.WaveletCoefficients
    """
    sets = [
        CoefficientSet(
            level=level,
            kind=kind,
            frame=frame,
            quadrature=quad,
            translation_index=translation,
            first_sample_index=first,
            last_sample_index=last,
            pseudo_frequency=f_level,
            settled=settled,
            values=to_float_array(values),
        )
        for level, kind, frame, quad, translation, first, last, f_level, settled, values in (
            _coefficient_set_fields(coefficients, slots, samples_per_rev, rotor_speed)
        )
    ]
    return WaveletCoefficients(
        header=header,
        wavelet=wavelet,
        samples_per_rev=samples_per_rev,
        sample_index=sample_index,
        period_index=sample_index // samples_per_period,
        samples_per_period=samples_per_period,
        channel_names=list(SENSOR_NAMES),
        sets=sets,
    )


def coefficients_bytes(
    header,
    wavelet: str,
    samples_per_rev: int,
    samples_per_period: int,
    sample_index: int,
    rotor_speed: float,
    coefficients,
    slots,
) -> bytes:
    """Serialise the ``WaveletCoefficients`` message :func:`coefficients_msg` would build.

    Same parameters and the same fields and values, written as CDR bytes
    (:func:`amb_tools.cdr.coefficients_cdr`) without building the rclpy message objects;
    ``header`` may be an rclpy ``Header`` or a :class:`amb_tools.cdr.HeaderView`.

    Returns
    -------
    bytes
        For ``Publisher.publish``.
    """
    records = [c._replace(values=frozen_values(c.values)) for c in coefficients]
    sets = _coefficient_set_fields(records, slots, samples_per_rev, rotor_speed)
    return coefficients_cdr(
        header_view(header),
        wavelet,
        samples_per_rev,
        sample_index,
        sample_index // samples_per_period,
        samples_per_period,
        SENSOR_NAMES,
        sets,
        LocalRecords(tuple(slots), records),
    )


class LocalRecords(NamedTuple):
    """The filterbank's records of a message serialised in this process, for composed readers.

    Kept in the message's view (:attr:`amb_tools.cdr.CoefficientsView.records`): a reader on the
    same :class:`~amb_tools.local_bus.LocalBus` takes ``records`` (their ``values`` read-only,
    ordered by ``slots``) instead of rebuilding them from the sets (:func:`coefficient_records`),
    and need not check what this process's filterbank wrote (finite values, one support per
    coefficient, eight values per set).
    """

    slots: tuple
    records: list


def coefficient_records(msg, slots) -> list:
    """Turn a ``WaveletCoefficients`` message back into the filterbank's records.

    Inverse of :func:`coefficients_msg`: the sets of one (level, kind, translation) are joined,
    in the order of ``slots``, into one ``values`` vector, exactly as the filterbank core
    produced it, so that a consumer of the message stream sees the same numbers as one fed by
    the core directly.

    A message this process's filterbank serialised (:func:`coefficients_bytes`; the readers
    composed with it on one :class:`~amb_tools.local_bus.LocalBus`) carries the records
    themselves (:class:`LocalRecords`): asked for the same ``slots``, they are returned as they
    are (read-only values), the same numbers without the joining.

    Parameters
    ----------
    msg : amb_msgs.msg.WaveletCoefficients
    slots : list of (frame, quadrature) codes
        The blocks the consumer expects, in order (a subset of what the filterbank publishes).

    Returns
    -------
    list of amb_wavelet.analysis.Coefficient
        In message order (finest level first), ``values`` of shape ``(len(slots) * 8,)``.

    Raises
    ------
    MessageError
        If a set has the wrong number of values or a non-finite value, or a requested slot is
        missing for a coefficient.
    """
    local = getattr(msg, "records", None)
    if isinstance(local, LocalRecords) and local.slots == tuple(slots):
        return list(local.records)  # composed with the filterbank: its own records
    records: dict[tuple, dict] = {}
    for s in msg.sets:
        key = (s.level, s.kind, s.translation_index)
        entry = records.setdefault(key, {"set": s, "values": {}})
        values = from_float_array(s.values)
        check_length("sets[].values", values, N_SENSORS)
        entry["values"][(s.frame, s.quadrature)] = values
    out = []
    for (level, kind, m), entry in records.items():
        missing = [slot for slot in slots if slot not in entry["values"]]
        if missing:
            raise MessageError(
                f"coefficient level {level} translation {m}: (frame, quadrature) {missing} "
                "not published; configure the filterbank with those frames and channels"
            )
        values = np.concatenate([entry["values"][slot] for slot in slots])
        check_finite("sets[].values", values)
        s = entry["set"]
        name = APPROXIMATION if kind == CoefficientSet.KIND_APPROXIMATION else DETAIL
        out.append(
            Coefficient(
                level, name, m, s.first_sample_index, s.last_sample_index, values, s.settled
            )
        )
    return out
