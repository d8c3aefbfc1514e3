"""amb-run's end: the nodes drained, even when the plant's final report was missed; the bag full.

``/diagnostics`` is volatile: a run short enough to end before amb-run's reader is matched to
the plant's writer leaves amb-run without the plant's final count (``make demo`` failed so
once: "the plant's final report was not received"). The plant logs the same count when it
completes; amb-run reads it from the plant's log. Here amb-run's drain runs on its own: the
report reader is a stand-in holding what the other nodes reported, the node processes are
real processes, the plant's log a file.

Then the recorder is waited for until its counts reach what every publisher reports as
published: a fixed grace before stopping it once lost the controller's last command (77 of 78 in
the bag; ``test_composed.py`` in a loaded suite).
"""

from __future__ import annotations

import subprocess
import sys

import pytest

from amb_apps.run_end import DRAINED, drain, plant_samples, settle_recording
from amb_apps.run_processes import NodeRun

PLANT_LINE = (
    "[INFO] [1.0] [plant_sim]: scenario x complete at t = 8.0250 s (4992 samples) in 2.10 s "
    "wall, real-time factor 3.82; commands: applied 154, missing 0\n"
)


class _Reports:
    """What amb-run's /diagnostics reader holds: the plant's last report and the nodes'.

    ``recorded``: the recorder's counts per topic, one report per ``spin`` (the last repeated).
    """

    namespace = "/"

    def __init__(
        self,
        plant: dict[str, str],
        processed: int,
        nodes: dict[str, dict[str, str]] | None = None,
        recorded: list[dict[str, str]] | None = None,
    ) -> None:
        self.values = plant
        self._processed = processed
        self._nodes = nodes or {}
        self._recorded = list(recorded or [])
        self.spins = 0

    def spin(self, seconds: float) -> None:
        self.spins += 1
        if len(self._recorded) > 1:
            self._recorded.pop(0)

    def processed(self, name: str, key: str) -> int:
        return self._processed

    def report(self, name: str) -> dict[str, str]:
        if name == "recorder":
            return self._recorded[0] if self._recorded else {}
        return self._nodes.get(name, {})


def _drain(reports: _Reports, runs, **kw) -> int:
    """amb-run's end: the plant's count (its report, else its log), then the drain."""
    return drain(reports, runs, plant_samples(reports, runs), **kw)


@pytest.fixture
def runs(tmp_path):
    out = []
    for name in ("plant_sim", *DRAINED, "recorder"):
        run = NodeRun(name, [], tmp_path / f"{name}.log")
        run.log_path.write_text("")
        if name != "plant_sim":  # the drained nodes and the recorder still run
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


PUBLISHERS = {
    "wavelet_filterbank": {"messages_published": "2496"},
    "wavelet_controller": {"commands_published": "154", "statuses_published": "154"},
    "fault_monitor": {"events_published": "1"},
}
COMPLETE = {
    "/amb/measurement": "4992",
    "/amb/wavelet/coefficients": "2496",
    "/amb/control/command": "154",
    "/amb/control/status": "154",
    "/amb/fault/events": "1",
}


def test_the_recorder_is_waited_for_until_it_wrote_every_published_message(runs, capsys) -> None:
    short = {**COMPLETE, "/amb/control/command": "153"}  # the last command still on its way
    reports = _Reports({}, 4991, PUBLISHERS, [{}, short, short, COMPLETE])
    assert settle_recording(reports, runs, 4992, timeout=5.0, quiet=False) == 0
    assert reports.spins >= 3  # the two short reports were waited out
    assert "bag complete" in capsys.readouterr().out


def test_a_recording_left_short_fails_the_run_and_names_the_topic(runs, capsys) -> None:
    short = {**COMPLETE, "/amb/control/command": "153"}
    reports = _Reports({}, 4991, PUBLISHERS, [short])
    assert settle_recording(reports, runs, 4992, timeout=0.5, quiet=True) == 1
    assert "/amb/control/command 153 of 154" in capsys.readouterr().err


def test_no_recorder_nothing_to_wait_for(runs) -> None:
    without = [r for r in runs if r.name != "recorder"]
    assert settle_recording(_Reports({}, 4991, PUBLISHERS, []), without, 4992, 0.5, True) == 0
