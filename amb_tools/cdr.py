"""The two stream messages as CDR bytes, written and read with numpy and ``struct``.

``Measurement`` (one per sample) and ``WaveletCoefficients`` (one per odd sample) are the only
messages at the sample rate. Building them as rclpy message objects and letting rclpy convert
them costs, per message, tens of microseconds of Python (``__init__`` and property setters of
every nested ``CoefficientSet``, ``Header`` and ``Time``), and so does the reverse conversion
in every subscriber: at 67 Hz x 32 samples/rev that was a large part of each node's CPU
(``bench/pipeline_profile.py``). Here the nodes publish the serialised bytes directly
(``Publisher.publish`` accepts ``bytes``) and subscribe with ``raw=True``:

- :func:`measurement_cdr_block` serialises a whole block of samples in a few numpy operations;
- :func:`coefficients_cdr` serialises the coefficients one sample completed;
- :func:`read_measurement` and :func:`read_coefficients` read the bytes into light views with
  the messages' field names (``numpy`` views of the arrays, no copy). The views are read-only
  by contract (their arrays are): the same ``bytes`` object read again returns the view already
  made, so the nodes composed on one :class:`~amb_tools.local_bus.LocalBus`, which each read
  every message the bus hands them, read it once between them.

The layout is the OMG CDR of ROS 2 (XCDR1, little endian: the 4-byte encapsulation header
``00 01 00 00``, each primitive aligned to its size counted from the end of that header,
strings as ``uint32`` length including the NUL, sequences as ``uint32`` count), the layout of
the ``amb_msgs`` definitions. Padding is written as zeros (rclpy leaves it uninitialised: bags
and tests compare deserialised fields, never raw bytes). A buffer in any other encapsulation
(big endian, XCDR2) is handed to rclpy's own deserialiser, so a peer that serialises otherwise
is still understood. The tests check both directions against rclpy's serialiser.
"""

from __future__ import annotations

import struct
from dataclasses import dataclass, field
from functools import lru_cache

import amb_msgs.msg
import numpy as np
from builtin_interfaces.msg import Time
from rclpy.serialization import deserialize_message
from std_msgs.msg import Header

CDR_LE = b"\x00\x01\x00\x00"
_ORIGIN = len(CDR_LE)  # alignment counts from the end of the encapsulation header


def _align(pos: int, size: int) -> int:
    """Position ``pos`` (from the buffer start) rounded up to a multiple of ``size`` in CDR."""
    return pos + (-(pos - _ORIGIN) % size)


def _string(value: str) -> bytes:
    data = value.encode() + b"\x00"
    return struct.pack("<I", len(data)) + data


def _read_string(buf: bytes, pos: int) -> tuple[str, int]:
    pos = _align(pos, 4)
    (n,) = struct.unpack_from("<I", buf, pos)
    return bytes(buf[pos + 4 : pos + 3 + n]).decode(), pos + 4 + n


@dataclass(slots=True, frozen=True)
class StampView:
    """``builtin_interfaces/Time`` read from CDR: ``sec``, ``nanosec`` (comparable, hashable)."""

    sec: int
    nanosec: int


@dataclass(slots=True)
class HeaderView:
    """``std_msgs/Header`` read from CDR; :meth:`to_msg` gives the rclpy message."""

    stamp: StampView
    frame_id: str

    def to_msg(self):
        """Return a ``std_msgs.msg.Header`` (for a message built from this one's header)."""
        return Header(
            stamp=Time(sec=self.stamp.sec, nanosec=self.stamp.nanosec), frame_id=self.frame_id
        )


def _header(buf: bytes) -> tuple[HeaderView, int]:
    sec, nanosec = struct.unpack_from("<iI", buf, _ORIGIN)
    frame_id, pos = _read_string(buf, _ORIGIN + 8)
    return HeaderView(StampView(sec, nanosec), frame_id), pos


def header_view(h) -> HeaderView:
    """An rclpy ``std_msgs/Header`` (or a view) as a :class:`HeaderView`."""
    if isinstance(h, HeaderView):
        return h
    return HeaderView(StampView(h.stamp.sec, h.stamp.nanosec), h.frame_id)


# ---------------------------------------------------------------------------------------------
# Measurement
# ---------------------------------------------------------------------------------------------


