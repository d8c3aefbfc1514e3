"""wavelet_controller over real DDS: one command per measured period, services, bad params."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest
from amb_msgs.msg import ControlCommand, ControllerStatus, Measurement
from amb_msgs.srv import SetControllerMode, StartIdentification
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from reliability_helpers import Diagnostics, call_service, set_parameters, subscribed_by

from amb_tools.streams import FRAME_CODES, QUAD_CODES
from amb_wavelet.analysis import AnalysisFilterbank
from amb_wavelet.frontend import FRAMES, QUADRATURES, ChannelFrontEnd
from amb_wavelet.messages import coefficients_msg

pytestmark = pytest.mark.ros

SPR = 16
DELAY = 2
#: The tests' command reader. A test publishes its whole stream before it spins again, so its
#: reader must hold every command of the run: with the nodes' ``COMMAND_QOS`` (16 deep) the
#: 26-period test lost its first commands whenever the controller kept up with the stream.
EVERY_COMMAND = QoSProfile(
    history=HistoryPolicy.KEEP_LAST, depth=256, reliability=ReliabilityPolicy.RELIABLE
)


def _stream(n_periods: int, skip_coefficients_of: int | None = None):
    """Measurements and the filterbank's coefficient messages of a synchronous orbit."""
    front = ChannelFrontEnd(SPR)
    bank = AnalysisFilterbank("haar", 5, front.n_channels)
    slots = [(FRAME_CODES[f], QUAD_CODES[q]) for f in FRAMES for q in QUADRATURES]
    out = []
    for n in range(n_periods * SPR):
        angle = 2 * np.pi * (n % SPR) / SPR
        m = Measurement(sample_index=n, samples_per_rev=SPR, rotor_angle=angle)
        m.rotor_speed = 2 * np.pi * 20.0
        m.displacement = 1e-5 * np.array([np.cos(angle + c) for c in range(8)])
        m.header.stamp.nanosec = n * 1000
        records = bank.step(front.step(m.displacement, angle), n)
        c = None
        if records and n != skip_coefficients_of:
            c = coefficients_msg(m.header, "haar", SPR, SPR, n, m.rotor_speed, records, slots)
        out.append((m, c))
    return out


def _start(node_process, **params):
    return node_process(
        "wavelet_controller",
        params={"samples_per_rev": SPR, "delay_periods": DELAY, "status_period": 0.2, **params},
    )


def _command_reader_matched(ros, node, ctrl) -> None:
    """Wait until the controller's command writer reports the test's reader matched.

    Its own count (on /diagnostics), not the test's view of the graph: with one core busy a
    writer matched a reader seconds after the reader saw it, and the first commands were lost.
    """
    writers = Diagnostics(node)
    assert ros.spin_until(
        lambda: writers.matched("wavelet_controller", "/amb/control/command") >= 1, 30.0
    ), ctrl.log()


def _run_periods(ros, ctrl, name: str, n_periods: int):
    """Feed ``n_periods`` of :func:`_stream` to ``ctrl``; return its commands and the stream."""
    node = ros.node(name)
    commands: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    stream = _stream(n_periods)
    for m, c in stream:
        if c is not None:
            pc.publish(c)
        pm.publish(m)
    assert ros.spin_until(lambda: len(commands) == n_periods, 30.0), ctrl.log()
    return commands, stream


