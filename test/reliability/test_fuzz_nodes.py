"""Property tests over real DDS: random and garbled messages never stop a node or leak a NaN.

Each test starts the node as its own process (as ``ros2 run``), throws hypothesis-generated
messages at it (typed messages with random indices, stamps, sizes, NaN/inf/huge values, and
raw CDR bytes truncated or corrupted, published with ``publish(bytes)``), then checks that the
process is still running, that every message it published is finite (and, for forces, within
the force limit), that ``/diagnostics`` counts the rejections with no callback error, and that
a valid stream afterwards is processed normally (the node recovered without a restart).
"""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import yaml
from amb_msgs.msg import ControlCommand, Measurement, WaveletCoefficients
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from rclpy.serialization import serialize_message
from reliability_helpers import Diagnostics

from amb_common.rig import load_rig
from amb_tools.conversions import from_float_array, to_float_array
from amb_tools.streams import COMMAND_QOS, FRAME_CODES, QUAD_CODES, stream_qos
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.messages import coefficients_msg

pytestmark = [pytest.mark.ros, pytest.mark.slow]

SPR = 16
HZ = 20.0
OMEGA = 2 * math.pi * HZ
EXAMPLES = 25
FUZZ = settings(
    max_examples=EXAMPLES,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
    database=None,
)

any_float = st.floats(allow_nan=True, allow_infinity=True)
small_float = st.floats(-1e-3, 1e-3)
index = st.one_of(st.integers(0, 2**63 - 1), st.integers(0, 4 * SPR))


@st.composite
def measurements(draw) -> Measurement:
    m = Measurement(sample_index=draw(index))
    m.samples_per_rev = draw(st.sampled_from([SPR, SPR, 0, 7, 2**32 - 1]))
    m.rotor_angle = draw(st.one_of(st.floats(0.0, 6.28), any_float))
    m.rotor_speed = draw(st.one_of(st.just(OMEGA), any_float))
    m.displacement = np.array(
        draw(st.lists(st.one_of(small_float, any_float), min_size=8, max_size=8))
    )
    m.current = np.array(draw(st.lists(st.one_of(small_float, any_float), min_size=4, max_size=4)))
    m.header.stamp.sec = draw(st.integers(0, 2**31 - 1))
    m.header.stamp.nanosec = draw(st.integers(0, 999_999_999))
    return m


def garble(data: bytes, how: int, where: int, byte: int) -> bytes:
    """Truncate, corrupt one byte, or append garbage to serialized bytes."""
    where %= max(len(data), 1)
    if how == 0:
        return data[:where]
    if how == 1:
        return data[:where] + bytes([byte]) + data[where + 1 :]
    return data + bytes([byte]) * where


garbling = st.tuples(st.integers(0, 2), st.integers(0, 10_000), st.integers(0, 255))


def valid_stream(first: int, n: int, wavelet: str = "haar", levels: int = 5):
    """Measurements (with stamps n / fs) and the filterbank's coefficient messages."""
    front = ChannelFrontEnd(SPR)
    bank = AnalysisFilterbank(wavelet, levels, front.n_channels)
    bank.reset(start_sample_index=first)
    slots = [(FRAME_CODES[f], QUAD_CODES[q]) for f in FRAMES for q in QUADRATURES]
    fs = SPR * HZ
    out = []
    for i in range(first, first + n):
        angle = 2 * np.pi * (i % SPR) / SPR
        m = Measurement(sample_index=i, samples_per_rev=SPR, rotor_angle=angle, rotor_speed=OMEGA)
        m.displacement = 1e-5 * np.array([np.cos(angle + c) for c in range(8)])
        ns = round(i / fs * 1e9)
        m.header.stamp.sec, m.header.stamp.nanosec = divmod(ns, 1_000_000_000)
        records = bank.step(front.step(m.displacement, angle), i)
        c = None
        if records:
            c = coefficients_msg(m.header, wavelet, SPR, SPR, i, m.rotor_speed, records, slots)
        out.append((m, c))
    return out


def _all_finite_coefficients(msgs) -> bool:
    return all(np.all(np.isfinite(from_float_array(s.values))) for c in msgs for s in c.sets)


