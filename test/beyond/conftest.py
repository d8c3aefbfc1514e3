"""Shared fixtures of the beyond-the-thesis tests: the rig and resolved scenarios (cached)."""

from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
SCENARIOS = ROOT / "config" / "scenarios"


@pytest.fixture(scope="session")
def rig():
    from amb_common.rig import load_rig

    return load_rig()


@pytest.fixture(scope="session")
def first_critical(rig):
    from amb_plant_sim.scenario import load_scenario

    return load_scenario(SCENARIOS / "mass_loss_first_critical.yaml", rig)
