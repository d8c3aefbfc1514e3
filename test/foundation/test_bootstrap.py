"""The bootstrap is idempotent: a second run with nothing changed installs and builds nothing."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _tree_mtimes(folder: Path) -> dict[str, int]:
    return {str(p): p.lstat().st_mtime_ns for p in folder.rglob("*")}


def test_second_bootstrap_run_installs_and_builds_nothing() -> None:
    env = {k: v for k, v in os.environ.items() if k != "FORCE"}
    first = subprocess.run(
        ["bash", "tools/bootstrap.sh"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert first.returncode == 0, first.stderr
    install_before = _tree_mtimes(ROOT / "install")
    second = subprocess.run(
        ["bash", "tools/bootstrap.sh"], cwd=ROOT, env=env, capture_output=True, text=True
    )
    assert second.returncode == 0, second.stderr
    assert "installing" not in second.stdout and "colcon build" not in second.stdout, second.stdout
    assert "ready" in second.stdout
    assert _tree_mtimes(ROOT / "install") == install_before
