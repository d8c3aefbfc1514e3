"""A namespace moves the whole system: plant, filterbank and controller in ``/rig_a`` (issue 15).

The three nodes are started with ``--ros-args -r __ns:=/rig_a`` and run a short lock-step
scenario. An observer at the root namespace must see every sample on
``/rig_a/amb/measurement``, the coefficients on ``/rig_a/amb/wavelet/coefficients`` and one
command per period on ``/rig_a/amb/control/command``; the plant must have received every
command (no sample flagged ``STATUS_COMMAND_MISSING``: in lock step it waits for each), so the
exchange ran on the namespaced names in both directions. Nothing may appear on, or publish to,
the root names (``/amb/measurement``, ...): a second system at the root would not hear this one.
The services are under ``/rig_a`` too, and the nodes' ``/diagnostics`` reports (ROS-wide) carry
the namespace.
"""

from __future__ import annotations

import pytest
import yaml
from amb_msgs.msg import ControlCommand, Measurement, WaveletCoefficients
from diagnostic_msgs.msg import DiagnosticArray

from amb_tools.streams import COMMAND_QOS, stream_qos

pytestmark = pytest.mark.ros

SPR = 16
DELAY = 2  # the nodes' default delay_periods (amb_common.topics.DELAY_PERIODS)
NS = "/rig_a"
N_PERIODS = 20
SCENARIO = {
    "name": "namespace_test",
    "speed": {"hz": 20.0},
    "duration": N_PERIODS / 20.0,
    "events": [{"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 1.0e-3, "angle": 0.0}],
}
ROOT_STREAMS = {
    "/amb/measurement": Measurement,
    "/amb/wavelet/coefficients": WaveletCoefficients,
    "/amb/control/command": ControlCommand,
}


def test_plant_filterbank_and_controller_run_in_a_namespace(ros, node_process, tmp_path) -> None:
    ns_args = ["-r", f"__ns:={NS}"]
    node = ros.node("amb_test_namespace_observer")  # at the root namespace
    qos = stream_qos(SPR)
    qos.depth = 4 * N_PERIODS * SPR  # the observer may lag the lock-step run: keep every sample
    samples: list[Measurement] = []
    coefficients: list[WaveletCoefficients] = []
    commands: list[ControlCommand] = []
    stray: list[tuple[str, object]] = []
    reports: set[str] = set()
    node.create_subscription(Measurement, f"{NS}/amb/measurement", samples.append, qos)
    coefficient_sub = node.create_subscription(
        WaveletCoefficients, f"{NS}/amb/wavelet/coefficients", coefficients.append, qos
    )
    command_sub = node.create_subscription(
        ControlCommand, f"{NS}/amb/control/command", commands.append, COMMAND_QOS
    )
    for topic, cls in ROOT_STREAMS.items():
        node.create_subscription(cls, topic, lambda m, t=topic: stray.append((t, m)), qos)
    node.create_subscription(
        DiagnosticArray, "/diagnostics", lambda m: reports.update(s.name for s in m.status), 100
    )

    filterbank = node_process(
        "wavelet_filterbank",
        params={"samples_per_rev": SPR, "status_period": 0.2},
        extra_args=ns_args,
    )
    controller = node_process(
        "wavelet_controller",
        params={"samples_per_rev": SPR, "status_period": 0.2},
        extra_args=ns_args,
    )
    # the filterbank and the controller subscribe the namespaced measurements and publish the
    # namespaced coefficients and commands before the plant starts
    ready = ros.spin_until(
        lambda: (
            node.count_subscribers(f"{NS}/amb/measurement") >= 3
            and coefficient_sub.get_publisher_count() >= 1
            and command_sub.get_publisher_count() >= 1
        ),
        120.0,
    )
    assert ready, (
        f"graph: {node.get_topic_names_and_types()}\n{filterbank.log()}\n{controller.log()}"
    )
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    plant = node_process(
        "plant_sim",
        params={
            "scenario_file": str(scenario),
            "samples_per_rev": SPR,
            "wait_for_subscribers": 3,  # filterbank, controller, observer
            "status_period": 0.1,
            "exit_at_end": False,  # stays up for the graph checks below
        },
        extra_args=ns_args,
    )
    n_samples = N_PERIODS * SPR
    done = ros.spin_until_progress(
        lambda: (
            len(samples) == n_samples
            and len(commands) >= N_PERIODS
            and bool(coefficients)
            and coefficients[-1].sample_index == n_samples - 1
            and f"{NS[1:]}/plant_sim" in reports
        ),
        lambda: (len(samples), len(coefficients), len(commands)),
        stall=60.0,
        limit=300.0,
    )
    assert done, (len(samples), len(coefficients), len(commands), sorted(reports), plant.log())

    assert [m.sample_index for m in samples] == list(range(n_samples))
    missing = [m.sample_index for m in samples if m.status & Measurement.STATUS_COMMAND_MISSING]
    assert missing == [], "the plant missed commands sent on the namespaced command topic"
    assert [c.period_index for c in commands[:N_PERIODS]] == [k + DELAY for k in range(N_PERIODS)]
    assert all(c.sample_index % 2 == 1 for c in coefficients)  # haar: the finest level

    graph = dict(node.get_topic_names_and_types())
    services = dict(node.get_service_names_and_types())
    for name in ("amb/plant/inject_fault", "amb/control/set_mode",
                 "amb/control/start_identification"):  # fmt: skip
        assert f"{NS}/{name}" in services and f"/{name}" not in services, name
    for topic in ROOT_STREAMS:
        assert node.count_publishers(topic) == 0, (topic, graph.get(topic))
        assert node.count_publishers(f"{NS}{topic}") >= 1, topic
    assert stray == [], f"{len(stray)} messages on the root names: {stray[:1]}"
    # each node reports every 0.2 s: a loaded machine may not have delivered each one yet
    expected = {"rig_a/plant_sim", "rig_a/wavelet_filterbank", "rig_a/wavelet_controller"}
    assert ros.spin_until(lambda: expected <= reports, 60.0), sorted(reports)
    assert not {"plant_sim", "wavelet_filterbank", "wavelet_controller"} & reports
