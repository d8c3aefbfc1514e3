"""Every amb_msgs type crosses real DDS between two processes intact, field by field."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from msg_fill import diff, random_message, to_plain
from relay import QOS, message_classes

pytestmark = pytest.mark.ros

RELAY = str(Path(__file__).resolve().parents[1] / "support" / "relay.py")
N_MESSAGES = 5


def test_the_message_set_covers_the_contract() -> None:
    names = {cls.__name__ for cls in message_classes()}
    assert names == {
        "Measurement",
        "CoefficientSet",
        "WaveletCoefficients",
        "AxisCoefficients",
        "ControlCommand",
        "ControllerStatus",
        "FaultEvent",
    }


def test_fault_types_include_the_contract_classes() -> None:
    from amb_msgs.msg import FaultEvent

    names = ("UNKNOWN", "MASS_LOSS", "AUX_BEARING_CONTACT", "SENSOR_FAULT", "BASE_MOTION")
    values = [getattr(FaultEvent, name) for name in names]
    assert all(isinstance(v, int) for v in values)
    assert len(set(values)) == len(values), f"fault type constants collide: {values}"


def test_every_type_round_trips_through_another_process(ros, node_process) -> None:
    relay = node_process(RELAY)
    node = ros.node("amb_test_sender")
    received: dict[str, list] = {}
    pubs = {}
    subs = {}
    for cls in message_classes():
        name = cls.__name__
        received[name] = []
        pubs[name] = node.create_publisher(cls, f"/amb_test/in/{name}", QOS)
        subs[name] = node.create_subscription(
            cls, f"/amb_test/out/{name}", received[name].append, QOS
        )
    # our writers matched to the relay's readers (their own count: what we send before is lost)
    # and the relay seen by our readers; the relay holds what it receives until its own writer
    # has matched our reader (support/relay.py)
    discovered = ros.spin_until(
        lambda: (
            all(p.get_subscription_count() > 0 for p in pubs.values())
            and all(s.get_publisher_count() > 0 for s in subs.values())
        ),
        timeout=30.0,
    )
    assert discovered, f"relay process not discovered; its log:\n{relay.log()}"

    rng = np.random.default_rng(7)
    sent = {}
    for cls in message_classes():
        sent[cls.__name__] = [random_message(cls, rng) for _ in range(N_MESSAGES)]
        for msg in sent[cls.__name__]:
            pubs[cls.__name__].publish(msg)
    complete = ros.spin_until(
        lambda: all(len(received[n]) == N_MESSAGES for n in sent), timeout=30.0
    )
    assert complete, {n: len(v) for n, v in received.items() if len(v) != N_MESSAGES}
    for name, msgs in sent.items():
        for i, (a, b) in enumerate(zip(msgs, received[name], strict=True)):
            assert diff(to_plain(a), to_plain(b)) == [], f"{name}[{i}] changed in transit"
