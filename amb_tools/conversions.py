"""The one place where numpy arrays become ``amb_msgs`` messages and back.

Generated messages hold ``float64[N]`` fields as numpy arrays and ``float64[]`` fields as
``array.array('d')``. Filling a ``float64[]`` from ``array.array('d', x.tobytes())`` is one
copy; assigning a numpy array converts it element by element, far slower
(docs/results.md#msg-arrays), so every conversion goes through :func:`to_float_array`.
Readers use :func:`from_float_array` (``np.frombuffer``, no copy). Checks here raise
:class:`MessageError` (a ``ValueError``) with the field, the expected and the actual value, so
a node can count and report a bad message instead of propagating it. The wavelet coefficient
messages (filterbank records in and out) are the wavelet part's: :mod:`amb_wavelet.messages`.
"""

from __future__ import annotations

from array import array

import numpy as np
from amb_msgs.msg import (
    AxisCoefficients,
    CoefficientSet,
    ControlCommand,
    ControllerStatus,
    Measurement,
)
from builtin_interfaces.msg import Time

from amb_common.names import N_AXES
from amb_tools.cdr import measurement_cdr_block


class MessageError(ValueError):
    """A message field is malformed (length, value range, non-finite value)."""


def to_float_array(values: np.ndarray) -> array:
    """Return ``values`` as ``array('d')`` for a ``float64[]`` field (fast path)."""
    return array("d", np.ascontiguousarray(values, dtype=np.float64).tobytes())


def from_float_array(field: array | np.ndarray) -> np.ndarray:
    """Return a ``float64[]`` or ``float64[N]`` field as a read-only numpy view."""
    return np.frombuffer(field, dtype=np.float64) if isinstance(field, array) else field


