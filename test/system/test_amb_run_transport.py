"""``amb-run --udp PROCESS`` / ``--shm PROCESS``: a process's DDS transport, or a refusal.

The process gets ``AMB_TRANSPORT=udp`` in its environment (what it then does with it:
``test/reliability/test_off_shared_memory.py``). An unknown process, or one named by both
options, is refused before the run's folder is made; a node started with an unknown transport
stops with the configuration status and the reason.
"""

from __future__ import annotations

import os
import subprocess
import sys

import pytest

from amb_apps.run_cli import build_parser, run
from amb_apps.run_processes import NodeRun, transports
from amb_apps.system import OFF_SHARED_MEMORY
from amb_tools.node_main import EXIT_CONFIGURATION_ERROR
from amb_tools.transport_profile import TRANSPORT_VARIABLE

PROBE = f"import os; print(os.environ.get({TRANSPORT_VARIABLE!r}, 'unset'), flush=True)"


@pytest.mark.parametrize(
    ("options", "reason"),
    [
        (["--udp", "plant"], "expected one of"),
        (["--shm", "stack"], "expected one of"),
        (["--udp", "recorder", "--shm", "recorder"], "named by both --udp and --shm"),
    ],
)
def test_a_bad_transport_item_is_refused_before_anything_is_made(
    tmp_path, options: list[str], reason: str
) -> None:
    out = tmp_path / "run"
    args = build_parser().parse_args(
        ["--scenario", "mass_loss_first_critical.yaml", "--out", str(out), *options]
    )
    with pytest.raises(SystemExit) as refused:
        run(args)
    assert reason in str(refused.value)
    assert not out.exists()


def test_the_options_name_each_process_transport() -> None:
    assert transports([], [])["recorder"] == "udp", "the recorder is off shared memory by default"
    assert transports(["recorder", "wavelet_stack"], []) == {
        **dict.fromkeys(OFF_SHARED_MEMORY, "udp"),
        "recorder": "udp",
        "wavelet_stack": "udp",
    }
    for name in OFF_SHARED_MEMORY:  # a default undone
        assert transports([], [name])[name] == "shm"


@pytest.mark.parametrize(("transport", "seen"), [("udp", "udp"), ("shm", "unset")])
def test_the_process_gets_its_transport_in_its_environment(tmp_path, transport, seen) -> None:
    log = tmp_path / "probe.log"
    env = {k: v for k, v in os.environ.items() if k != TRANSPORT_VARIABLE}
    child = NodeRun("recorder", [sys.executable, "-c", PROBE], log, transport=transport)
    child.start(env)
    assert child.proc.wait(30) == 0, log.read_text()
    child.stop()
    assert log.read_text().split() == [seen]


def test_a_node_started_with_an_unknown_transport_says_why_and_stops() -> None:
    env = {**os.environ, TRANSPORT_VARIABLE: "tcp"}
    code = "from amb_tools.recorder_node import main; raise SystemExit(main())"
    done = subprocess.run(
        [sys.executable, "-c", code], env=env, capture_output=True, text=True, timeout=120
    )
    assert done.returncode == EXIT_CONFIGURATION_ERROR, done.stdout + done.stderr
    assert "AMB_TRANSPORT='tcp': expected one of ('shm', 'udp')" in done.stderr