def test_one_command_per_period_and_mode_services(ros, node_process) -> None:
    ctrl = _start(node_process, controller="transient")
    node = ros.node("amb_test_driver")
    commands: list[ControlCommand] = []
    statuses: list[ControllerStatus] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    node.create_subscription(ControllerStatus, "/amb/control/status", statuses.append, 10)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    n_periods = 6
    lost = 4 * SPR - 1  # the coefficients completing period 3 (its 1x level) are lost
    for m, c in _stream(n_periods, skip_coefficients_of=lost):
        if c is not None:  # coefficients before their measurement: the node joins them
            pc.publish(c)
        if m.sample_index // SPR in (4, 5):  # the plant ran periods 4 and 5 without commands
            m.status = Measurement.STATUS_COMMAND_MISSING
        pm.publish(m)
    assert ros.spin_until(lambda: len(commands) == n_periods, 30.0), ctrl.log()
    assert ros.spin_until(lambda: statuses and statuses[-1].period_index == n_periods - 1, 10.0)
    assert statuses[-1].commands_late == 2, "the commands sent for periods 4 and 5"
    assert [c.period_index for c in commands] == [k + DELAY for k in range(n_periods)]
    assert all(c.based_on_period == k for k, c in enumerate(commands))
    assert all(len(c.force) == 4 * SPR and not any(c.force) for c in commands)  # OFF
    assert commands[3].hold, "an incomplete period is answered with a held, zero command"
    assert statuses[-1].mode == ControllerStatus.MODE_OFF

    set_mode = node.create_client(SetControllerMode, "/amb/control/set_mode")
    identify = node.create_client(StartIdentification, "/amb/control/start_identification")
    assert set_mode.wait_for_service(timeout_sec=10.0) and identify.wait_for_service(10.0)

    def call(client, request):
        future = client.call_async(request)
        assert ros.spin_until(future.done, 10.0)
        return future.result()

    no_model = call(set_mode, SetControllerMode.Request(mode=ControllerStatus.MODE_ACTIVE))
    assert not no_model.accepted and no_model.mode == ControllerStatus.MODE_OFF
    started = call(identify, StartIdentification.Request(level=1, amplitude=10.0))
    assert started.accepted, started.message
    bad = call(set_mode, SetControllerMode.Request(mode=9))
    assert not bad.accepted


@pytest.mark.slow  # one process start-up per case (start-up refusals)
@pytest.mark.parametrize(
    ("params", "words"),
    [
        ({"w": 1.5}, ("'w'", "1.5")),
        ({"v": -1.2}, ("'v'", "-1.2")),
        ({"delay_periods": 0}, ("delay_periods",)),
        ({"wavelet": "bior2.2"}, ("wavelet", "bior2.2")),
        ({"force_limit": [2000.0, 2000.0, 2000.0, 2000.0]}, ("force_limit", "1000")),
        ({"model_file": "/nonexistent/model.npz"}, ("model",)),
        ({"start_mode": "active"}, ("start_mode",)),
    ],
)
def test_invalid_parameters_stop_the_node_with_a_reason(node_process, params, words) -> None:
    ctrl = _start(node_process, **params)
    assert ctrl.wait(60) == 2, ctrl.log()
    log = ctrl.log()
    assert all(w in log for w in words), log


@pytest.mark.slow
def test_a_slow_filterbank_is_waited_for_while_its_coefficients_keep_coming(
    ros, node_process
) -> None:
    """Lock-step under load: the coefficients of a period trickle in, the controller waits.

    The plant publishes a period's measurements at once and waits for the command; a loaded
    filterbank then needs longer than ``coefficient_timeout`` (1 s) to get through them, though
    each coefficient message follows the last within a fraction of it. Here the measurements of
    three periods arrive at once and their coefficients one every 0.1 s (2.4 s in all, also
    longer than ``measurement_timeout``, 2 s): every period must be answered with a computed
    command, none held for missing coefficients.
    """
    ctrl = _start(node_process, controller="transient")
    node = ros.node("amb_test_slow_filterbank")
    commands: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    n_periods = 3
    stream = _stream(n_periods)
    for m, _c in stream:
        pm.publish(m)
    for _m, c in stream:
        if c is not None:
            ros.spin_for(0.1)
            pc.publish(c)
    assert ros.spin_until(lambda: len(commands) == n_periods, 30.0), ctrl.log()
    assert [c.period_index for c in commands] == [k + DELAY for k in range(n_periods)]
    assert [c.hold for c in commands] == [False] * n_periods, ctrl.log()


def _delay_model(path) -> str:
    """A model of one period of delay on each coefficient, with its exact inverse (8 x 8)."""
    from amb_controller.model_file import WaveletModel

    n = 8  # 4 inner sensors x 2 quadratures at 1 x; 4 axes x 2 quadratures
    markov = np.zeros((2, n, n))
    markov[1] = 1e-5 * np.eye(n)
    inverse = np.zeros((6, n, n))  # inverse_order 5, as configured
    inverse[0] = 1e5 * np.eye(n)
    model = WaveletModel(markov, inverse, "haar", SPR, 2 * np.pi * 20.0, (1,))
    return str(model.save(path))


