"""Bags for the amb-report tests: two short amb-sim runs of the first-critical mass loss.

The runs are made once per test session (a few seconds each at 32 samples per revolution):
PID + transient wavelet control with the fault monitor, and PID only.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from amb_apps import sim_cli

ROOT = Path(__file__).resolve().parents[2]
SCENARIO = ROOT / "config/scenarios/mass_loss_first_critical.yaml"
SPR = 32
DURATION = 6.0  # the fault monitor decides about 1.2 s after the 4.0 s mass loss


def _sim(out: Path, controller: str, monitor: bool) -> Path:
    args = ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--duration",
            str(DURATION), "--controller", controller, "--out", str(out)]  # fmt: skip
    if controller != "none":
        args += ["--model", "fe"]
    if monitor:
        args.append("--fault-monitor")
    assert sim_cli.main(args) == 0
    return out


@pytest.fixture(scope="session")
def sim_wavelet(tmp_path_factory) -> Path:
    """amb-sim run folder (bag + metrics.json): PID + transient control, fault monitor on."""
    return _sim(tmp_path_factory.mktemp("report_sim") / "wavelet", "transient", True)


@pytest.fixture(scope="session")
def sim_pid(tmp_path_factory) -> Path:
    """amb-sim run folder: PID only, no fault monitor."""
    return _sim(tmp_path_factory.mktemp("report_sim") / "pid", "none", False)


@pytest.fixture(scope="session")
def scenario() -> Path:
    """The scenario file of the amb-sim runs."""
    return SCENARIO


@pytest.fixture(scope="session")
def spr() -> int:
    """Samples per revolution of the amb-sim runs."""
    return SPR
