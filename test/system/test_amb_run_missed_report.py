"""amb-run drains the nodes even when the plant's final /diagnostics report was missed.

``/diagnostics`` is volatile: a run short enough to end before amb-run's reader is matched to
the plant's writer leaves amb-run without the plant's final count (``make demo`` failed so
once: "the plant's final report was not received"). The plant logs the same count when it
completes; amb-run reads it from the plant's log. Here amb-run's drain runs on its own: the
report reader is a stand-in holding what the other nodes reported, the node processes are
real processes, the plant's log a file.
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from amb_apps.run_cli import DRAINED, NodeRun, _drain

PLANT_LINE = (
    "[INFO] [1.0] [plant_sim]: scenario x complete at t = 8.0250 s (4992 samples) in 2.10 s "
    "wall, real-time factor 3.82; commands: applied 154, missing 0\n"
)


class _Reports:
    """What amb-run's /diagnostics reader holds: the plant's last report and the nodes'."""

    def __init__(self, plant: dict[str, str], processed: int) -> None:
        self.values = plant
        self._processed = processed

    def spin(self, seconds: float) -> None:
        pass

    def processed(self, name: str, key: str) -> int:
        return self._processed


@pytest.fixture
def runs(tmp_path):
    out = []
    for name in ("plant_sim", *DRAINED):
        run = NodeRun(name, [], tmp_path / f"{name}.log")
        run.log_path.write_text("")
        if name != "plant_sim":  # the drained nodes still run
            run.proc = subprocess.Popen([sys.executable, "-c", "import time; time.sleep(30)"])
        out.append(run)
    yield out
    for run in out:
        if run.proc is not None:
            run.proc.kill()
            run.proc.wait()


def test_count_read_from_the_plant_log_when_the_report_was_missed(runs, capsys) -> None:
    runs[0].log_path.write_text(PLANT_LINE)
    assert _drain(_Reports({}, processed=4991), runs, timeout=5.0, quiet=False) == 0
    assert "plant done at sample 4991" in capsys.readouterr().out


def test_nodes_behind_the_logged_count_are_waited_for(runs, capsys) -> None:
    runs[0].log_path.write_text(PLANT_LINE)
    assert _drain(_Reports({}, processed=4000), runs, timeout=0.5, quiet=True) == 1
    assert "drain timeout" in capsys.readouterr().err


def test_no_report_and_no_completion_line_stops_the_nodes_as_they_are(runs, capsys) -> None:
    assert _drain(_Reports({}, processed=4991), runs, timeout=5.0, quiet=True) == 1
    assert "no completion line" in capsys.readouterr().err


def test_the_report_wins_when_received(runs, capsys) -> None:
    report = {"done": "True", "sample_index": "100"}
    assert _drain(_Reports(report, processed=99), runs, timeout=5.0, quiet=False) == 0
    assert "plant done at sample 99" in capsys.readouterr().out
