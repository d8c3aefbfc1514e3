"""fault_monitor node over real DDS: bad parameters and bad messages are refused, counted, reported.

Issue 8 for the fault monitor. Start-up: every invalid value stops the process with exit status
2 and a message naming the parameter, the value and the allowed range. Run time: a refused
change returns ``successful=False`` with the reason and the old value stays; an accepted one is
applied (the trip level follows ``trip_1x_fraction`` in proportion, a closed form that needs no
rig number). Messages: a hand-built stream with known bad messages inserted (NaN, zero speed,
wrong ``samples_per_rev``, unknown codes, wrong set lengths, repeats, strays forward and back,
stamps from the future) must leave exactly the counts inserted on ``/diagnostics``, no trip
from the huge displacements the refused messages carry, and every valid message processed.
"""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest
from amb_msgs.msg import FaultEvent, Measurement, WaveletCoefficients
from diagnostic_msgs.msg import DiagnosticArray
from reliability_helpers import Diagnostics, get_parameter, set_parameters
from ros_harness import configuration_refusals

from amb_tools.conversions import to_float_array
from amb_tools.streams import FRAME_CODES, QUAD_CODES
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.messages import coefficients_msg

pytestmark = pytest.mark.ros

SPR = 16
HZ = 20.0
OMEGA = 2 * math.pi * HZ
FS = SPR * HZ
AMPLITUDE = 1e-5  # m per channel of the valid stream
HUGE = 0.05  # m: far over any trip level (the rig's clearances are below 1 mm)
SLOTS = [(FRAME_CODES[f], QUAD_CODES[q]) for f in FRAMES for q in QUADRATURES]


def _stamp(msg, t: float) -> None:
    msg.header.stamp.sec, msg.header.stamp.nanosec = divmod(round(t * 1e9), 1_000_000_000)


def _stream(first: int, n: int) -> list[tuple[Measurement, WaveletCoefficients | None]]:
    """A valid measurement stream and the filterbank's coefficient messages (reset at first)."""
    front = ChannelFrontEnd(SPR)
    bank = AnalysisFilterbank("haar", 5, front.n_channels)
    bank.reset(start_sample_index=first)
    out = []
    for i in range(first, first + n):
        angle = 2 * np.pi * (i % SPR) / SPR
        m = Measurement(sample_index=i, samples_per_rev=SPR, rotor_angle=angle, rotor_speed=OMEGA)
        m.displacement = AMPLITUDE * np.cos(angle + np.arange(8))
        _stamp(m, i / FS)
        records = bank.step(front.step(m.displacement, angle), i)
        c = (
            coefficients_msg(m.header, "haar", SPR, SPR, i, OMEGA, records, SLOTS)
            if records
            else None
        )
        out.append((m, c))
    return out


def _copy_measurement(m: Measurement, **fields) -> Measurement:
    """A deep copy (header included: a shallow one would share the stamp) with some fields set."""
    c = copy.deepcopy(m)
    for k, v in fields.items():
        setattr(c, k, v)
    return c


# ---------------------------------------------------------------------------------- start-up
@pytest.fixture(scope="module")
def bad_files(tmp_path_factory):
    folder = tmp_path_factory.mktemp("bad")
    (folder / "rig.yaml").write_text("amb: [unclosed\n")
    (folder / "events.jsonl").write_text('{"fault_type": "NOT_A_FAULT"}\n')
    return folder


STARTUP_CASES = [
    # (parameters, words the message must contain: parameter, value, range or rule)
    ({"samples_per_rev": 24}, ("'samples_per_rev'", "24", "power of two")),
    ({"k": 500.0}, ("'k'", "500.0", "1..100")),
    ({"k": 5}, ("'k'", "'5'", "DOUBLE")),  # an integer for a double: Jazzy refuses it
    ({"levels": [9]}, ("'levels'", "[9]", "1..7")),  # samples_per_rev 32: 1 .. log2(32) + 2
    ({"frames": ["fixed", "spinning"]}, ("'frames'", "spinning", "'rotating'")),
    ({"decision_max_revs": 4.0}, ("decision_max_revs", "4.0", ">= decision_revs")),
    ({"control_step": 0.0}, ("'control_step'", "0.0", "0.001..100000")),
    ({"tail_rise_median": 0.5}, ("'tail_rise_median'", "0.5", "1..100")),
    ({"rig": "/nonexistent/rig.yaml"}, ("'rig'", "/nonexistent/rig.yaml", "not found")),
    ({"rig": "{bad}/rig.yaml"}, ("'rig'", "rig.yaml", "flow")),
    ({"event_log": "{bad}/events.jsonl"}, ("'event_log'", "events.jsonl", ":1")),
    ({"blackbox_dir": "/proc/none"}, ("'blackbox_dir'", "/proc/none", "No such file")),
]