def throw_until_taken_in(ros, throw, taken_in, renew, proc) -> None:
    """
    Run the fuzz ``throw()`` until the node under test takes in at least one of its messages.

    From a writer the transport sometimes delivered nothing at all (issue 17; the fuzz writers'
    messages in about 1 of 4-8 runs on a loaded machine, once all of a fuzz run in a fresh-clone
    CI run: the node idle, every counter 0). What this module tests is what a node does with
    the messages that reach it, so when ``taken_in()`` (the node's counters of everything it took
    in, from ``/diagnostics``) has not moved 10 s after a fuzz run, ``renew()`` makes new writers
    and the fuzz runs again, three times at most; then the test is an expected failure of
    issue 17, with the node's log.
    """
    start = taken_in()
    for attempt in range(3):
        throw()
        if ros.spin_until(lambda: taken_in() > start, 10.0):
            return
        print(f"fuzz run {attempt + 1}: the node took in none of it; again from new writers")
        renew()
    pytest.xfail(f"issue 17: none of three fuzz runs reached the node\n{proc.log()}")


def test_filterbank_survives_random_and_garbled_measurements(ros, node_process) -> None:
    fb = node_process(
        "wavelet_filterbank", params={"samples_per_rev": SPR, "levels": 5, "status_period": 0.1}
    )
    node = ros.node("amb_fuzz_fb")
    qos = stream_qos(SPR)
    pub = node.create_publisher(Measurement, "/amb/measurement", qos)
    got: list[WaveletCoefficients] = []
    node.create_subscription(WaveletCoefficients, "/amb/wavelet/coefficients", got.append, qos)
    diag = Diagnostics(node)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 30.0), fb.log()
    sent = {"typed": 0, "raw": 0}

    @FUZZ
    @given(
        batch=st.lists(measurements(), min_size=1, max_size=8), raw=st.lists(garbling, max_size=3)
    )
    def throw(batch, raw) -> None:
        for m in batch:
            pub.publish(m)
            sent["typed"] += 1
        for how, where, byte in raw:
            pub.publish(garble(serialize_message(batch[0]), how, where, byte))
            sent["raw"] += 1
        ros.spin_for(0.02)

    keys = ("samples", "rejected", "stray_dropped", "stamp_rejected", "repeats_dropped")

    def taken_in() -> int:
        return sum(diag.number("wavelet_filterbank", k) for k in keys)

    def renew() -> None:
        nonlocal pub
        pub = node.create_publisher(Measurement, "/amb/measurement", qos)
        assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 30.0), fb.log()

    throw_until_taken_in(ros, throw, taken_in, renew, fb)
    # Let the node work off the fuzz burst before the valid stream follows: with a fixed 1 s
    # pause the valid burst was lost in about 1 of 4 runs on a loaded machine (the node still
    # busy with the burst). Quiescence: the node's counters of everything it took in
    # (accepted, rejected, dropped) unchanged over 1 s of its 0.1 s status reports.
    seen = (-1, time.monotonic())
    deadline = time.monotonic() + 60.0
    while time.monotonic() < deadline:
        ros.spin_for(0.2)
        now = taken_in()
        if now != seen[0]:
            seen = (now, time.monotonic())
        elif time.monotonic() - seen[1] >= 1.0:
            break
    before = {k: diag.number("wavelet_filterbank", k) for k in keys}
    # The valid stream comes from a new writer. From the fuzz writer it was not delivered at all
    # in about 1 of 4-8 runs (the node idle, its counters still, before == after in the failure
    # message), with the EventsExecutor and the single-threaded one alike: what the node does
    # with messages that reach it is what this test checks.
    pub = node.create_publisher(Measurement, "/amb/measurement", qos)
    assert ros.spin_until(lambda: pub.get_subscription_count() > 0, 30.0), fb.log()
    stream = valid_stream(10_000, 4 * SPR)
    for m, _ in stream:
        pub.publish(m)
    last = stream[-1][0].sample_index
    if not ros.spin_until(lambda: any(c.sample_index == last for c in got), 20.0):
        pytest.fail(
            f"valid stream not processed: before it {before}, after {diag.values} "
            f"{fb.returncode}\n{fb.log()}"
        )
    ros.spin_for(0.3)
    assert fb.returncode is None, fb.log()
    assert _all_finite_coefficients(got)
    rejected = sum(
        diag.number("wavelet_filterbank", k)
        for k in ("rejected", "stray_dropped", "stamp_rejected", "repeats_dropped")
    )
    assert rejected > 0, diag.values
    assert diag.get("wavelet_filterbank", "callback_errors") == "0", fb.log()
    # the valid stream after the garbage: coefficients for its odd samples, from a reset
    mine = [c for c in got if 10_000 <= c.sample_index <= last]
    assert [c.sample_index for c in mine] == list(range(10_001, last + 1, 2))