#: The float64 fields of a ``Measurement`` after ``samples_per_rev``, in order, and their sizes.
MEASUREMENT_DOUBLES = (
    ("rotor_angle", 1),
    ("rotor_speed", 1),
    ("displacement", 8),
    ("current", 4),
    ("bearing_force", 4),
    ("wavelet_force", 4),
)
_N_DOUBLES = sum(n for _, n in MEASUREMENT_DOUBLES)


@lru_cache(maxsize=8)
def _measurement_dtype(frame_id_bytes: int) -> tuple[np.dtype, int]:
    """Record layout of a ``Measurement`` whose frame_id has ``frame_id_bytes`` (with the NUL).

    Returns the structured dtype (fields at their CDR offsets, from the buffer start) and the
    serialised size.
    """
    pos = _ORIGIN + 12 + frame_id_bytes
    fields = {"encapsulation": ("<u4", 0), "sec": ("<i4", 4), "nanosec": ("<u4", 8),
              "frame_len": ("<u4", 12)}  # fmt: skip
    pos = _align(pos, 8)
    fields["sample_index"] = ("<u8", pos)
    fields["samples_per_rev"] = ("<u4", pos + 8)
    pos = _align(pos + 12, 8)
    for name, count in MEASUREMENT_DOUBLES:
        fields[name] = (("<f8", (count,)) if count > 1 else "<f8", pos)
        pos += 8 * count
    fields["status"] = ("<u2", pos)
    size = pos + 2
    dtype = np.dtype(
        {
            "names": list(fields),
            "formats": [f for f, _ in fields.values()],
            "offsets": [o for _, o in fields.values()],
            "itemsize": size,
        }
    )
    return dtype, size


@dataclass(slots=True)
class MeasurementView:
    """
    A ``Measurement`` read from CDR.

    Field names of ``amb_msgs/Measurement``; arrays are read-only ``float64`` views.
    """

    header: HeaderView
    sample_index: int
    samples_per_rev: int
    rotor_angle: float
    rotor_speed: float
    displacement: np.ndarray
    current: np.ndarray
    bearing_force: np.ndarray
    wavelet_force: np.ndarray
    status: int


def measurement_cdr_block(
    sample_index: np.ndarray,
    time_ns: np.ndarray,
    samples_per_rev: int,
    rotor_angle: np.ndarray,
    rotor_speed: np.ndarray,
    displacement: np.ndarray,
    current: np.ndarray,
    bearing_force: np.ndarray,
    wavelet_force: np.ndarray,
    status: np.ndarray,
    frame_id: str = "amb_rig",
) -> list[bytes]:
    """Serialise ``n`` ``Measurement`` messages at once.

    Parameters
    ----------
    sample_index : numpy.ndarray
        ``(n,)`` sample indices.
    time_ns : numpy.ndarray
        ``(n,)`` int, ``header.stamp`` in ns (>= 0).
    samples_per_rev : int
        Samples per revolution.
    rotor_angle, rotor_speed : numpy.ndarray
        ``(n,)`` rad and rad/s.
    displacement : numpy.ndarray
        ``(n, 8)`` m.
    current, bearing_force, wavelet_force : numpy.ndarray
        ``(n, 4)`` A, N, N.
    status : numpy.ndarray
        ``(n,)`` ``STATUS_*`` flags.
    frame_id : str
        ``header.frame_id``.

    Returns
    -------
    list of bytes
        One CDR buffer per sample, ready for ``Publisher.publish``.
    """
    name = frame_id.encode() + b"\x00"
    dtype, size = _measurement_dtype(len(name))
    n = len(sample_index)
    rec = np.zeros(n, dtype=dtype)
    rec["encapsulation"] = np.frombuffer(CDR_LE, dtype="<u4")[0]
    t = np.asarray(time_ns, dtype=np.int64)
    rec["sec"] = t // 1_000_000_000
    rec["nanosec"] = t % 1_000_000_000
    rec["frame_len"] = len(name)
    rec["sample_index"] = sample_index
    rec["samples_per_rev"] = samples_per_rev
    rec["rotor_angle"] = rotor_angle
    rec["rotor_speed"] = rotor_speed
    rec["displacement"] = displacement
    rec["current"] = current
    rec["bearing_force"] = bearing_force
    rec["wavelet_force"] = wavelet_force
    rec["status"] = status
    raw = rec.view(np.uint8).reshape(n, size)
    raw[:, _ORIGIN + 12 : _ORIGIN + 12 + len(name)] = np.frombuffer(name, dtype=np.uint8)
    data = raw.tobytes()
    return [data[i * size : (i + 1) * size] for i in range(n)]


