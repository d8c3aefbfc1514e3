"""Shared fixtures of the plant core tests."""

from pathlib import Path

import pytest

from amb_common.rig import load_rig

RIG_PATH = Path(__file__).resolve().parents[2] / "config" / "rig.yaml"


@pytest.fixture(scope="session")
def rig():
    """The calibrated thesis rig from config/rig.yaml."""
    return load_rig(RIG_PATH)