@st.composite
def commands(draw) -> ControlCommand:
    k = draw(st.one_of(st.integers(-5, 60), st.integers(-(2**63), 2**63 - 1)))
    c = ControlCommand(period_index=k, delay_periods=draw(st.sampled_from([2, 2, 2, 0, 1, 3])))
    c.samples_per_period = draw(st.sampled_from([SPR, SPR, SPR, 0, 3]))
    start = k * SPR if -(2**63) <= k * SPR < 2**64 and k >= 0 else 0
    c.start_sample_index = draw(st.sampled_from([start, start, 0, 5]))
    c.based_on_period = draw(st.integers(0, 2**64 - 1) | st.integers(0, 60))
    size = draw(st.sampled_from([4 * SPR, 4 * SPR, 0, 4 * SPR - 1, 4 * SPR + 3]))
    values = draw(
        st.lists(st.one_of(st.floats(-5e3, 5e3), any_float), min_size=size, max_size=size)
    )
    c.force = to_float_array(np.array(values, dtype=float))
    c.header.stamp.sec = draw(st.integers(0, 2) | st.integers(0, 2**31 - 1))
    return c


def test_plant_survives_random_and_garbled_commands(ros, node_process, tmp_path) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(
        yaml.safe_dump(
            {
                "name": "fuzz",
                "speed": {"hz": HZ},
                "duration": 3.0,
                "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3}],
            }
        )
    )
    plant = node_process(
        "plant_sim",
        params={
            "scenario_file": str(scenario),
            "samples_per_rev": SPR,
            "command_timeout": 0.05,
            "status_period": 0.1,
        },
    )
    node = ros.node("amb_fuzz_plant")
    pub = node.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
    samples: list[Measurement] = []
    node.create_subscription(Measurement, "/amb/measurement", samples.append, stream_qos(SPR))
    diag = Diagnostics(node)
    assert ros.spin_until(lambda: len(samples) > 0, 30.0)
    limit = load_rig().amb.force_limit  # the default wavelet_force_limit

    # Well-formed commands, by the message definition (not by the plant's own check): the only
    # source a non-zero wavelet force may come from. period -> forces (SPR, 4) sent for it (the
    # message is axis-major: all samples of b1x, then b1y, ...).
    wellformed: dict[int, list[np.ndarray]] = {}

    @FUZZ
    @given(batch=st.lists(commands(), min_size=1, max_size=6), raw=st.lists(garbling, max_size=3))
    def throw(batch, raw) -> None:
        # one well-formed command for a period still ahead, so that forces are applied and the
        # check below has something to check: +-150 N, and one sample at twice the limit (to
        # be clipped). Held +-1000 N on every axis, as this once sent, throws the rotor onto
        # its retainers, whose contact the plant integrates step by step at 45-100 ms per
        # sample: 15-30 x slower than real time, and past the old 60 s wait on a slower CPU.
        k = (samples[-1].sample_index // SPR if samples else 0) + 3
        good = ControlCommand(period_index=k, samples_per_period=SPR, start_sample_index=k * SPR)
        good.delay_periods = 2  # the plant's default
        good.based_on_period = k - 2
        force = np.linspace(-150.0, 150.0, 4 * SPR)
        force[SPR // 2] = 2.0 * limit
        good.force = to_float_array(force)
        for c in [good, *batch]:
            force = np.asarray(c.force, dtype=float)
            if (
                c.samples_per_period == SPR
                and force.size == 4 * SPR
                and np.all(np.isfinite(force))
                and c.start_sample_index == c.period_index * SPR
                and c.delay_periods == 2
            ):
                wellformed.setdefault(int(c.period_index), []).append(force.reshape(4, SPR).T)
            pub.publish(c)
        for how, where, byte in raw:
            pub.publish(garble(serialize_message(batch[0]), how, where, byte))
        ros.spin_for(0.02)

    throw()
    # the random well-formed commands may still reach the retainers (slow contact steps): wait
    # for the end as long as samples keep coming
    assert ros.spin_until_progress(lambda: plant.returncode is not None, lambda: len(samples))
    assert plant.returncode == 0
    ros.spin_for(0.3)
    n = round(3.0 * HZ) * SPR
    assert [m.sample_index for m in samples] == list(range(n)), "samples lost or repeated"
    for m in samples:
        assert np.all(np.isfinite(m.displacement)) and np.all(np.isfinite(m.wavelet_force))
        assert np.all(np.abs(m.wavelet_force) <= limit)
    # Random well-formed commands at the force limit may shake the rotor into its retainers
    # (0.97 mm once, in a fresh-clone run): a displacement bound is not this test's property.
    # What is: no force that a well-formed command for that period did not ask for (clipped
    # to the limit; the bearing's own saturation may only reduce it).
    for m in samples:
        applied = np.asarray(m.wavelet_force, dtype=float)
        if not np.any(applied):
            continue
        k, j = divmod(int(m.sample_index), SPR)
        rows = [np.clip(f[j], -limit, limit) for f in wellformed.get(k, [])]
        assert any(
            np.all(np.abs(applied) <= np.abs(r) + 1e-9) and np.all(applied * r >= 0) for r in rows
        ), f"sample {m.sample_index}: force {applied} not asked for by a well-formed command"
    assert any(np.any(m.wavelet_force) for m in samples), "no command was ever applied"
    assert diag.number("plant_sim", "rejected") + diag.number("plant_sim", "late") > 0
    assert diag.get("plant_sim", "callback_errors") == "0", plant.log()


@st.composite
def coefficient_messages(draw) -> WaveletCoefficients:
    (_m, c) = valid_stream(draw(st.integers(0, 3)) * 2 + 1, 1)[0]
    c = c or WaveletCoefficients()
    c.sample_index = draw(index)
    c.wavelet = draw(st.sampled_from(["haar", "haar", "db2", ""]))
    c.samples_per_rev = draw(st.sampled_from([SPR, SPR, 8]))
    for s in c.sets:
        size = draw(st.sampled_from([8, 8, 8, 0, 9]))
        s.values = to_float_array(
            np.array(
                draw(st.lists(st.one_of(small_float, any_float), min_size=size, max_size=size))
            )
        )
        s.level = draw(st.sampled_from([s.level, s.level, 0, 9, 255]))
        s.translation_index = draw(st.sampled_from([s.translation_index, 2**62, -3]))
    return c


def test_controller_survives_random_measurements_and_coefficients(ros, node_process) -> None:
    ctrl = node_process(
        "wavelet_controller",
        params={"samples_per_rev": SPR, "coefficient_timeout": 0.2, "status_period": 0.1},
    )
    node = ros.node("amb_fuzz_ctrl")
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    got: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", got.append, COMMAND_QOS)
    diag = Diagnostics(node)

    @FUZZ
    @given(
        ms=st.lists(measurements(), max_size=6),
        cs=st.lists(coefficient_messages(), max_size=4),
        raw=st.lists(garbling, max_size=2),
    )
    def throw(ms, cs, raw) -> None:
        for m in ms:
            pm.publish(m)
        for c in cs:
            pc.publish(c)
        for how, where, byte in raw:
            pc.publish(
                garble(serialize_message(WaveletCoefficients(wavelet="haar")), how, where, byte)
            )
        ros.spin_for(0.02)

    name = "wavelet_controller"
    counters = ("measurements_rejected", "coefficients_rejected", "coefficients_missing")

    def taken_in() -> int:
        seq = sum(int(v) for k, v in diag.values.get(name, {}).items() if k.startswith("samples_"))
        processed = diag.get(name, "last_sample", "None") != "None"
        return sum(diag.number(name, k) for k in counters) + seq + processed

    def renew() -> None:
        nonlocal pm, pc
        pm, pc = ros.stream_writers(node, SPR, ctrl)

    assert ros.spin_until(lambda: name in diag.values, 30.0), ctrl.log()
    throw_until_taken_in(ros, throw, taken_in, renew, ctrl)
    ros.spin_for(0.5)
    before = len(got)
    pm, pc = ros.stream_writers(node, SPR, ctrl)  # new writers: from fuzz writers it was lost
    first = 1_000_000 * SPR
    for m, c in valid_stream(first, 6 * SPR):
        if c is not None:
            pc.publish(c)
        pm.publish(m)
    assert ros.spin_until(
        lambda: any(c.based_on_period == first // SPR + 5 for c in got[before:]), 20.0
    ), (diag.values, ctrl.log())
    ros.spin_for(0.3)
    assert ctrl.returncode is None, ctrl.log()
    for c in got:
        f = from_float_array(c.force)
        assert np.all(np.isfinite(f)) and np.all(np.abs(f) <= 1000.0)
    based = [c.based_on_period for c in got[before:] if c.based_on_period >= first // SPR]
    assert based == list(range(first // SPR, first // SPR + 6)), based
    rejected = diag.number("wavelet_controller", "measurements_rejected") + diag.number(
        "wavelet_controller", "coefficients_rejected"
    )
    assert rejected > 0, diag.values
    assert diag.get("wavelet_controller", "callback_errors") == "0", ctrl.log()


def test_fault_monitor_survives_random_measurements_and_coefficients(ros, node_process) -> None:
    """The fault monitor: garbage on both inputs, then a valid stream is monitored again."""
    from amb_msgs.msg import FaultEvent

    fm = node_process("fault_monitor", params={"samples_per_rev": SPR, "status_period": 0.1})
    node = ros.node("amb_fuzz_fm")
    pm, pc = ros.stream_writers(node, SPR, fm)
    events: list[FaultEvent] = []
    node.create_subscription(FaultEvent, "/amb/fault/events", events.append, 100)
    diag = Diagnostics(node)
    name = "fault_monitor"
    assert ros.spin_until(lambda: name in diag.values, 30.0), fm.log()

    @FUZZ
    @given(
        ms=st.lists(measurements(), max_size=6),
        cs=st.lists(coefficient_messages(), max_size=4),
        raw=st.lists(garbling, max_size=2),
    )
    def throw(ms, cs, raw) -> None:
        for m in ms:
            pm.publish(m)
        for c in cs:
            pc.publish(c)
        for how, where, byte in raw:
            pm.publish(garble(serialize_message(Measurement()), how, where, byte))
            pc.publish(
                garble(serialize_message(cs[0] if cs else WaveletCoefficients()), how, where, byte)
            )
        ros.spin_for(0.02)

    refused = [
        f"{s}_{k}" for s in ("samples", "coefficients") for k in ("repeat", "stray", "stamp")
    ]
    counters = ["measurements_rejected", "coefficients_rejected", *refused]

    def taken_in() -> int:
        return sum(diag.number(name, k) for k in ("messages", *counters))

    def renew() -> None:
        nonlocal pm, pc
        pm, pc = ros.stream_writers(node, SPR, fm)

    throw_until_taken_in(ros, throw, taken_in, renew, fm)
    ros.spin_for(1.0)
    before = diag.number(name, "messages")
    # new writers for the valid stream (this test lost it once in a fresh-clone CI run)
    pm, pc = ros.stream_writers(node, SPR, fm)
    stream = valid_stream(1_000_000 * SPR, 6 * SPR)
    for m, c in stream:
        pm.publish(m)
        if c is not None:
            pc.publish(c)
    valid = sum(c is not None for _, c in stream)
    # all but at most the first two (a candidate after the garbage, or a stamp the garbage's
    # last accepted message makes impossible) are monitored
    assert ros.spin_until(lambda: diag.number(name, "messages") >= before + valid - 2, 20.0), (
        diag.values.get(name),
        fm.log()[-3000:],
    )
    ros.spin_for(0.3)
    assert fm.returncode is None, fm.log()
    rejected = sum(diag.number(name, k) for k in counters)
    assert rejected > 0, diag.values.get(name)
    assert diag.get(name, "callback_errors") == "0", fm.log()
    for e in events:
        assert all(np.isfinite([e.severity, e.confidence, e.rotor_speed])), e