class _LastRead:
    """The view made from the last ``bytes`` object read (one per reader function)."""

    __slots__ = ("last",)

    def __init__(self) -> None:
        self.last: tuple = (None, None)  # (bytes, view), replaced whole: threads see a pair

    def get(self, raw: bytes):
        """The view of ``raw`` if it is the very ``bytes`` object read last (``is``), else None."""
        last_raw, view = self.last  # last_raw: bytes or None (put keeps nothing else)
        return view if last_raw is raw else None

    def put(self, raw: bytes, view):
        """Keep ``view`` as the one of ``raw`` (immutable ``bytes`` only); return it."""
        self.last = (raw, view) if isinstance(raw, bytes) else (None, None)
        return view


_LAST_MEASUREMENT = _LastRead()
_LAST_COEFFICIENTS = _LastRead()


def read_measurement(raw: bytes) -> MeasurementView:
    """Read a serialised ``Measurement`` (any CDR encapsulation; see the module docstring).

    The same ``bytes`` object read again returns the same (read-only) view.

    Raises
    ------
    ValueError
        If the buffer is too short for its own layout.
    """
    view = _LAST_MEASUREMENT.get(raw)
    if view is None:
        view = _LAST_MEASUREMENT.put(raw, _read_measurement(raw))
    return view


def _read_measurement(raw: bytes) -> MeasurementView:
    if raw[:2] != CDR_LE[:2]:
        return _measurement_from_msg(_deserialise(raw, "Measurement"))
    try:
        sec, nanosec, name_len = struct.unpack_from("<iII", raw, _ORIGIN)
        frame_id = bytes(raw[16 : 15 + name_len]).decode()
        pos = _align(16 + name_len, 8)
        sample_index, spr = struct.unpack_from("<QI", raw, pos)
        pos = _align(pos + 12, 8)
        angle, speed = struct.unpack_from("<dd", raw, pos)
        values = np.frombuffer(raw, dtype="<f8", count=_N_DOUBLES - 2, offset=pos + 16)
        (status,) = struct.unpack_from("<H", raw, pos + 8 * _N_DOUBLES)
    except (struct.error, ValueError) as exc:
        raise ValueError(f"Measurement of {len(raw)} bytes: {exc}") from exc
    return MeasurementView(
        HeaderView(StampView(sec, nanosec), frame_id), sample_index, spr, angle, speed,
        values[0:8], values[8:12], values[12:16], values[16:20], status,
    )  # fmt: skip


def _deserialise(raw: bytes, name: str):
    try:
        return deserialize_message(bytes(raw), getattr(amb_msgs.msg, name))
    except Exception as exc:  # rclpy raises RMWError (not a ValueError) on a garbled buffer
        raise ValueError(f"{name} of {len(raw)} bytes: {exc}") from exc


def _measurement_from_msg(msg) -> MeasurementView:
    return MeasurementView(
        header_view(msg.header), int(msg.sample_index), int(msg.samples_per_rev),
        float(msg.rotor_angle), float(msg.rotor_speed), np.asarray(msg.displacement),
        np.asarray(msg.current), np.asarray(msg.bearing_force), np.asarray(msg.wavelet_force),
        int(msg.status),
    )  # fmt: skip


# ---------------------------------------------------------------------------------------------
# WaveletCoefficients
# ---------------------------------------------------------------------------------------------


@dataclass(slots=True)
class CoefficientSetView:
    """A ``CoefficientSet`` read from CDR (``values``: read-only ``float64`` view)."""

    level: int
    kind: int
    frame: int
    quadrature: int
    translation_index: int
    first_sample_index: int
    last_sample_index: int
    pseudo_frequency: float
    settled: bool
    values: np.ndarray


@dataclass(slots=True)
class CoefficientsView:
    """A ``WaveletCoefficients`` read from CDR (field names of the message)."""

    header: HeaderView
    wavelet: str
    samples_per_rev: int
    sample_index: int
    period_index: int
    samples_per_period: int
    channel_names: list[str]
    sets: list[CoefficientSetView]
    #: The producer's own records of these coefficients when the view was made in this process
    #: by :func:`coefficients_cdr` (``records``), else None: composed readers take them instead
    #: of rebuilding them from ``sets``.
    records: object = field(default=None, repr=False, metadata={"message_field": False})


