"""The hand-written CDR of the two stream messages agrees with rclpy's own serialiser.

Reference: ``rclpy.serialization`` (the generated type support of ``amb_msgs``). Each direction
is checked field by field after deserialisation (padding bytes are not compared: rclpy leaves
them uninitialised): bytes written by :mod:`amb_tools.cdr` are deserialised by rclpy into the
message the object builders make, and bytes serialised by rclpy are read by the views into the
same fields.
"""

from __future__ import annotations

from array import array
from types import SimpleNamespace

import numpy as np
import pytest
from msg_fill import diff, random_message, to_plain

from amb_tools.cdr import HeaderView, StampView, read_coefficients, read_measurement
from amb_tools.conversions import measurement_bytes, measurement_msgs
from amb_wavelet.messages import coefficients_bytes, coefficients_msg

pytestmark = pytest.mark.ros


def test_random_measurements_read_like_rclpy_deserialises_them() -> None:
    from amb_msgs.msg import Measurement
    from rclpy.serialization import serialize_message

    rng = np.random.default_rng(7)
    for i in range(40):
        msg = random_message(Measurement, rng)
        msg.header.frame_id = "f" * (i % 11)  # every alignment of the fields after it
        view = read_measurement(serialize_message(msg))
        assert diff(to_plain(view), to_plain(msg)) == [], i


def test_random_coefficient_messages_read_like_rclpy_deserialises_them() -> None:
    from amb_msgs.msg import CoefficientSet, WaveletCoefficients
    from rclpy.serialization import serialize_message

    rng = np.random.default_rng(8)
    for i in range(40):
        msg = random_message(WaveletCoefficients, rng)
        msg.sets = [random_message(CoefficientSet, rng) for _ in range(i % 9)]
        for k, s in enumerate(msg.sets):
            s.values = array("d", rng.normal(size=(i + k) % 10))  # incl. empty sequences
        view = read_coefficients(serialize_message(msg))
        assert diff(to_plain(view), to_plain(msg)) == [], i


def _block(n: int, rng: np.random.Generator) -> SimpleNamespace:
    return SimpleNamespace(
        sample_index=np.arange(1000, 1000 + n),
        time=(np.arange(1000, 1000 + n) + rng.random()) / 2144.0,
        angle=rng.random(n) * 2 * np.pi,
        omega=np.full(n, 421.0) + rng.normal(size=n),
        displacement=rng.normal(size=(n, 8)) * 1e-5,
        current=rng.normal(size=(n, 4)),
        bearing_force=rng.normal(size=(n, 4)) * 400.0,
        truth=None,
    )


def _filterbank(wavelet: str, n: int, rng: np.random.Generator):
    """Front end and filterbank at 32 samples/rev, every (frame, quadrature) slot, n samples."""
    from amb_tools.streams import FRAME_CODES, QUAD_CODES
    from amb_wavelet.analysis import AnalysisFilterbank
    from amb_wavelet.frontend import ChannelFrontEnd

    front = ChannelFrontEnd(32)
    bank = AnalysisFilterbank(wavelet, 6, front.n_channels)
    slots = [(FRAME_CODES[f], QUAD_CODES[q]) for f in FRAME_CODES for q in QUAD_CODES]
    block = _block(n, rng)
    bank.reset(start_sample_index=int(block.sample_index[0]))
    return front, bank, slots, block


def test_measurement_bytes_deserialise_to_the_messages_measurement_msgs_builds() -> None:
    from amb_msgs.msg import Measurement
    from rclpy.serialization import deserialize_message

    rng = np.random.default_rng(9)
    block = _block(32, rng)
    wf = rng.normal(size=(32, 4)) * 50.0
    status = rng.integers(0, 16, size=32)
    limit = 500.0  # some samples saturate: the flag must be set in both
    expected = measurement_msgs(block, wf, status, 32, limit)
    raw, flags = measurement_bytes(block, wf, status, 32, limit)
    assert any(m.status & Measurement.STATUS_FORCE_SATURATED for m in expected)
    assert [m.status for m in expected] == flags.tolist()
    for i, (b, m) in enumerate(zip(raw, expected, strict=True)):
        assert deserialize_message(b, Measurement) == m, i


@pytest.mark.parametrize("wavelet", ["haar", "db4"])
def test_coefficients_bytes_deserialise_to_the_message_coefficients_msg_builds(wavelet) -> None:
    from amb_msgs.msg import Measurement, WaveletCoefficients
    from rclpy.serialization import deserialize_message

    front, bank, slots, block = _filterbank(wavelet, 96, np.random.default_rng(10))
    msgs = measurement_msgs(block, np.zeros((96, 4)), 0, 32, 1e4)
    published = 0
    for k, m in enumerate(msgs):
        m.header.frame_id = "rig" * (k % 4)
        n = int(m.sample_index)
        coefficients = bank.step(front.step(m.displacement, m.rotor_angle), n)
        if not coefficients:
            continue
        args = (m.header, wavelet, 32, 32, n, m.rotor_speed, coefficients, slots)
        raw = coefficients_bytes(*args)
        mine = deserialize_message(raw, WaveletCoefficients)
        assert mine == coefficients_msg(*args), n
        # the view kept at serialisation (for composed readers) is the one the parser reads
        _assert_same_view(read_coefficients(raw), read_coefficients(bytes(bytearray(raw))))
        published += 1
    assert published == 48  # every odd sample completes a level-1 coefficient
    assert isinstance(msgs[0], Measurement)


