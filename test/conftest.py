"""Shared pytest fixtures: an isolated ROS domain per test run, contexts, node processes."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

sys.path.insert(0, str(Path(__file__).resolve().parent / "support"))

from ros_harness import NodeProcess, RosTestContext, claim_domain_id

#: The node processes a test started (read by the report hook below).
STARTED = pytest.StashKey[list]()
#: Characters of each node's log shown with a failure.
LOG_TAIL = 8000


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
def node_process(ros_domain_id: int, tmp_path: Path, request: pytest.FixtureRequest):
    """Start node executables as separate processes; all are stopped at teardown.

    Call ``node_process(executable, params_file=..., params=...)``; see ``NodeProcess``.
    When the test fails, each process's log is attached to its report.
    """
    started: list[NodeProcess] = request.node.stash.setdefault(STARTED, [])

    def start(executable: str, **kwargs) -> NodeProcess:
        proc = NodeProcess(executable, tmp_path, **kwargs)
        started.append(proc)
        return proc

    yield start
    for proc in started:
        proc.stop()


@pytest.hookimpl(wrapper=True)
def pytest_runtest_makereport(item: pytest.Item, call: pytest.CallInfo):
    """Attach the log of every node the test started to a failed (or timed-out) report."""
    report = yield
    if report.failed:
        for proc in item.stash.get(STARTED, []):
            try:
                text = proc.log()
            except OSError as exc:
                text = f"(log unreadable: {exc})"
            if len(text) > LOG_TAIL:
                text = f"... ({len(text) - LOG_TAIL} characters before)\n" + text[-LOG_TAIL:]
            code = proc.proc.poll()
            state = "running" if code is None else f"exit {code}"
            report.sections.append((f"log of {proc.name} ({state}, {proc.log_path})", text))
    return report