@pytest.mark.slow
def test_invalid_start_up_values_exit_2_naming_parameter_value_and_range(
    node_process, bad_files
) -> None:
    """All cases are started at once (start-up dominates the wall time), then checked."""
    procs = []
    for params, words in STARTUP_CASES:
        params = {
            k: v.format(bad=bad_files) if isinstance(v, str) else v for k, v in params.items()
        }
        procs.append((params, words, node_process("fault_monitor", params=params)))
    failures = configuration_refusals([(str(params), proc, words) for params, words, proc in procs])
    assert not failures, "\n".join(failures)


# ---------------------------------------------------------------------------------- run time
@pytest.mark.slow
def test_run_time_changes_are_checked_kept_or_applied(ros, node_process) -> None:
    fm = node_process("fault_monitor", params={"samples_per_rev": SPR, "status_period": 0.1})
    node = ros.node("amb_test_fm_params")
    diag = Diagnostics(node)
    reports: list[DiagnosticArray] = []
    node.create_subscription(
        DiagnosticArray,
        "/diagnostics",
        lambda m: reports.append(m) if any(s.name == "fault_monitor" for s in m.status) else None,
        10,
    )
    target = "fault_monitor"

    def plane_level(key: str) -> float:
        return float(diag.get("fault_monitor: plane 1", key, "nan"))

    assert ros.spin_until(lambda: not math.isnan(plane_level("trip_1x_level_m")), 30.0), fm.log()
    level_half = plane_level("trip_1x_level_m")  # trip_1x_fraction 0.5 of the clearance
    for name, value, words in (
        ("trip_hysteresis", 1.5, ("trip_hysteresis", "1.5", "0.99")),
        ("trip_hysteresis", math.nan, ("trip_hysteresis", "nan", "0.99")),
        ("trip_1x", -1e-6, ("trip_1x", "-1e-06", "Min: 0.0")),
        ("trip_1x_fraction", math.inf, ("trip_1x_fraction", "inf", "Max: 1.0")),
        ("status_period", 0.0, ("status_period", "0.0", "0.05")),
        ("control_step", math.inf, ("control_step", "inf", "Max: 100000.0")),
        ("tail_rise_median", 4.0, ("tail_rise_median", "read-only")),
        ("k", 10.0, ("k", "read-only")),
    ):
        (result,) = set_parameters(ros, node, target, {name: value})
        assert not result.successful, (name, value)
        assert all(w in result.reason for w in words), (name, value, result.reason)
    assert get_parameter(ros, node, target, "trip_hysteresis") == 0.1  # old values kept
    assert get_parameter(ros, node, target, "trip_1x_fraction") == 0.5
    assert get_parameter(ros, node, target, "k") == 8.0
    assert plane_level("trip_1x_level_m") == level_half
    # accepted: the default 1 x level is the fraction of the clearance, so it halves
    (ok,) = set_parameters(ros, node, target, {"trip_1x_fraction": 0.25})
    assert ok.successful, ok.reason
    assert ros.spin_until(lambda: plane_level("trip_1x_level_m") != level_half, 10.0)
    assert plane_level("trip_1x_level_m") == pytest.approx(level_half / 2, rel=1e-5)
    (ok,) = set_parameters(ros, node, target, {"control_step": 5.0})
    assert ok.successful, ok.reason
    assert ros.spin_until(lambda: diag.get(target, "control_step_n") == "5.0", 10.0), diag.values
    (ok,) = set_parameters(ros, node, target, {"trip_displacement": 3e-4})
    assert ok.successful, ok.reason
    assert ros.spin_until(lambda: plane_level("trip_level_m") == 3e-4, 10.0), diag.values
    # status_period applied: from 0.1 s to 2 s, so at most 3 reports in 4.5 s (not ~45)
    (ok,) = set_parameters(ros, node, target, {"status_period": 2.0})
    assert ok.successful, ok.reason
    before = len(reports)
    ros.spin_for(4.5)
    assert 1 <= len(reports) - before <= 3, len(reports) - before
    assert fm.returncode is None, fm.log()