_SET = struct.Struct("<qqQd?")


def coefficients_cdr(
    header: HeaderView,
    wavelet: str,
    samples_per_rev: int,
    sample_index: int,
    period_index: int,
    samples_per_period: int,
    channel_names: list[str] | tuple[str, ...],
    sets: list[tuple],
    records: object = None,
) -> bytes:
    """Serialise a ``WaveletCoefficients`` message.

    Parameters
    ----------
    header : HeaderView
        Stamp and frame of the completing measurement.
    wavelet : str
        PyWavelets name.
    samples_per_rev, sample_index, period_index, samples_per_period : int
        As the message fields.
    channel_names : sequence of str
        The channel names.
    sets : list of tuple
        ``(level, kind, frame, quadrature, translation_index, first_sample_index,
        last_sample_index, pseudo_frequency, settled, values)`` per ``CoefficientSet``,
        ``values`` a float64 array (a read-only one is kept in the view as it is, others are
        copied).
    records : object, optional
        The producer's own form of the same coefficients, kept in the view
        (:attr:`CoefficientsView.records`) for the readers composed in this process.

    Returns
    -------
    bytes
    """
    names = tuple(channel_names)
    sizes = tuple(len(s[9]) for s in sets)
    layout, frame, tail, names_cdr = _coefficients_layout(
        header.frame_id, wavelet, int(samples_per_rev), names, sizes
    )
    flat = [CDR_LE, header.stamp.sec, header.stamp.nanosec, frame, tail, sample_index,
            period_index, samples_per_period, names_cdr, len(sets)]  # fmt: skip
    for level, kind, frame, quad, m, first, last, freq, settled, values in sets:
        flat += (level, kind, frame, quad, m, first, last, freq, settled, len(values))
        flat += values.tolist() if isinstance(values, np.ndarray) else list(values)
    raw = layout.pack(*flat)
    # the view read_coefficients would parse from these bytes, made from the fields at hand: a
    # reader composed in this process (amb_tools.local_bus) is handed this very object and
    # gets the view without parsing it again
    _LAST_COEFFICIENTS.put(
        raw,
        CoefficientsView(
            header, wavelet, int(samples_per_rev), int(sample_index), int(period_index),
            int(samples_per_period), list(names),
            [CoefficientSetView(int(level), int(kind), int(frame), int(quad), int(m), int(first),
                                int(last), float(freq), bool(settled), frozen_values(values))
             for level, kind, frame, quad, m, first, last, freq, settled, values in sets],
            records,
        ),
    )  # fmt: skip
    return raw


@lru_cache(maxsize=64)
def _coefficients_layout(
    frame_id: str, wavelet: str, samples_per_rev: int, names: tuple[str, ...], sizes: tuple
) -> tuple[struct.Struct, bytes, bytes, bytes]:
    """The whole ``WaveletCoefficients`` CDR as one struct, and its three constant parts.

    A stream's layout repeats with the sizes of its sets. The struct packs the encapsulation
    header, ``sec, nanosec``, the frame id (constant), the wavelet and ``samples_per_rev``
    (constant), ``sample_index, period_index, samples_per_period``, the channel names
    (constant), ``n_sets`` and the fields of each set as :func:`_sets_format`; the constants
    are returned with it.
    """
    frame = _string(frame_id)
    pos = 8 + len(frame)  # counted from the origin (after the encapsulation header)
    tail = bytes(-pos % 4) + _string(wavelet)
    tail += bytes(-(pos + len(tail)) % 4) + struct.pack("<I", samples_per_rev)
    pos += len(tail)
    fmt = f"<4siI{len(frame)}s{len(tail)}s{-pos % 8}xQqI"
    pos += -pos % 8 + 20
    names_cdr = struct.pack("<I", len(names))
    for name in names:
        names_cdr += bytes(-(pos + len(names_cdr)) % 4) + _string(name)
    names_cdr += bytes(-(pos + len(names_cdr)) % 4)
    pos += len(names_cdr) + 4
    sets = _sets_format(pos % 8, sizes)
    return struct.Struct(f"{fmt}{len(names_cdr)}sI{sets}"), frame, tail, names_cdr


