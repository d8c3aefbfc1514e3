"""A process started with ``AMB_TRANSPORT=udp`` has no shared-memory transport and still talks.

``amb_tools.transport_profile`` (module notes, "Off shared memory"): with the localhost
discovery range these wheels' RMW sets the participant's transports itself, so the process gets
the profile's loopback-UDP participant as its default and the ``SYSTEM_DEFAULT`` range; with any
other range ``FASTDDS_BUILTIN_TRANSPORTS=UDPv4``. The environment is checked against the
profile file's own text; the process test checks what Fast DDS made: the writer process's
threads (Fast DDS names its shared-memory listeners ``dds.shm.<port>``, its UDP ones
``dds.udp.<port>``) and every message at this test's ordinary (shared-memory) reader.
"""

from __future__ import annotations

import os
import subprocess
import sys
import threading
import xml.etree.ElementTree as ET

import pytest
from rclpy.qos import HistoryPolicy, QoSProfile, ReliabilityPolicy
from std_msgs.msg import String
from writer_process import writer_script

from amb_tools.transport_profile import (
    LOOPBACK_PARTICIPANT,
    PROFILE_VARIABLES,
    TRANSPORT_VARIABLE,
    TransportError,
    project_profile,
    transport_of,
    use_project_profile,
)

pytestmark = [pytest.mark.ros]

TOPIC = "/amb_test/off_shared_memory"
MESSAGES = 50
WRITER = writer_script(
    "amb_test_off_shm_writer",
    TOPIC,
    "depth=1, history=HistoryPolicy.KEEP_ALL",
    f"""
for k in range({MESSAGES}):
    pub.publish(String(data=str(k)))
if not pub.wait_for_all_acked(Duration(seconds=20.0)):
    sys.exit("not acknowledged in 20 s")
tasks = os.listdir("/proc/self/task")
names = sorted(open(f"/proc/self/task/{{t}}/comm").read().strip() for t in tasks)
print("threads", *names, flush=True)
""",
)


def _defaults(path) -> list[ET.Element]:
    """The participant profiles of the profile file ``path`` marked default."""
    root = ET.parse(path).getroot()
    return [p for p in root.iterfind(".//{*}participant") if p.get("is_default_profile") == "true"]


def _participant(path) -> ET.Element:
    """The default participant profile of the profile file ``path``."""
    found = _defaults(path)
    assert len(found) == 1, f"{path}: {len(found)} default participant profiles"
    return found[0]


def test_the_transport_variable_takes_shm_or_udp_only() -> None:
    assert transport_of({}) == "shm"
    assert transport_of({TRANSPORT_VARIABLE: "UDP"}) == "udp"
    assert transport_of({TRANSPORT_VARIABLE: "shm"}) == "shm"
    with pytest.raises(TransportError, match="'tcp'"):
        transport_of({TRANSPORT_VARIABLE: "tcp"})


def test_udp_with_the_localhost_range_makes_the_loopback_participant_the_default(tmp_path) -> None:
    env = {TRANSPORT_VARIABLE: "udp", "ROS_AUTOMATIC_DISCOVERY_RANGE": "LOCALHOST"}
    path = use_project_profile(env)
    assert path != project_profile()
    assert env[PROFILE_VARIABLES[0]] == str(path)
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert "FASTDDS_BUILTIN_TRANSPORTS" not in env
    participant = _participant(path)
    assert participant.get("profile_name") == LOOPBACK_PARTICIPANT
    assert participant.findtext(".//{*}useBuiltinTransports") == "false"
    ids = [e.text for e in participant.iterfind(".//{*}userTransports/{*}transport_id")]
    descriptors = {
        d.findtext("{*}transport_id"): d
        for d in ET.parse(path).getroot().iterfind(".//{*}transport_descriptor")
    }
    assert [descriptors[i].findtext("{*}type") for i in ids] == ["UDPv4"]
    assert [a.text for a in descriptors[ids[0]].iterfind(".//{*}address")] == ["127.0.0.1"]
    for where in ("metatrafficUnicastLocatorList", "initialPeersList"):
        assert [a.text for a in participant.iterfind(f".//{{*}}{where}//{{*}}address")] == [
            "127.0.0.1"
        ], where
    # the copy keeps the rest of the project's profile (the writers' heartbeat)
    assert ET.parse(path).getroot().find(".//{*}heartbeatPeriod") is not None
    # the project's own file has no default participant: processes on shared memory keep Fast
    # DDS's
    assert not _defaults(project_profile())


