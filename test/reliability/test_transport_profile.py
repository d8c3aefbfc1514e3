"""The nodes' Fast DDS profile: reliable writers ask for acknowledgements every 20 ms, not 3 s.

A reliable Fast DDS writer learns what a reader lacks, and resends it, when the reader answers
its heartbeat (``amb_tools.transport_profile``). A writer's ``wait_for_all_acked`` after one
publish lasts until the next heartbeat, so it measures the period the writer runs with: with
Fast DDS's defaults 2.70-3.01 s (``docs/history.md``, "Fast DDS's heartbeat period"; 2.9-3.0 s
again on 2026-12-05 with an empty profile in place of the project's), with the project's
profile the 20 ms period plus the transport. The writer is a process started as the node
executables start (:func:`use_project_profile` before ``rclpy.init``), the reader this test's.
"""

from __future__ import annotations

import os
import subprocess
import sys
import xml.etree.ElementTree as ET

import pytest
from std_msgs.msg import String
from writer_process import writer_script

from amb_tools.transport_profile import PROFILE_VARIABLES, project_profile, use_project_profile

pytestmark = [pytest.mark.ros]

TOPIC = "/amb_test/transport_profile"
PUBLISHES = 5
WRITER = writer_script(
    "amb_test_profile_writer",
    TOPIC,
    "depth=10",
    f"""
waits = []
for k in range({PUBLISHES}):
    pub.publish(String(data=str(k)))
    t0 = time.monotonic()
    if not pub.wait_for_all_acked(Duration(seconds=10.0)):
        sys.exit("not acknowledged in 10 s")
    waits.append(time.monotonic() - t0)
print("waits", *waits, flush=True)
""",
)


def test_the_project_profile_is_chosen_unless_the_user_chose_one(tmp_path) -> None:
    env: dict[str, str] = {}
    assert use_project_profile(env) == project_profile()
    assert env == {PROFILE_VARIABLES[0]: str(project_profile())}
    period = ET.parse(project_profile()).getroot().find(".//{*}heartbeatPeriod")
    assert period is not None, "the profile sets the writers' heartbeat period"
    seconds = int(period.findtext("{*}sec")) + int(period.findtext("{*}nanosec")) * 1e-9
    assert 0 < seconds <= 0.05
    for name in PROFILE_VARIABLES:
        own = {name: str(tmp_path / "mine.xml")}
        assert use_project_profile(own) == tmp_path / "mine.xml"
        assert own == {name: str(tmp_path / "mine.xml")}, "a user's profile is left alone"


@pytest.mark.slow
def test_a_node_process_writer_is_acknowledged_within_its_short_heartbeat(ros) -> None:
    node = ros.node("amb_test_profile_reader")
    received: list[str] = []
    node.create_subscription(String, TOPIC, lambda m: received.append(m.data), 10)
    env = {k: v for k, v in os.environ.items() if k not in PROFILE_VARIABLES}
    writer = subprocess.Popen(
        [sys.executable, "-c", WRITER], env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE,
        text=True,
    )  # fmt: skip
    try:
        ros.spin_until(lambda: writer.poll() is not None, 90.0)
    finally:
        if writer.poll() is None:
            writer.kill()
        out, err = writer.communicate()
    assert writer.returncode == 0, f"writer failed:\n{out}\n{err}"
    waits = sorted(float(w) for w in out.split("waits", 1)[1].split())
    assert len(waits) == PUBLISHES
    # 3 s between heartbeats by default, 20 ms with the profile: the median far below either
    # end, whatever the machine's load (a loaded writer or reader adds milliseconds)
    assert waits[PUBLISHES // 2] < 0.5, f"acknowledged after {waits} s:\n{err}"
    assert received == [str(k) for k in range(PUBLISHES)]
