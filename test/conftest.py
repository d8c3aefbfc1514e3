"""Shared pytest fixtures: an isolated ROS domain per test run, contexts, node processes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "support"))

from ros_harness import NodeProcess, RosTestContext, claim_domain_id


@pytest.fixture(scope="session")
def ros_domain_id() -> int:
    """The ROS domain id this test run holds (isolated from other runs on the machine)."""
    return claim_domain_id()


@pytest.fixture
def ros(ros_domain_id: int):
    """A fresh rclpy context with an executor; nodes created through it are torn down."""
    ctx = RosTestContext()
    yield ctx
    ctx.close()


@pytest.fixture
def node_process(ros_domain_id: int, tmp_path: Path):
    """Start node executables as separate processes; all are stopped at teardown.

    Call ``node_process(executable, params_file=..., params=...)``; see ``NodeProcess``.
    """
    started: list[NodeProcess] = []

    def start(executable: str, **kwargs) -> NodeProcess:
        proc = NodeProcess(executable, tmp_path, **kwargs)
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.stop()