def frozen_values(values) -> np.ndarray:
    """A read-only float64 array: ``values`` if it is one already, else a copy.

    (A parsed view is read-only, and the caller's array may change.)
    """
    if isinstance(values, np.ndarray) and values.dtype == np.float64 and not values.flags.writeable:
        return values
    out = np.array(values, dtype=np.float64)
    out.flags.writeable = False
    return out


def _sets_format(start: int, sizes: tuple[int, ...]) -> str:
    """The ``struct`` format (no byte order) of ``CoefficientSet[]`` from ``start`` (mod 8).

    ``start`` is counted after the origin; ``sizes`` is the number of values of each set;
    padding bytes (``x``) are written as zeros.
    """
    fmt, pos = [], start

    def pad(size: int) -> None:
        nonlocal pos
        n = -pos % size
        if n:
            fmt.append(f"{n}x")
        pos += n

    for n in sizes:
        fmt.append("4B")
        pos += 4
        pad(8)
        fmt.append("qqQd?")
        pos += 33
        pad(4)
        fmt.append("I")
        pos += 4
        if n:
            pad(8)
            fmt.append(f"{n}d")
            pos += 8 * n
    return "".join(fmt)


def read_coefficients(raw: bytes) -> CoefficientsView:
    """Read a serialised ``WaveletCoefficients`` (any CDR encapsulation; module docstring).

    The same ``bytes`` object read again returns the same (read-only) view, and the ``bytes``
    that :func:`coefficients_cdr` returned last in this process return the view it made from
    its fields (the readers composed with the filterbank parse nothing).

    Raises
    ------
    ValueError
        If the buffer ends before its own counts say.
    """
    view = _LAST_COEFFICIENTS.get(raw)
    if view is None:
        view = _LAST_COEFFICIENTS.put(raw, _read_coefficients(raw))
    return view


def _read_coefficients(raw: bytes) -> CoefficientsView:
    if raw[:2] != CDR_LE[:2]:
        msg = _deserialise(raw, "WaveletCoefficients")
        return CoefficientsView(
            header_view(msg.header), msg.wavelet, int(msg.samples_per_rev), int(msg.sample_index),
            int(msg.period_index), int(msg.samples_per_period), list(msg.channel_names),
            [CoefficientSetView(s.level, s.kind, s.frame, s.quadrature, s.translation_index,
                                s.first_sample_index, s.last_sample_index, s.pseudo_frequency,
                                s.settled, np.frombuffer(s.values, dtype=np.float64))
             for s in msg.sets],
        )  # fmt: skip
    try:
        return _read_coefficients_le(raw)
    except struct.error as exc:
        raise ValueError(f"WaveletCoefficients of {len(raw)} bytes: {exc}") from exc


def _read_coefficients_le(raw: bytes) -> CoefficientsView:
    header, pos = _header(raw)
    wavelet, pos = _read_string(raw, pos)
    pos = _align(pos, 4)
    (spr,) = struct.unpack_from("<I", raw, pos)
    pos = _align(pos + 4, 8)
    sample_index, period_index, spp, n_names = struct.unpack_from("<QqII", raw, pos)
    pos += 24
    names = []
    for _ in range(n_names):
        name, pos = _read_string(raw, pos)
        names.append(name)
    pos = _align(pos, 4)
    (n_sets,) = struct.unpack_from("<I", raw, pos)
    pos += 4
    sets = []
    unpack_set = _SET.unpack_from
    for _ in range(n_sets):
        level, kind, frame, quad = raw[pos : pos + 4]
        pos = _align(pos + 4, 8)
        m, first, last, freq, settled = unpack_set(raw, pos)
        pos = _align(pos + _SET.size, 4)
        (n,) = struct.unpack_from("<I", raw, pos)
        pos += 4
        if n:
            pos = _align(pos, 8)
            if pos + 8 * n > len(raw):
                raise struct.error(f"values of {n} doubles run past the end")
            values = np.frombuffer(raw, dtype="<f8", count=n, offset=pos)
            pos += 8 * n
        else:
            values = np.zeros(0)
        sets.append(
            CoefficientSetView(level, kind, frame, quad, m, first, last, freq, settled, values)
        )
    return CoefficientsView(header, wavelet, spr, sample_index, period_index, spp, names, sets)