@pytest.mark.slow
def test_a_controller_unsafe_on_its_own_model_is_never_active(ros, node_process, tmp_path):
    """Issue 18, never worse than PID: start, service and run-time change (supervisor docstring).

    On the delay model, ``w = 0.75`` with ``v = 0.995`` puts a closed-loop pole at 0.995 (a
    decay of 0.5 % per period, above ``max_model_radius`` 0.98), ``v = 0.75`` at 0.84.
    """
    ctrl = _start(
        node_process,
        controller="transient",
        model_file=_delay_model(tmp_path / "delay.npz"),
        start_mode="active",
        v=0.995,
    )
    node = ros.node("amb_test_model_check")
    commands: list[ControlCommand] = []
    statuses: list[ControllerStatus] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    node.create_subscription(ControllerStatus, "/amb/control/status", statuses.append, 10)
    diagnostics = Diagnostics(node)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    stream = _stream(9)

    def periods(first: int, last: int) -> None:
        for m, c in stream[first * SPR : (last + 1) * SPR]:
            if c is not None:
                pc.publish(c)
            pm.publish(m)
        assert ros.spin_until(lambda: len(commands) == last + 1, 30.0), ctrl.log()
        assert ros.spin_until(lambda: statuses and statuses[-1].period_index == last, 10.0)

    periods(0, 2)  # started "active" with an unsafe loop: the node runs, OFF, and says why
    assert ctrl.proc.poll() is None, ctrl.log()
    assert statuses[-1].mode == ControllerStatus.MODE_OFF
    assert "ACTIVE refused" in statuses[-1].message and "0.995" in statuses[-1].message
    assert "staying OFF" in ctrl.log()
    assert not any(any(c.force) for c in commands)
    name = "wavelet_controller"
    assert ros.spin_until(lambda: diagnostics.get(name, "closed_loop_radius") != "", 10.0)
    assert float(diagnostics.get(name, "closed_loop_radius")) == pytest.approx(0.995, abs=1e-3)

    set_mode = node.create_client(SetControllerMode, "/amb/control/set_mode")
    assert set_mode.wait_for_service(timeout_sec=10.0)
    active = SetControllerMode.Request(mode=ControllerStatus.MODE_ACTIVE)
    refused = call_service(ros, set_mode, active)
    assert not refused.accepted and "spectral radius 0.995" in refused.message

    assert set_parameters(ros, node, name, {"v": 0.75})[0].successful
    periods(3, 4)  # applied at a period boundary: the rebuilt controller is safe
    accepted = call_service(ros, set_mode, active)
    assert accepted.accepted, accepted.message
    periods(5, 6)
    assert statuses[-1].mode == ControllerStatus.MODE_ACTIVE
    assert set_parameters(ros, node, name, {"v": 0.995})[0].successful
    periods(7, 8)  # the running controller became unsafe: switched OFF, with the reason
    assert statuses[-1].mode == ControllerStatus.MODE_OFF, ctrl.log()
    assert statuses[-1].message.startswith("off: closed loop on its own model")
    assert "after the parameter change" in ctrl.log()


