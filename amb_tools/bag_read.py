"""Read a rosbag2 of this project's topics into numpy arrays (ROS-free, ``rosbags``).

Reads bags written by ``amb-sim``, by the ``recorder`` node (``amb-run``) or by
``ros2 bag record``: every message is deserialised with the ``amb_msgs`` type store
(:func:`amb_tools.bag_types.typestore`) and the time of each message is its **header stamp**
(simulated time in lock step), never the bag's receive time, so that the three kinds of bag
read the same. Missing or empty topics are tolerated: their arrays are empty and the topic is
listed in :attr:`BagData.missing`.

A bag recorded under a namespace (the system started in ``/rig1`` records
``/rig1/amb/measurement``, ...) reads the same: the streams are looked up under the namespace
given, or else under the one namespace in which the bag holds them
(:func:`amb_common.topics.bag_namespace`); :attr:`BagData.namespace` says which.

The per-period 1 x wavelet phasor is rebuilt from ``/amb/wavelet/coefficients`` exactly as the
in-process loop builds it (:class:`amb_apps.closed_loop._Loop`): for control period
``k`` (samples ``k N .. k N + N - 1``), the last fixed-frame detail coefficient of the 1 x
level ``j1 = log2(samples_per_rev)`` completed in that period,
``P_k = x_{1,1,even} + i x_{1,1,odd}`` (thesis section 4.3; the level indexing of chapters 7-8
puts ``x_{1,1}`` at 1 x running speed), and ``0`` for a period in which none was completed.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from rosbags.rosbag2 import Reader

from amb_common.topics import (
    COEFFICIENTS,
    COMMAND,
    FAULT_EVENTS,
    MEASUREMENT,
    ROOT_NAMESPACE,
    STATUS,
    absolute,
    bag_namespace,
)
from amb_common.topics import namespace as as_namespace
from amb_tools.bag_types import typestore

#: Topics a complete report uses, relative to the bag's namespace (``/diagnostics`` is counted,
#: not drawn).
EXPECTED_TOPICS = (MEASUREMENT, COEFFICIENTS, COMMAND, STATUS, FAULT_EVENTS)

# CoefficientSet constants (amb_msgs/msg/CoefficientSet.msg)
KIND_DETAIL = 0
FRAME_FIXED = 0
QUADRATURE_EVEN = 0
QUADRATURE_ODD = 1

#: FaultEvent.fault_type codes (amb_msgs/msg/FaultEvent.msg) and their names.
FAULT_TYPE_NAMES = {
    0: "UNKNOWN",
    1: "MASS_LOSS",
    2: "AUX_BEARING_CONTACT",
    3: "SENSOR_FAULT",
    4: "BASE_MOTION",
    5: "COIL_FAILURE",
    6: "TRIP",
}


class BagReadError(ValueError):
    """A bag cannot be read as a bag of this project (missing folder, no usable topic)."""


@dataclass
class Measurements:
    """``/amb/measurement`` as arrays, sorted by sample index (SI units).

    Attributes
    ----------
    sample_index : numpy.ndarray
        ``(n,)`` int64.
    stamp_ns : numpy.ndarray
        ``(n,)`` int64, header stamps in ns.
    time : numpy.ndarray
        ``(n,)`` s, header stamps.
    displacement : numpy.ndarray
        ``(n, 8)`` m, ``[x1, y1, x2, y2, x3, y3, x4, y4]``, planes from the non-driven end.
    current, bearing_force, wavelet_force : numpy.ndarray
        ``(n, 4)`` A, N, N per axis ``[b1x, b1y, b2x, b2y]``.
    rotor_speed, rotor_angle : numpy.ndarray
        ``(n,)`` rad/s, rad.
    status : numpy.ndarray
        ``(n,)`` ``Measurement.STATUS_*`` flags.
    samples_per_rev : int
    """

    sample_index: np.ndarray
    stamp_ns: np.ndarray
    time: np.ndarray
    displacement: np.ndarray
    current: np.ndarray
    bearing_force: np.ndarray
    wavelet_force: np.ndarray
    rotor_speed: np.ndarray
    rotor_angle: np.ndarray
    status: np.ndarray
    samples_per_rev: int


@dataclass
class OneXCoefficients:
    """The 1 x level fixed-frame wavelet coefficients, one per control period.

    Attributes
    ----------
    wavelet : str
        PyWavelets name.
    level : int
        Filterbank level ``j1 = log2(samples_per_rev)`` (pseudo-frequency band 0.5-1 x).
    samples_per_period : int
        Control period ``N`` in samples.
    even, odd : numpy.ndarray
        ``(K, 8)`` m sqrt(samples) (orthonormal filters), period ``k`` in row ``k``; 0 where no
        coefficient was completed in the period.
    present : numpy.ndarray of bool
        ``(K,)``, true where a coefficient was completed in the period.
    """

    wavelet: str
    level: int
    samples_per_period: int
    even: np.ndarray
    odd: np.ndarray
    present: np.ndarray

    @property
    def phasor(self) -> np.ndarray:
        """``(K, 8)`` complex ``P_k = even + i odd`` (thesis section 4.3)."""
        return self.even + 1j * self.odd


@dataclass
class LevelSeries:
    """Fixed-frame even detail coefficients of one level over the run.

    Attributes
    ----------
    level : int
    sample_index : numpy.ndarray
        ``(m,)`` completing sample of each coefficient.
    values : numpy.ndarray
        ``(m, 8)`` m sqrt(samples).
    pseudo_frequency : float
        Hz, as published (last message).
    """

    level: int
    sample_index: np.ndarray
    values: np.ndarray
    pseudo_frequency: float


@dataclass
class Commands:
    """``/amb/control/command`` as arrays, sorted by target period.

    Attributes
    ----------
    period_index : numpy.ndarray
        ``(m,)`` target period.
    start_sample_index : numpy.ndarray
        ``(m,)`` first sample of the target period.
    force : numpy.ndarray
        ``(m, 4, N)`` N, wavelet force samples per axis.
    hold : numpy.ndarray of bool
        ``(m,)``.
    wavelet : str
    delay_periods : int
    """

    period_index: np.ndarray
    start_sample_index: np.ndarray
    force: np.ndarray
    hold: np.ndarray
    wavelet: str
    delay_periods: int


@dataclass
class BagData:
    """Everything a report draws from one bag.

    Attributes
    ----------
    path : pathlib.Path
    counts : dict of str to int
        Messages per topic in the bag (every topic, including ``/diagnostics``; names as in
        the bag).
    missing : list of str
        Expected topics (:data:`EXPECTED_TOPICS`) absent or empty, absolute names under
        :attr:`namespace`.
    measurements : Measurements or None
    one_x : OneXCoefficients or None
    levels : dict of int to LevelSeries
    commands : Commands or None
    controller : dict
        From the last ``ControllerStatus``: ``controller``, ``mode``, ``delay_periods``,
        ``commands_sent``, ``commands_late``; empty if no status.
    fault_events : list of dict
        One per ``FaultEvent`` (fields as :meth:`amb_common.faults.FaultEvent.to_dict`).
    notes : list of str
        What could not be read and why.
    namespace : str
        The namespace the streams were read under (``/``: ``/amb/measurement``, ...).
    """

    path: Path
    counts: dict[str, int]
    missing: list[str]
    measurements: Measurements | None = None
    one_x: OneXCoefficients | None = None
    levels: dict[int, LevelSeries] = field(default_factory=dict)
    commands: Commands | None = None
    controller: dict = field(default_factory=dict)
    fault_events: list[dict] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)
    samples_per_rev: int | None = None
    namespace: str = ROOT_NAMESPACE
    _stamp_map: tuple[np.ndarray, np.ndarray] | None = None

    def topic(self, name: str) -> str:
        """Return the name stream ``name`` (relative, :mod:`amb_common.topics`) has in the bag."""
        return absolute(name, self.namespace)

    def sample_time(self, sample_index: np.ndarray | int) -> np.ndarray:
        """Return the time (s) of sample indices from the stamps of sample-indexed messages.

        Exact for samples present in ``/amb/measurement`` (or the coefficient stream);
        linearly inter-/extrapolated otherwise. ``NaN`` if the bag has no stamped samples.
        """
        n = np.asarray(sample_index, dtype=float)
        if self._stamp_map is None or self._stamp_map[0].size == 0:
            return np.full(n.shape, np.nan)
        idx, t = self._stamp_map
        if idx.size == 1:
            return np.full(n.shape, t[0])
        out = np.interp(n, idx, t)
        # linear extrapolation beyond the ends at the mean sample interval
        dt = (t[-1] - t[0]) / (idx[-1] - idx[0])
        out = np.where(n < idx[0], t[0] + (n - idx[0]) * dt, out)
        return np.where(n > idx[-1], t[-1] + (n - idx[-1]) * dt, out)

    def speed_hz(self) -> float | None:
        """Return the running speed in Hz: median measured speed, else from the stamps."""
        if self.measurements is not None and self.measurements.rotor_speed.size:
            return float(np.median(self.measurements.rotor_speed) / (2 * np.pi))
        if self._stamp_map is not None and self._stamp_map[0].size > 1 and self.samples_per_rev:
            idx, t = self._stamp_map
            fs = (idx[-1] - idx[0]) / (t[-1] - t[0])
            return float(fs / self.samples_per_rev)
        return None


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def _ns(stamp) -> int:
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def _parse_evidence_value(text: str):
    """Return ``text`` as int or float when it is one (``str`` of a number round-trips)."""
    for cast in (int, float):
        try:
            return cast(text)
        except ValueError:
            continue
    return text


def read_bag(path: str | Path, namespace: str | None = None) -> BagData:
    """Read one bag of this project's topics.

    Parameters
    ----------
    path : str or pathlib.Path
        Bag folder (with ``metadata.yaml``) or a single ``.mcap``/``.db3`` file's folder.
    namespace : str, optional
        The namespace the system ran in (``/rig1``: ``/rig1/amb/measurement``, ...); None: the
        one the bag holds the streams under (:func:`amb_common.topics.bag_namespace`).

    Returns
    -------
    BagData

    Raises
    ------
    BagReadError
        If ``path`` is not a readable rosbag2 folder, ``namespace`` is not a namespace, or
        none is given and the bag holds the streams under several.
    """
    path = Path(path)
    if path.is_file():
        path = path.parent
    if not (path / "metadata.yaml").is_file():
        raise BagReadError(
            f"{path} is not a rosbag2 folder (expected a folder with metadata.yaml, as written "
            "by amb-sim, amb-run or 'ros2 bag record')"
        )
    store = typestore()
    raw: dict[str, list] = {t: [] for t in EXPECTED_TOPICS}  # by relative name
    counts: dict[str, int] = {}
    notes: list[str] = []
    unreadable: set[str] = set()
    try:
        with Reader(path) as reader:
            for conn in reader.connections:
                counts.setdefault(conn.topic, 0)
            try:
                ns = bag_namespace(counts) if namespace is None else as_namespace(namespace)
            except ValueError as exc:
                raise BagReadError(f"bag {path}: {exc}") from exc
            stream = {absolute(t, ns): t for t in EXPECTED_TOPICS}  # name in the bag -> stream
            for conn, _t, data in reader.messages():
                counts[conn.topic] = counts.get(conn.topic, 0) + 1
                if conn.topic not in stream or conn.topic in unreadable:
                    continue
                try:
                    raw[stream[conn.topic]].append(store.deserialize_cdr(data, conn.msgtype))
                except Exception as exc:  # a foreign or changed type: skip the topic, say so
                    notes.append(f"{conn.topic}: cannot deserialise {conn.msgtype}: {exc}")
                    unreadable.add(conn.topic)
                    raw[stream[conn.topic]] = []
    except Exception as exc:  # rosbags raises its own hierarchy (ReaderError, ...)
        if isinstance(exc, BagReadError):
            raise
        raise BagReadError(f"cannot read bag {path}: {exc}") from exc
    missing = [absolute(t, ns) for t in EXPECTED_TOPICS if not raw[t]]
    data = BagData(path=path, counts=counts, missing=missing, notes=notes, namespace=ns)
    if raw[MEASUREMENT]:
        data.measurements = _measurements(raw[MEASUREMENT])
        data.samples_per_rev = data.measurements.samples_per_rev
    if raw[COEFFICIENTS] and data.samples_per_rev is None:
        data.samples_per_rev = int(raw[COEFFICIENTS][0].samples_per_rev)
    data._stamp_map = _stamp_map(data.measurements, raw[COEFFICIENTS])
    if raw[COMMAND]:
        data.commands = _commands(raw[COMMAND])
    if raw[COEFFICIENTS] and data.samples_per_rev:
        n_last = None
        if data.measurements is not None:
            n_last = int(data.measurements.sample_index[-1])
        data.one_x, data.levels = _coefficients(raw[COEFFICIENTS], data.samples_per_rev, n_last)
        if data.one_x is None:
            notes.append(
                f"{data.topic(COEFFICIENTS)}: no fixed-frame even/odd detail at the 1 x level "
                f"j = log2({data.samples_per_rev}); the 1 x phasor and settling are not available"
            )
    if raw[STATUS]:
        s = raw[STATUS][-1]
        data.controller = {
            "controller": str(s.controller),
            "mode": int(s.mode),
            "delay_periods": int(s.delay_periods),
            "commands_sent": int(s.commands_sent),
            "commands_late": int(s.commands_late),
        }
    data.fault_events = [_fault_event(m, data) for m in raw[FAULT_EVENTS]]
    return data


def _measurements(msgs: list) -> Measurements:
    order = np.argsort([int(m.sample_index) for m in msgs], kind="stable")
    msgs = [msgs[i] for i in order]
    stamp_ns = np.array([_ns(m.header.stamp) for m in msgs], dtype=np.int64)
    return Measurements(
        sample_index=np.array([int(m.sample_index) for m in msgs], dtype=np.int64),
        stamp_ns=stamp_ns,
        time=np.array([_seconds(m.header.stamp) for m in msgs]),
        displacement=np.array([m.displacement for m in msgs], dtype=float).reshape(-1, 8),
        current=np.array([m.current for m in msgs], dtype=float).reshape(-1, 4),
        bearing_force=np.array([m.bearing_force for m in msgs], dtype=float).reshape(-1, 4),
        wavelet_force=np.array([m.wavelet_force for m in msgs], dtype=float).reshape(-1, 4),
        rotor_speed=np.array([m.rotor_speed for m in msgs], dtype=float),
        rotor_angle=np.array([m.rotor_angle for m in msgs], dtype=float),
        status=np.array([int(m.status) for m in msgs], dtype=np.int64),
        samples_per_rev=int(msgs[0].samples_per_rev),
    )


def _stamp_map(meas: Measurements | None, coefficient_msgs: list):
    if meas is not None:
        return meas.sample_index.astype(float), meas.time
    if coefficient_msgs:
        idx = np.array([int(m.sample_index) for m in coefficient_msgs], dtype=float)
        t = np.array([_seconds(m.header.stamp) for m in coefficient_msgs])
        order = np.argsort(idx, kind="stable")
        return idx[order], t[order]
    return None


def _coefficients(msgs: list, samples_per_rev: int, last_sample: int | None):
    j1 = samples_per_rev.bit_length() - 1
    n_period = int(msgs[0].samples_per_period) or samples_per_rev
    wavelet = str(msgs[0].wavelet)
    one_x: dict[int, dict[int, np.ndarray]] = {}  # period -> quadrature -> values (last wins)
    levels: dict[int, dict] = {}
    for m in msgs:
        n = int(m.sample_index)
        for s in m.sets:
            if s.kind != KIND_DETAIL or s.frame != FRAME_FIXED:
                continue
            values = np.asarray(s.values, dtype=float)
            if s.level == j1 and s.quadrature in (QUADRATURE_EVEN, QUADRATURE_ODD):
                one_x.setdefault(n // n_period, {})[int(s.quadrature)] = values
            if s.quadrature == QUADRATURE_EVEN:
                lv = levels.setdefault(int(s.level), {"n": [], "v": [], "f": 0.0})
                lv["n"].append(n)
                lv["v"].append(values)
                lv["f"] = float(s.pseudo_frequency)
    series = {
        j: LevelSeries(j, np.array(lv["n"], dtype=np.int64), np.array(lv["v"]), lv["f"])
        for j, lv in sorted(levels.items())
    }
    if not one_x:
        return None, series
    last = last_sample if last_sample is not None else max(int(m.sample_index) for m in msgs)
    n_periods = last // n_period + 1
    even = np.zeros((n_periods, 8))
    odd = np.zeros((n_periods, 8))
    present = np.zeros(n_periods, dtype=bool)
    for k, quads in one_x.items():
        if k >= n_periods:
            continue
        even[k] = quads.get(QUADRATURE_EVEN, 0.0)
        odd[k] = quads.get(QUADRATURE_ODD, 0.0)
        present[k] = True
    return OneXCoefficients(wavelet, j1, n_period, even, odd, present), series


def _commands(msgs: list) -> Commands:
    msgs = sorted(msgs, key=lambda m: int(m.period_index))
    n = int(msgs[0].samples_per_period)
    force = np.array(
        [np.asarray(m.force, dtype=float).reshape(4, n) for m in msgs if len(m.force) == 4 * n]
    )
    msgs = [m for m in msgs if len(m.force) == 4 * n]
    return Commands(
        period_index=np.array([int(m.period_index) for m in msgs], dtype=np.int64),
        start_sample_index=np.array([int(m.start_sample_index) for m in msgs], dtype=np.int64),
        force=force.reshape(len(msgs), 4, n),
        hold=np.array([bool(m.hold) for m in msgs]),
        wavelet=str(msgs[0].wavelet),
        delay_periods=int(msgs[0].delay_periods),
    )


def _fault_event(msg, data: BagData) -> dict:
    """Return a ``FaultEvent`` message as the fault monitor's ``to_dict`` mapping.

    ``decision_sample_index`` (the sample at which the event was emitted) is not a message
    field: it is the sample whose stamp equals the header stamp, when ``/amb/measurement``
    holds one (else ``None``). Evidence values, strings in the message, are parsed back to
    numbers where they are numbers.
    """
    decision = None
    meas = data.measurements
    if meas is not None:
        hit = np.flatnonzero(meas.stamp_ns == _ns(msg.header.stamp))
        if hit.size:
            decision = int(meas.sample_index[hit[0]])
    return {
        "fault_type": FAULT_TYPE_NAMES.get(int(msg.fault_type), f"CODE_{int(msg.fault_type)}"),
        "onset_sample_index": int(msg.onset_sample_index),
        "detection_sample_index": int(msg.detection_sample_index),
        "decision_sample_index": decision,
        "samples_per_rev": data.samples_per_rev,
        "omega": float(msg.rotor_speed),
        "plane": int(msg.plane),
        "channel": int(msg.channel),
        "bearing": int(msg.bearing),
        "severity": float(msg.severity),
        "confidence": float(msg.confidence),
        "count": int(msg.count),
        "evidence": {kv.key: _parse_evidence_value(kv.value) for kv in msg.evidence},
        "description": str(msg.description),
        "event_id": int(msg.event_id),
        "fault_type_code": int(msg.fault_type),
    }