# ---------------------------------------------------------------------------------- messages
def test_bad_messages_are_rejected_counted_and_never_reach_the_monitor(ros, node_process) -> None:
    fm = node_process("fault_monitor", params={"samples_per_rev": SPR, "status_period": 0.1})
    node = ros.node("amb_test_fm_messages")
    events: list[FaultEvent] = []
    node.create_subscription(FaultEvent, "/amb/fault/events", events.append, 100)
    diag = Diagnostics(node)
    pm, pc = ros.stream_writers(node, SPR, fm)
    assert ros.spin_until(lambda: diag.values, 30.0), fm.log()
    name = "fault_monitor"
    n = 4 * SPR
    stream = _stream(0, n)
    after = _stream(n + 40, SPR)  # a confirmed gap of 40 samples (filterbank reset there)

    # measurements: what each inserted message must add to which counter
    meas = []
    expected_meas = {"measurements_rejected": 2, "samples_repeat": 1, "samples_stray": 2}
    expected_meas |= {"samples_stamp": 1, "samples_gap": 1, "samples_restart": 0}
    for m, _ in stream:
        i = m.sample_index
        if i == 11:  # NaN and zero speed: check_measurement
            meas.append(_copy_measurement(m, displacement=np.full(8, np.nan)))
            meas.append(_copy_measurement(m, rotor_speed=0.0, displacement=np.full(8, HUGE)))
        if i == 31:  # a stray far ahead, carrying a huge displacement
            meas.append(_copy_measurement(m, sample_index=10**12, displacement=np.full(8, HUGE)))
        if i == 41:  # the next index stamped 10 s ahead: from the future
            bad = _copy_measurement(m, displacement=np.full(8, HUGE))
            _stamp(bad, i / FS + 10.0)
            meas.append(bad)
        if i == 51:  # a step back, not confirmed by the next sample
            meas.append(_copy_measurement(stream[45][0], displacement=np.full(8, HUGE)))
        meas.append(m)
        if i == 20:
            meas.append(_copy_measurement(m))  # repeated
    meas += [m for m, _ in after]
    for m in meas:
        pm.publish(m)
    assert ros.spin_until(lambda: diag.number(name, "samples_gap") == 1, 20.0), (
        diag.values.get(name),
        fm.log(),
    )

    coef = []
    valid = [c for _, c in stream if c is not None]
    valid_after = [c for _, c in after if c is not None]
    expected_coef = {"coefficients_rejected": 4, "coefficients_repeat": 1}
    expected_coef |= {"coefficients_stray": 1, "coefficients_stamp": 1, "coefficients_gap": 1}
    for k, c in enumerate(valid):
        if k == 5:
            nan = copy.deepcopy(c)
            nan.sets[-1].values = to_float_array(np.array([0.0] * 7 + [np.inf]))
            frame = copy.deepcopy(c)
            frame.sets[0].frame = 7
            spr = copy.deepcopy(c)
            spr.samples_per_rev = 2 * SPR
            short = copy.deepcopy(c)
            short.sets[0].values = to_float_array(np.zeros(9))
            coef += [nan, frame, spr, short]
        if k == 10:
            stray = copy.deepcopy(c)
            stray.sample_index = c.sample_index + 1000
            for s in stray.sets:
                s.last_sample_index = stray.sample_index
            coef.append(stray)
        if k == 15:
            future = copy.deepcopy(c)
            _stamp(future, c.sample_index / FS + 10.0)
            coef.append(future)
        coef.append(c)
        if k == 20:
            coef.append(copy.deepcopy(c))  # repeated
    coef += valid_after
    for c in coef:
        pc.publish(c)
    total = len(valid) + len(valid_after)
    assert ros.spin_until(lambda: diag.number(name, "messages") == total, 20.0), (
        diag.values.get(name),
        fm.log(),
    )
    ros.spin_for(0.3)
    counts = {k: diag.number(name, k) for k in expected_meas | expected_coef}
    assert counts == expected_meas | expected_coef, diag.values
    assert diag.number(name, "restarts") == 1  # the confirmed gap only, not the strays
    assert diag.get(name, "callback_errors") == "0", fm.log()
    # nothing refused reached the trips: the peak is the valid stream's radius
    peak = float(diag.get("fault_monitor: plane 1", "peak_displacement_m"))
    radius = max(math.hypot(m.displacement[0], m.displacement[1]) for m, _ in stream)
    assert peak == pytest.approx(radius, rel=1e-5), diag.values
    assert not [e for e in events if e.fault_type == FaultEvent.TRIP], events
    assert fm.returncode is None, fm.log()