@pytest.mark.slow
def test_a_sinusoidal_output_basis_sends_a_pure_1x_force(ros, node_process, tmp_path):
    """``output_basis: sinusoid``: the force of every command is a 1 x sinusoid per axis.

    Reference: numpy's FFT of the force samples in the ControlCommand messages.
    """
    ctrl = _start(
        node_process,
        controller="transient",
        output_basis="sinusoid",
        model_file=_delay_model(tmp_path / "delay.npz"),
        start_mode="active",
    )
    n_periods = 5
    commands, _ = _run_periods(ros, ctrl, "amb_test_sinusoid", n_periods)
    assert {c.wavelet for c in commands} == {"sinusoid"}
    force = np.array([c.force for c in commands]).reshape(n_periods, 4, SPR)
    spectrum = np.abs(np.fft.rfft(force, axis=2))
    assert spectrum[:, :, 1].max() * 2 / SPR > 1.0, "a force of more than 1 N acts"
    assert spectrum[:, :, [0, *range(2, SPR // 2 + 1)]].max() < 1e-9 * spectrum[:, :, 1].max()
    quads = {(a.level, a.quadrature) for c in commands for a in c.coefficients}
    assert {level for level, _ in quads} == {1} and len(quads) == 2  # cosine and sine


@pytest.mark.slow
def test_the_predictive_controller_runs_in_the_node_with_its_parameters(
    ros, node_process, tmp_path
):
    """``controller: predictive`` with non-default horizon, moves and weights (issue 18 item 2).

    Reference: the ROS-free pipeline (tested against closed forms in
    test/controller/test_predictive.py) fed the same samples with the same configuration; the
    node must pass every parameter through and send exactly its commands.
    """
    from amb_controller.config import ControllerConfig
    from amb_controller.model_file import WaveletModel
    from amb_controller.pipeline import ControllerPipeline
    from amb_controller.supervisor import Mode

    params = {
        "controller": "predictive",
        "output_basis": "sinusoid",
        "horizon": 6,
        "moves": 2,
        "move_weight": 0.5,
        "input_weight": 0.1,
    }
    model_file = _delay_model(tmp_path / "delay.npz")
    ctrl = _start(node_process, model_file=model_file, start_mode="active", **params)
    n_periods = 6
    commands, stream = _run_periods(ros, ctrl, "amb_test_predictive", n_periods)

    config = ControllerConfig(samples_per_rev=SPR, delay_periods=DELAY, **params)
    front = ChannelFrontEnd(SPR)
    pipe = ControllerPipeline(config, 1000.0, WaveletModel.load(model_file), front.labels)
    assert pipe.set_mode(Mode.ACTIVE)[0]
    bank = AnalysisFilterbank("haar", 5, front.n_channels)
    expected = []
    for m, _ in stream:
        records = bank.step(front.step(m.displacement, m.rotor_angle), m.sample_index)
        out = pipe.on_sample(m.sample_index, records, m.displacement, m.rotor_speed)
        if out is not None:
            expected.append(np.ravel(out.force))
    got = np.array([c.force for c in sorted(commands, key=lambda c: c.period_index)])
    expected = np.array(expected)
    assert np.abs(expected).max() > 1.0, "the reference commands a force of more than 1 N"
    np.testing.assert_allclose(got, expected, rtol=0, atol=1e-9 * np.abs(expected).max())
    assert {c.wavelet for c in commands} == {"sinusoid"}


def _early_model(path, n_periods_h: int = 6) -> tuple[str, np.ndarray]:
    """A synthetic early-action model for SPR (all 8 sensors, two planes); its plane pair 1."""
    from amb_controller.early_model import EarlyActionModel

    rng = np.random.default_rng(7)
    L = n_periods_h * SPR
    lp = L + 4 * SPR
    k = np.arange(lp)
    modes = [
        np.exp(-0.15 * 2 * np.pi * f * k) * np.sin(2 * np.pi * f * k) for f in (1 / SPR, 3 / SPR)
    ]
    bearing = sum(np.einsum("n,sa->nsa", m[:L], rng.uniform(-1, 1, (8, 4))) for m in modes) * 1e-6
    planes = []
    for _ in range(2):
        pair = []
        for c in range(2):
            drive = np.cos(2 * np.pi * k / SPR + c * np.pi / 2)
            resp = [np.convolve(drive, m)[:lp] for m in modes]
            pair.append(sum(np.outer(r, rng.uniform(-1, 1, 8)) for r in resp) * 1e-3)
        planes.append(np.stack(pair, axis=2))
    model = EarlyActionModel(SPR, bearing, np.array(planes), ("D1", "D2"), tuple(range(8)))
    return str(model.save(path)), model.plane_responses[1]


@pytest.mark.slow
def test_the_early_action_reports_a_sudden_unbalance_from_its_model_file(
    ros, node_process, tmp_path
):
    """``early_model_file`` (issue 18 item 4): the node loads it, tests every period, says so.

    Reference: the change written into the measurements here, 0.36 kg m in plane D2 from sample
    20 SPR + 5 (the model's own response, noise-free); the node must name the plane, the
    unbalance (to 1 %) and the onset sample. The controller stays OFF: the early action decides
    but adds no force (the force path is the pipeline's, tested in process), and a missing
    file stops the node with a reason.
    """
    path, pair = _early_model(tmp_path / "early.npz")
    ctrl = _start(node_process, controller="transient", early_model_file=path)
    node = ros.node("amb_test_early")
    commands: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    n_periods, onset = 26, 20 * SPR + 5
    change = np.zeros((n_periods * SPR, 8))
    change[onset:] = pair[: n_periods * SPR - onset] @ np.array([0.3, -0.2])
    for m, c in _stream(n_periods):
        m.displacement = np.asarray(m.displacement) + change[m.sample_index]
        if c is not None:
            pc.publish(c)
        pm.publish(m)
    assert ros.spin_until(lambda: len(commands) == n_periods, 30.0), ctrl.log()
    assert ros.spin_until(lambda: "early action" in ctrl.log(), 10.0), ctrl.log()
    log = ctrl.log()
    found = re.search(r"sudden unbalance (\d+) g cm at (\w+)", log)
    assert found is not None, log
    assert found.group(2) == "D2"
    assert float(found.group(1)) == pytest.approx(math.hypot(0.3, -0.2) * 1e5, rel=0.01)
    assert "not active" in log, log
    assert f"onset sample {onset}" in log, log
    assert all(not np.any(c.force) for c in commands)  # OFF: zero force throughout
    ctrl.stop()
    bad = _start(node_process, early_model_file=str(tmp_path / "none.npz"))
    assert bad.wait(60) == 2, bad.log()
    assert "early-action model" in bad.log()


def test_coefficients_ahead_of_silent_measurements_are_reported_once(ros, node_process) -> None:
    """A measurement reader the transport no longer feeds, while the filterbank's is fed.

    The coefficients run on ahead of the last measurement (here: the test stops sending
    measurements after two periods, as the shared-memory transport did to a controller stopped
    for seconds, docs/history.md). Coefficients from the future alone are not the error (they
    are also a burst the measurements will follow); after ``measurement_timeout`` without a
    measurement they are, and the node says it once, naming the transport.
    """
    ctrl = _start(node_process, measurement_timeout=1.5)  # the first check's margin under load
    node = ros.node("amb_test_blind_reader")
    commands: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    stream = _stream(16)
    for m, c in stream[: 2 * SPR]:
        if c is not None:
            pc.publish(c)
        pm.publish(m)
    assert ros.spin_until(lambda: len(commands) == 2, 30.0), ctrl.log()
    future = [c for _m, c in stream[12 * SPR :] if c is not None]
    error = "transport no longer feeds"
    pc.publish(future[0])  # at once: ahead, but measurements may still follow
    assert ros.spin_until(lambda: "from the future" in ctrl.log(), 10.0), ctrl.log()
    assert error not in ctrl.log()
    ros.spin_for(2.0)  # the measurements' silence outlasts measurement_timeout
    for c in future[1:]:
        pc.publish(c)
        ros.spin_for(0.01)
    assert ros.spin_until(lambda: error in ctrl.log(), 10.0), ctrl.log()
    ros.spin_for(0.5)
    assert ctrl.log().count(error) == 1, ctrl.log()


def test_silent_streams_with_a_matched_writer_move_the_readers_to_a_new_participant(
    ros, node_process
) -> None:
    """Both streams silent while their writers are matched: the readers get a participant anew.

    What the controller does when the transport stops feeding both of its readers
    (``amb_tools.reader_participant``), shown with writers that merely pause: after
    ``reader_renewal_after`` s without a message, the readers move once to a new participant (a
    node ``wavelet_controller_readers_1`` in the graph), and the stream that resumes is read
    from there: commands come again for the periods after the pause.
    """
    ctrl = _start(node_process, reader_renewal_after=1.0)
    node = ros.node("amb_test_renewed_readers")
    commands: list[ControlCommand] = []
    node.create_subscription(ControlCommand, "/amb/control/command", commands.append, EVERY_COMMAND)
    diagnostics = Diagnostics(node)
    pm, pc = ros.stream_writers(node, SPR, ctrl)
    _command_reader_matched(ros, node, ctrl)
    stream = _stream(12)

    def send(periods: range) -> None:
        for m, c in stream[periods.start * SPR : periods.stop * SPR]:
            if c is not None:
                pc.publish(c)
            pm.publish(m)

    send(range(0, 2))
    assert ros.spin_until(lambda: len(commands) == 2, 30.0), ctrl.log()
    moved = "moved to a new participant"
    assert ros.spin_until(lambda: moved in ctrl.log(), 20.0), ctrl.log()
    readers = "wavelet_controller_readers_1"
    for topic in ("/amb/measurement", "/amb/wavelet/coefficients"):
        assert ros.spin_until(lambda t=topic: subscribed_by(node, t, readers), 20.0), ctrl.log()
    assert ros.spin_until(
        lambda: diagnostics.get("wavelet_controller", "readers_renewed") == "1", 10.0
    ), ctrl.log()
    ros.spin_for(1.0)  # the test's writers match the new readers (their own view may lag)
    send(range(2, 12))
    assert ros.spin_until(lambda: len(commands) >= 6, 30.0), (len(commands), ctrl.log())
    assert ctrl.log().count(moved) == 1, ctrl.log()
    assert "measurements resumed" in ctrl.log()
