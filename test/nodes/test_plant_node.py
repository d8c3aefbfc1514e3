"""plant_sim over real DDS: lock-step exchange, forces applied, bad commands, fault injection.

The reference for the published measurements is the simulator core itself run in this process
with the same forces: the node must add nothing and lose nothing (bit-for-bit equality).
"""

from __future__ import annotations

import re
import time

import numpy as np
import pytest
import yaml
from amb_msgs.msg import ControlCommand, Measurement
from amb_msgs.srv import InjectFault
from diagnostic_msgs.msg import DiagnosticArray

from amb_common.rig import load_rig
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator
from amb_tools.conversions import to_float_array
from amb_tools.streams import COMMAND_QOS, stream_qos

pytestmark = pytest.mark.ros

SPR = 16
DELAY = 2
SCENARIO = {
    "name": "node_test",
    "speed": {"hz": 20.0},
    "duration": 0.5,  # 10 revolutions = 10 periods
    "measurement_noise": 1.0e-7,
    "events": [
        {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3, "angle": 0.0},
        # 200 g cm keeps the loop linear at 20 Hz (a 430 g cm loss, 2 Hz above the second
        # critical speed, saturates the coils: the plant steps sample by sample, at 0.71 x real
        # time in one suite run, and the realtime tests would measure that instead)
        {"kind": "mass_loss", "time": 0.2, "disk": "D1", "me": 2.0e-3, "angle": 1.0},
    ],
}


def _force(period: int) -> np.ndarray:
    """A distinct wavelet force pattern per period, (SPR, 4) N."""
    n = np.arange(SPR)[:, None]
    axis = np.arange(4)[None, :]
    return 20.0 * np.sin(2 * np.pi * n / SPR + period + axis)


def _command(period: int, force: np.ndarray) -> ControlCommand:
    c = ControlCommand(period_index=period, start_sample_index=period * SPR)
    c.samples_per_period = SPR
    c.delay_periods = DELAY
    c.force = to_float_array(force.T.ravel())  # axis-major
    return c