def stamp(t: float) -> Time:
    """Return simulated time ``t`` (s, >= 0) as a ``builtin_interfaces/Time``."""
    ns = round(t * 1e9)
    return Time(sec=ns // 1_000_000_000, nanosec=ns % 1_000_000_000)


def stamp_seconds(msg_stamp: Time) -> float:
    """Return a ``builtin_interfaces/Time`` in s."""
    return msg_stamp.sec + msg_stamp.nanosec * 1e-9


def check_finite(name: str, values: np.ndarray) -> np.ndarray:
    """Raise :class:`MessageError` unless every value is finite; return ``values``."""
    if not np.all(np.isfinite(values)):
        bad = int(np.count_nonzero(~np.isfinite(values)))
        raise MessageError(f"field '{name}' has {bad} non-finite value(s) (NaN or inf)")
    return values


def check_length(name: str, values: np.ndarray, expected: int) -> np.ndarray:
    """Raise :class:`MessageError` unless ``len(values) == expected``; return ``values``."""
    if len(values) != expected:
        raise MessageError(f"field '{name}' has {len(values)} values, expected {expected}")
    return values


# ---------------------------------------------------------------------------------------------
# Message builders shared by the nodes and the in-process runner (identical bytes in both bags)
# ---------------------------------------------------------------------------------------------


def measurement_msgs(
    block, wavelet_force: np.ndarray, status, samples_per_rev: int, force_limit: float
):
    """Build one ``Measurement`` per sample of a simulator block.

    Parameters
    ----------
    block : amb_plant_sim.simulator.MeasurementBlock
        ``n`` samples (only the measurable fields are used, never ``truth``).
    wavelet_force : numpy.ndarray
        ``(n, 4)`` N, the wavelet force applied in each sample.
    status : int or numpy.ndarray
        ``Measurement.STATUS_*`` flags for all samples, or ``(n,)`` per sample;
        ``STATUS_FORCE_SATURATED`` is added where a bearing force reaches ``force_limit``.
    samples_per_rev : int
        Samples per revolution.
    force_limit : float
        N, bearing capacity per axis.

    Returns
    -------
    list of amb_msgs.msg.Measurement
    """
    n = block.sample_index.size
    flags = np.broadcast_to(np.asarray(status, dtype=np.int64), (n,)).copy()
    saturated = np.any(np.abs(block.bearing_force) >= force_limit * (1 - 1e-9), axis=1)
    flags[saturated] |= Measurement.STATUS_FORCE_SATURATED
    out = []
    for s in range(n):
        m = Measurement()
        m.header.stamp = stamp(float(block.time[s]))
        m.header.frame_id = "amb_rig"
        m.sample_index = int(block.sample_index[s])
        m.samples_per_rev = samples_per_rev
        m.rotor_angle = float(block.angle[s])
        m.rotor_speed = float(block.omega[s])
        m.displacement = block.displacement[s]
        m.current = block.current[s]
        m.bearing_force = block.bearing_force[s]
        m.wavelet_force = wavelet_force[s]
        m.status = int(flags[s])
        out.append(m)
    return out


def measurement_bytes(
    block, wavelet_force: np.ndarray, status, samples_per_rev: int, force_limit: float
) -> tuple[list[bytes], np.ndarray]:
    """Serialise the ``Measurement`` messages of a block (what :func:`measurement_msgs` builds).

    The same fields, values and flags as :func:`measurement_msgs`, written as CDR bytes in a
    few numpy operations (:func:`amb_tools.cdr.measurement_cdr_block`) for
    ``Publisher.publish``.

    Parameters
    ----------
    block, wavelet_force, status, samples_per_rev, force_limit
        As :func:`measurement_msgs`.

    Returns
    -------
    messages : list of bytes
        One serialised ``Measurement`` per sample.
    flags : numpy.ndarray
        ``(n,)`` the ``status`` of each message (with ``STATUS_FORCE_SATURATED``).
    """
    n = block.sample_index.size
    flags = np.broadcast_to(np.asarray(status, dtype=np.int64), (n,)).copy()
    saturated = np.any(np.abs(block.bearing_force) >= force_limit * (1 - 1e-9), axis=1)
    flags[saturated] |= Measurement.STATUS_FORCE_SATURATED
    messages = measurement_cdr_block(
        sample_index=block.sample_index,
        time_ns=np.round(np.asarray(block.time, dtype=float) * 1e9).astype(np.int64),
        samples_per_rev=samples_per_rev,
        rotor_angle=block.angle,
        rotor_speed=block.omega,
        displacement=block.displacement,
        current=block.current,
        bearing_force=block.bearing_force,
        wavelet_force=wavelet_force,
        status=flags,
        frame_id="amb_rig",
    )
    return messages, flags


def command_msg(
    command,
    header,
    control_labels,
    samples_per_period: int,
    delay_periods: int,
    wavelet: str,
):
    """Build the ``ControlCommand`` of one controller command.

    Parameters
    ----------
    command : amb_controller.supervisor.Command
        Target period, based-on period, control coefficients (control-basis order) and
        force samples ``(4, samples_per_period)`` in N.
    header : std_msgs.msg.Header
        Header of the last measured sample the command is based on (the last sample of
        period ``based_on_period``): the command's stamp is that sample's stamp (simulated
        time in lockstep), so that it does not depend on how long the computation took.
    control_labels : sequence of str
        Label of each control coefficient, ``"p{p}/q{q}/{quad}/c{axis}"``
        (:func:`amb_controller.basis.control_basis`).
    samples_per_period : int
        Force samples per axis.
    delay_periods : int
        Evaluation delay ``i``.
    wavelet : str
        PyWavelets name of the control wavelet.

    Returns
    -------
    amb_msgs.msg.ControlCommand
        ``force[axis * samples_per_period + n]`` (axis-major); one ``AxisCoefficients`` per
        (axis, level p, quadrature) with the values over the translations ``q = 1, 2, ...``.

    Raises
    ------
    MessageError
        If the force has the wrong shape or a non-finite value.
    """
    force = np.asarray(command.force, dtype=float)
    if force.shape != (N_AXES, samples_per_period):
        raise MessageError(
            f"field 'force' has shape {force.shape}, expected ({N_AXES}, {samples_per_period})"
        )
    check_finite("force", force)
    coefficients = np.asarray(command.coefficients, dtype=float)
    check_length("coefficients", coefficients, len(control_labels))
    check_finite("coefficients", coefficients)
    quad_codes = {"even": CoefficientSet.QUADRATURE_EVEN, "odd": CoefficientSet.QUADRATURE_ODD}
    groups: dict[tuple[int, int, int], list[tuple[int, float]]] = {}
    for label, value in zip(control_labels, coefficients, strict=True):
        p, q, quad, axis = label.split("/")
        key = (int(axis[1:]), int(p[1:]), quad_codes[quad])
        groups.setdefault(key, []).append((int(q[1:]), float(value)))
    axis_sets = [
        AxisCoefficients(
            axis=axis,
            level=level,
            quadrature=quad,
            values=to_float_array(np.array([v for _, v in sorted(items)])),
        )
        for (axis, level, quad), items in sorted(groups.items())
    ]
    return ControlCommand(
        header=header,
        period_index=int(command.target_period),
        start_sample_index=int(command.target_period) * samples_per_period,
        samples_per_period=samples_per_period,
        delay_periods=int(delay_periods),
        based_on_period=int(command.based_on_period),
        wavelet=wavelet,
        coefficients=axis_sets,
        force=to_float_array(force.ravel()),
        hold=bool(command.hold),
    )


def controller_status_msg(status: dict, header):
    """Build a ``ControllerStatus`` from ``ControllerPipeline.status()``.

    Parameters
    ----------
    status : dict
        Keys as the message fields (``mode``, ``controller``, ``period_index``,
        ``delay_periods``, ``compute_time`` s, ``peak_wavelet_force`` (4,) N, ``saturated``,
        ``guard_tripped``, ``identification_progress``, ``commands_sent``, ``commands_late``,
        ``inputs_rejected``, ``model_file``, ``message``).
    header : std_msgs.msg.Header
        Stamp: the last measured sample the status refers to (as its command).

    Returns
    -------
    amb_msgs.msg.ControllerStatus
    """
    peak = check_length(
        "peak_wavelet_force", np.asarray(status["peak_wavelet_force"], dtype=float), N_AXES
    )
    return ControllerStatus(
        header=header,
        mode=int(status["mode"]),
        controller=str(status["controller"]),
        period_index=int(status["period_index"]),
        delay_periods=int(status["delay_periods"]),
        compute_time=float(status["compute_time"]),
        peak_wavelet_force=check_finite("peak_wavelet_force", peak),
        saturated=bool(status["saturated"]),
        guard_tripped=bool(status["guard_tripped"]),
        identification_progress=float(status["identification_progress"]),
        commands_sent=int(status["commands_sent"]),
        commands_late=int(status["commands_late"]),
        inputs_rejected=int(status["inputs_rejected"]),
        model_file=str(status["model_file"]),
        message=str(status["message"]),
    )