def test_udp_with_the_deprecated_localhost_variable_is_the_same() -> None:
    env = {TRANSPORT_VARIABLE: "udp", "ROS_LOCALHOST_ONLY": "1"}
    path = use_project_profile(env)
    assert _participant(path).get("profile_name") == LOOPBACK_PARTICIPANT
    assert env["ROS_AUTOMATIC_DISCOVERY_RANGE"] == "SYSTEM_DEFAULT"
    assert "ROS_LOCALHOST_ONLY" not in env


@pytest.mark.parametrize("scope", ["SUBNET", "SYSTEM_DEFAULT", None])
def test_udp_with_another_range_sets_the_builtin_transports(scope) -> None:
    env = {TRANSPORT_VARIABLE: "udp"} | ({"ROS_AUTOMATIC_DISCOVERY_RANGE": scope} if scope else {})
    assert use_project_profile(env) == project_profile()
    assert env["FASTDDS_BUILTIN_TRANSPORTS"] == "UDPv4"
    assert env.get("ROS_AUTOMATIC_DISCOVERY_RANGE") == scope


def test_udp_is_refused_with_a_profile_of_the_users(tmp_path) -> None:
    env = {TRANSPORT_VARIABLE: "udp", PROFILE_VARIABLES[1]: str(tmp_path / "mine.xml")}
    with pytest.raises(TransportError, match="profile file of your own"):
        use_project_profile(env)


def _writer(transport: str | None) -> tuple[int, str, str]:
    """Run the writer process with ``AMB_TRANSPORT=transport`` (None: unset)."""
    env = {k: v for k, v in os.environ.items() if k not in (*PROFILE_VARIABLES, TRANSPORT_VARIABLE)}
    if transport is not None:
        env[TRANSPORT_VARIABLE] = transport
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        out, err = writer.communicate(timeout=120.0)
    except subprocess.TimeoutExpired:
        writer.kill()
        out, err = writer.communicate()
    return writer.returncode, out, err


@pytest.mark.slow
@pytest.mark.parametrize("transport", [None, "udp"])
def test_a_writer_off_shared_memory_reaches_an_ordinary_reader(ros, transport) -> None:
    node = ros.node("amb_test_off_shm_reader")
    received: list[str] = []
    qos = QoSProfile(
        depth=1, history=HistoryPolicy.KEEP_ALL, reliability=ReliabilityPolicy.RELIABLE
    )
    node.create_subscription(String, TOPIC, lambda m: received.append(m.data), qos)
    done: list[tuple[int, str, str]] = []
    thread = threading.Thread(target=lambda: done.append(_writer(transport)), daemon=True)
    thread.start()
    assert ros.spin_until(lambda: bool(done), 150.0), "the writer process did not end"
    code, out, err = done[0]
    assert code == 0, f"writer failed:\n{out}\n{err}"
    threads = out.split("threads", 1)[1].split()
    shm = [t for t in threads if t.startswith("dds.shm")]
    assert any(t.startswith("dds.udp") for t in threads), threads
    if transport == "udp":
        assert not shm, f"AMB_TRANSPORT=udp, yet shared-memory threads {shm}:\n{err}"
    else:  # the premise: an ordinary process of these wheels listens on shared memory
        assert shm, threads
    assert ros.spin_until(lambda: len(received) >= MESSAGES, 10.0), received
    assert received == [str(k) for k in range(MESSAGES)]