class _Loop:
    """Test-side controller: answers every measured period m with a command for m + DELAY."""

    def __init__(self, ros, skip=(), corrupt=(), late_at: int | None = None) -> None:
        self.node = ros.node("amb_test_controller")
        self.samples: list[Measurement] = []
        self.arrivals: list[float] = []  # s, monotonic wall time of each sample's arrival
        self.diag: dict[str, str] = {}
        self.reports: list[dict[str, str]] = []  # every plant_sim report, in order
        self.skip, self.corrupt = set(skip), set(corrupt)
        self.late_at = late_at  # answer each period only when its own sample late_at arrives
        self.pub = self.node.create_publisher(ControlCommand, "/amb/control/command", COMMAND_QOS)
        self.node.create_subscription(
            Measurement, "/amb/measurement", self.on_measurement, stream_qos(SPR)
        )
        self.node.create_subscription(DiagnosticArray, "/diagnostics", self.on_diag, 10)

    def on_measurement(self, m: Measurement) -> None:
        self.arrivals.append(time.monotonic())
        self.samples.append(m)
        if self.late_at is not None:
            k, position = divmod(m.sample_index, SPR)
            if position == self.late_at and k >= DELAY:
                self.pub.publish(_command(k, _force(k)))  # its period has started: late
            return
        if m.sample_index % SPR == SPR - 1:
            target = m.sample_index // SPR + DELAY
            if target in self.skip:
                return
            cmd = _command(target, _force(target))
            if target in self.corrupt:
                bad = _command(target, _force(target))
                bad.force[3] = float("nan")
                self.pub.publish(bad)  # rejected; the good one follows
            self.pub.publish(cmd)

    def on_diag(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            if s.name == "plant_sim":
                self.diag.update({kv.key: kv.value for kv in s.values})
                self.reports.append({kv.key: kv.value for kv in s.values})


def _start_plant(node_process, tmp_path, **params):
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    return node_process(
        "plant_sim",
        params={
            "scenario_file": str(scenario),
            "samples_per_rev": SPR,
            "delay_periods": DELAY,
            "status_period": 0.1,
            **params,
        },
    )


def _reference(forces_by_period: dict[int, np.ndarray]):
    rig = load_rig()
    sim = PlantSimulator(rig, scenario_from_dict(SCENARIO, rig), samples_per_rev=SPR, seed=0)
    n_periods = 10
    blocks = [sim.advance(SPR, forces_by_period.get(k)) for k in range(n_periods)]
    return np.concatenate([b.displacement for b in blocks])


def test_lockstep_applies_each_command_in_its_period(ros, node_process, tmp_path) -> None:
    loop = _Loop(ros, corrupt={5})
    plant = _start_plant(node_process, tmp_path)
    assert ros.spin_until(lambda: len(loop.samples) == 10 * SPR, 60.0), (
        len(loop.samples),
        plant.log(),
    )
    assert plant.wait(60) == 0
    idx = [m.sample_index for m in loop.samples]
    assert idx == list(range(10 * SPR))
    forces = {k: _force(k) for k in range(DELAY, 10)}
    wf = np.array([m.wavelet_force for m in loop.samples])
    expected = np.concatenate([forces.get(k, np.zeros((SPR, 4))) for k in range(10)])
    np.testing.assert_array_equal(wf, expected)
    assert not any(m.status & Measurement.STATUS_COMMAND_MISSING for m in loop.samples)
    disp = np.array([m.displacement for m in loop.samples])
    np.testing.assert_array_equal(disp, _reference(forces))
    assert "rejected 1" in plant.log()  # the NaN command of period 5
    assert "periods controlled 100.0%" in plant.log()  # all 8 after the first DELAY


@pytest.mark.slow
def test_missing_command_times_out_to_zero_force(ros, node_process, tmp_path) -> None:
    loop = _Loop(ros, skip={4})
    # 2 s: the test's own answers, slowed by a loaded machine, must not be missed; the skipped
    # period costs those 2 s once
    plant = _start_plant(node_process, tmp_path, command_timeout=2.0)
    assert ros.spin_until(lambda: len(loop.samples) == 10 * SPR, 60.0), plant.log()
    assert plant.wait(60) == 0
    period4 = loop.samples[4 * SPR : 5 * SPR]
    assert all(m.status & Measurement.STATUS_COMMAND_MISSING for m in period4)
    assert all(not np.any(m.wavelet_force) for m in period4)
    assert "missing 1," in plant.log()


@pytest.mark.slow
def test_realtime_publishes_each_sample_at_its_instant(ros, node_process, tmp_path) -> None:
    """A rig does not send a period's samples in one burst: they leave at the sample rate."""
    loop = _Loop(ros)
    plant = _start_plant(node_process, tmp_path, mode="realtime")
    assert ros.spin_until(lambda: len(loop.samples) == 10 * SPR, 60.0), plant.log()
    assert plant.wait(60) == 0
    assert [m.sample_index for m in loop.samples] == list(range(10 * SPR))
    fs = SPR * SCENARIO["speed"]["hz"]
    arrivals = np.array(loop.arrivals).reshape(10, SPR)
    spread = arrivals[:, -1] - arrivals[:, 0]  # s, first to last sample of each period
    # (SPR - 1) / fs = 47 ms at the sample instants; a burst arrives within a few ms. A loaded
    # machine may hold the test's own process for a period and hand it a whole period at
    # once (the median spread failed with two busy processes beside it): published at the
    # sample instants, several periods still arrive spread; published in bursts, none does.
    assert np.count_nonzero(spread > 0.5 * (SPR - 1) / fs) >= 3, spread
    # The run took its real time: arrivals can be late (never early), so a hold of the test's
    # process at the start compresses the first samples into a burst; after it, they track the
    # sample instants. Some sample of the first half must be followed by the last one no sooner
    # than 0.8 x the real time between them (a burst-publishing plant: ms for every sample).
    flat = arrivals.ravel()
    ahead = (flat.size - 1 - np.arange(flat.size // 2)) / fs  # s between sample i and the last
    took = flat[-1] - flat[: flat.size // 2]
    assert np.any(took > 0.8 * ahead), np.max(took / ahead)
    applied = 0
    for k in range(10):  # each period ran with its command or, if that was late, from a sample on
        wf = np.array([m.wavelet_force for m in loop.samples[k * SPR : (k + 1) * SPR]])
        start = int(np.argmax(wf.any(axis=1))) if wf.any() else SPR
        assert not wf[:start].any() and np.array_equal(wf[start:], _force(k)[start:]), k
        assert not wf.any() or k >= DELAY, k
        applied += start == 0
    # the effective control delay, as the plant reports it, agrees with the forces it applied
    control = re.search(r"periods controlled ([\d.]+)%(, command arrival - period start)?",
                        plant.log())  # fmt: skip
    assert control is not None, plant.log()
    assert float(control.group(1)) == pytest.approx(100 * applied / (10 - DELAY), abs=0.05)
    assert applied == 0 or control.group(2) is not None  # each applied command was timed
    # the plant's own punctuality: how late its oldest due sample left at each wake, never early
    lag = re.search(r"sample publication lag p99 ([\d.]+) ms, max ([\d.]+) ms", plant.log())
    assert lag is not None, plant.log()
    assert 0.0 <= float(lag.group(1)) <= float(lag.group(2)), lag.group(0)
    # and its longest single write, under the wall time the run took
    write = re.search(r"longest measurement write ([\d.]+) ms", plant.log())
    wall = re.search(r"in ([\d.]+) s wall", plant.log())
    assert write is not None and wall is not None, plant.log()
    assert 0.0 <= float(write.group(1)) < 1e3 * float(wall.group(1)), write.group(0)
    # each period is simulated at its start and published sample by sample: the last sample
    # published trails the simulated time by 1 sample to 1 period (bench/realtime_session.py
    # places the samples in wall time with it)
    running = [
        (float(r["time"]), float(r["published_time"]))
        for r in loop.reports
        if float(r["published_time"]) >= 0 and r["done"] == "False"
    ]
    assert running, loop.reports
    for simulated, published in running:
        assert 1 / fs - 1e-6 <= simulated - published <= SPR / fs + 1e-6, running


@pytest.mark.slow
def test_realtime_applies_a_late_command_to_the_rest_of_its_period(
    ros, node_process, tmp_path
) -> None:
    """partial_commands: every command is sent when its own period's sample 3 has arrived."""
    loop = _Loop(ros, late_at=3)
    plant = _start_plant(node_process, tmp_path, mode="realtime")
    assert ros.spin_until(lambda: len(loop.samples) == 10 * SPR, 60.0), plant.log()
    assert plant.wait(60) == 0
    assert [m.sample_index for m in loop.samples] == list(range(10 * SPR))
    forces, starts = {}, {}
    for k in range(DELAY, 10):
        period = loop.samples[k * SPR : (k + 1) * SPR]
        wf = np.array([m.wavelet_force for m in period])
        missing = np.array([bool(m.status & Measurement.STATUS_COMMAND_MISSING) for m in period])
        start = int(np.argmax(wf.any(axis=1))) if wf.any() else SPR
        # the command cannot act before the sample it answered was published (sample 3)
        assert start >= 4, (k, start)
        assert not wf[:start].any() and np.array_equal(wf[start:], _force(k)[start:]), k
        np.testing.assert_array_equal(missing, np.arange(SPR) < start)  # flagged until it acts
        forces[k], starts[k] = np.where(np.arange(SPR)[:, None] < start, 0.0, _force(k)), start
    partial = sum(s < SPR for s in starts.values())
    # 46 ms of each 50 ms period remain after sample 3: on a loaded machine a command may
    # still miss its period now and then, but most must act
    assert partial >= (10 - DELAY) // 2, starts
    log = plant.log()
    assert f"partial {partial}" in log and f"late {10 - DELAY}" in log, log
    assert "periods controlled 0.0%" in log  # no period ran whole with its command
    share = sum(SPR - s for s in starts.values()) / SPR / (10 - DELAY)
    shown = re.search(r"samples controlled ([\d.]+)%", log)
    assert shown is not None and float(shown.group(1)) == pytest.approx(100 * share, abs=0.05)
    # what the rotor felt is what the samples say: the simulator core with the same forces
    disp = np.array([m.displacement for m in loop.samples])
    expected = _reference(forces)
    np.testing.assert_allclose(disp, expected, rtol=0.0, atol=1e-9 * np.abs(expected).max())


def test_fault_injection_service(ros, node_process, tmp_path) -> None:
    loop = _Loop(ros, skip=set(range(DELAY, 10)))  # no commands: the plant waits
    plant = _start_plant(node_process, tmp_path, command_timeout=600.0)
    client = loop.node.create_client(InjectFault, "/amb/plant/inject_fault")
    assert client.wait_for_service(timeout_sec=30.0), plant.log()

    def call(event_yaml: str) -> InjectFault.Response:
        # a request sent while the service's reply path is still being matched can go
        # unanswered (DDS discovery): ask again, up to three times
        for _ in range(3):
            future = client.call_async(InjectFault.Request(event_yaml=event_yaml))
            if ros.spin_until(future.done, 10.0):
                return future.result()
            client.remove_pending_request(future)
        raise AssertionError(f"no reply from /amb/plant/inject_fault:\n{plant.log()}")

    ok = call("{kind: sensor_fault, plane: 1, axis: x, mode: offset, value: 1.0e-4}")
    assert ok.accepted, ok.message
    bad = call("{kind: mass_loss, disk: D1}")
    assert not bad.accepted and "me" in bad.message
    worse = call("not: [valid")
    assert not worse.accepted


@pytest.mark.slow  # one process start-up per case (start-up refusals)
@pytest.mark.parametrize(
    ("params", "words"),
    [
        ({"samples_per_rev": 12}, ("samples_per_rev", "power of two")),
        ({"scenario_file": "/nonexistent.yaml"}, ("scenario_file", "no such file")),
        ({"wavelet_force_limit": 5000.0}, ("wavelet_force_limit", "capacity")),
        ({"mode": "fast"}, ("mode", "lockstep")),
    ],
)
def test_invalid_parameters_stop_the_node_with_a_reason(node_process, tmp_path, params, words):
    plant = _start_plant(node_process, tmp_path, **params)
    assert plant.wait(60) == 2
    log = plant.log()
    assert all(w in log for w in words), log
