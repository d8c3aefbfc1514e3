"""Shared pieces of the reliability tests: diagnostics, parameter calls, a scenario's model."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import yaml
from diagnostic_msgs.msg import DiagnosticArray

from amb_tools.streams import MATCHED_KEY


class Diagnostics:
    """Latest ``/diagnostics`` key/values and message per status name."""

    def __init__(self, node) -> None:
        self.values: dict[str, dict[str, str]] = {}
        self.messages: dict[str, str] = {}
        self.levels: dict[str, int] = {}
        node.create_subscription(DiagnosticArray, "/diagnostics", self._on, 50)

    def _on(self, msg: DiagnosticArray) -> None:
        for s in msg.status:
            self.values[s.name] = {kv.key: kv.value for kv in s.values}
            self.messages[s.name] = s.message
            self.levels[s.name] = int.from_bytes(s.level) if isinstance(s.level, bytes) else s.level

    def get(self, name: str, key: str, default: str = "") -> str:
        return self.values.get(name, {}).get(key, default)

    def number(self, name: str, key: str) -> int:
        return int(self.get(name, key, "0"))

    def matched(self, name: str, topic: str) -> int:
        """Readers node ``name``'s writer of ``topic`` has matched, as it reported (-1: none).

        The writer's own count (``amb_tools.streams.matched_subscribers``): what it publishes
        from then on reaches them. The graph seen by the test's participant does not say that;
        under load a writer was seen to match a reader seconds after the test saw both.
        """
        return int(self.get(name, MATCHED_KEY + topic, "-1"))


def missing_runs(indices, total: int, shown: int = 8) -> str:
    """The sample indices in ``0..total-1`` not in ``indices``, as runs ``first-last (count)``.

    For a failure message: where an observer lost samples (one long run: held or fed nothing
    for a while; many short ones: a reader that fell behind over and over).
    """
    missing = sorted(set(range(total)) - {int(i) for i in indices})
    runs: list[list[int]] = []
    for k in missing:
        if runs and k == runs[-1][1] + 1:
            runs[-1][1] = k
        else:
            runs.append([k, k])
    text = ", ".join(f"{a}-{b} ({b - a + 1})" for a, b in runs[:shown])
    more = f", and {len(runs) - shown} more runs" if len(runs) > shown else ""
    return f"{len(runs)} runs missing: {text}{more}" if runs else "none missing"


def subscribed_by(node, topic: str, name: str) -> bool:
    """Whether a node called ``name`` subscribes ``topic``, in the graph ``node`` sees."""
    return name in {i.node_name for i in node.get_subscriptions_info_by_topic(topic)}


def call_service(ros, client, request, attempts: int = 4, wait: float = 5.0):
    """
    Call a service and return its response, asking again if no response comes in ``wait`` s.

    Fast DDS drops a service's response when the client's response reader has not been
    matched 100 ms after the request arrived (rmw_fastrtps PR 467, 704: "failed to send
    response (timeout): client will not receive response"); ``wait_for_service`` only says that
    the request side is matched. Seen under load (a core kept busy) on the parameter services.
    The services called here are idempotent (set / get parameters), so asking again is safe.
    """
    for _ in range(attempts):
        future = client.call_async(request)
        if ros.spin_until(future.done, wait):
            return future.result()
        client.remove_pending_request(future)
    raise AssertionError(f"{client.srv_name}: no response in {attempts} calls of {wait} s")


def set_parameters(ros, node, target: str, params: dict):
    """Call ``/<target>/set_parameters``; return the list of ``SetParametersResult``."""
    from rcl_interfaces.srv import SetParameters
    from rclpy.parameter import Parameter

    client = node.create_client(SetParameters, f"/{target}/set_parameters")
    assert client.wait_for_service(timeout_sec=20.0), f"/{target}/set_parameters not available"
    request = SetParameters.Request(
        parameters=[Parameter(k, value=v).to_parameter_msg() for k, v in params.items()]
    )
    return call_service(ros, client, request).results


def get_parameter(ros, node, target: str, name: str):
    """Call ``/<target>/get_parameters`` for one name; return its Python value."""
    from rcl_interfaces.srv import GetParameters
    from rclpy.parameter import parameter_value_to_python

    client = node.create_client(GetParameters, f"/{target}/get_parameters")
    assert client.wait_for_service(timeout_sec=20.0)
    response = call_service(ros, client, GetParameters.Request(names=[name]))
    return parameter_value_to_python(response.values[0])


def fe_model_file(scenario: dict, tmp_path: Path) -> tuple[Path, Path]:
    """
    Write ``scenario`` to ``tmp_path/scenario.yaml``; build its FE-route model with ``amb-sim``.

    Returns
    -------
    tuple of Path
        The scenario file and ``tmp_path/model/model.npz`` (the transient controller's model
        for the scenario's speed, as ``wavelet_controller`` loads it).
    """
    path = tmp_path / "scenario.yaml"
    path.write_text(yaml.safe_dump(scenario))
    run = subprocess.run(
        [sys.executable, "-m", "amb_apps.sim_cli", "--scenario", str(path),
         "--controller", "transient", "--model", "fe", "--duration", "0.3", "--no-bag",
         "--out", str(tmp_path / "model")],
        capture_output=True, text=True, timeout=300,
    )  # fmt: skip
    assert run.returncode == 0, run.stderr
    return path, tmp_path / "model" / "model.npz"