@pytest.mark.parametrize("wavelet", ["haar", "db4"])
def test_composed_readers_take_the_filterbanks_records_with_the_numbers_dds_readers_get(
    wavelet,
) -> None:
    """The view kept at serialisation carries the filterbank's records (``LocalRecords``).

    A reader composed with the filterbank gets them as they are; a reader of the same bytes from
    DDS rebuilds them from the sets: both must see the core's numbers. The monitor's check of a
    local view still refuses another ``samples_per_rev``.
    """
    from amb_fault_monitor.coefficient_messages import check_coefficients
    from amb_tools.conversions import MessageError
    from amb_wavelet.messages import LocalRecords, coefficient_records

    front, bank, slots, block = _filterbank(wavelet, 64, np.random.default_rng(11))
    header = HeaderView(StampView(3, 4), "rig")
    checked = 0
    for xy, angle, n in zip(block.displacement, block.angle, block.sample_index, strict=True):
        core = bank.step(front.step(xy, angle), int(n))
        if not core:
            continue
        raw = coefficients_bytes(header, wavelet, 32, 32, int(n), 421.0, core, slots)
        local, remote = read_coefficients(raw), read_coefficients(bytes(bytearray(raw)))
        assert isinstance(local.records, LocalRecords) and remote.records is None
        mine, rebuilt = coefficient_records(local, slots), coefficient_records(remote, slots)
        assert len(mine) == len(rebuilt) == len(core)
        for a, b, c in zip(mine, rebuilt, core, strict=True):
            assert a[:5] == b[:5] == c[:5] and a.settled == b.settled == c.settled
            np.testing.assert_array_equal(a.values, c.values)
            np.testing.assert_array_equal(b.values, c.values)
            assert not a.values.flags.writeable  # shared by the readers: read-only
        # a reader asking for other slots rebuilds them from the sets
        part = coefficient_records(local, slots[2:])
        np.testing.assert_array_equal(part[0].values, core[0].values[16:])
        check_coefficients(local, 32)
        with pytest.raises(MessageError, match="samples_per_rev"):
            check_coefficients(local, 64)
        checked += 1
    assert checked == 32


SET_FIELDS = ("level", "kind", "frame", "quadrature", "translation_index", "first_sample_index",
              "last_sample_index", "pseudo_frequency", "settled")  # fmt: skip


def _assert_same_view(kept, parsed) -> None:
    assert kept is not parsed
    for name in ("header", "wavelet", "samples_per_rev", "sample_index", "period_index",
                 "samples_per_period", "channel_names"):  # fmt: skip
        assert getattr(kept, name) == getattr(parsed, name), name
    assert len(kept.sets) == len(parsed.sets)
    for a, b in zip(kept.sets, parsed.sets, strict=True):
        for name in SET_FIELDS:
            assert getattr(a, name) == getattr(b, name), name
            assert type(getattr(a, name)) is type(getattr(b, name)), name
        assert a.values.dtype == b.values.dtype and not a.values.flags.writeable
        np.testing.assert_array_equal(a.values, b.values)  # the same doubles, written and read


def test_truncated_buffers_are_refused_with_a_value_error() -> None:
    from amb_msgs.msg import CoefficientSet, Measurement, WaveletCoefficients
    from rclpy.serialization import serialize_message

    m = serialize_message(Measurement())
    c = WaveletCoefficients(sets=[CoefficientSet(values=array("d", [1.0] * 8))])
    raw = serialize_message(c)
    with pytest.raises(ValueError):
        read_measurement(m[:40])
    with pytest.raises(ValueError):
        read_coefficients(raw[: len(raw) - 9])


def test_garbled_encapsulation_is_refused_with_a_value_error() -> None:
    # A buffer whose encapsulation bytes are not little-endian CDR goes through rclpy's
    # deserialiser; its RMWError must surface as the ValueError the nodes count as a rejected
    # message (the filterbank fuzz test saw it as a callback error instead).
    from amb_msgs.msg import Measurement, WaveletCoefficients
    from rclpy.serialization import serialize_message

    for msg, read in (
        (Measurement(), read_measurement),
        (WaveletCoefficients(), read_coefficients),
    ):
        raw = bytearray(serialize_message(msg))
        raw[0:2] = b"\x00\x00"  # big-endian CDR header on a little-endian body
        with pytest.raises(ValueError):
            read(bytes(raw[:12]))


def test_one_bytes_object_is_read_once_and_its_view_is_read_only() -> None:
    """The nodes composed on one bus read the same bytes in turn: one view, never changed."""
    from amb_msgs.msg import Measurement, WaveletCoefficients
    from rclpy.serialization import serialize_message

    rng = np.random.default_rng(11)
    for cls, read in ((Measurement, read_measurement), (WaveletCoefficients, read_coefficients)):
        raw = serialize_message(random_message(cls, rng))
        first = read(raw)
        assert read(raw) is first
        copy = bytes(bytearray(raw))  # equal bytes, another object: read anew, same content
        again = read(copy)
        assert again is not first and diff(to_plain(again), to_plain(first)) == []
        assert read(raw) is not first  # only the last object is kept
    view = read_measurement(serialize_message(random_message(Measurement, rng)))
    with pytest.raises(ValueError, match="read-only"):
        view.displacement[0] = 1.0
