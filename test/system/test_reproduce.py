"""`make reproduce` machinery on one small experiment: runs, report, checks, index."""

from __future__ import annotations

import pytest
import yaml

from amb_apps.reproduce import main

SCENARIO = {
    "name": "repro_small",
    "speed": {"hz": 15.0},
    "duration": 3.0,
    "samples_per_rev": 32,
    "measurement_noise": 2.0e-7,
    "events": [
        {"kind": "unbalance", "time": 0.0, "disk": "D1", "me": 0.5e-3, "angle": 0.0},
        {"kind": "mass_loss", "time": 1.0, "disk": "D1", "me": 4.3e-3, "angle": 0.0},
    ],
}


@pytest.mark.slow
def test_reproduce_runs_checks_and_writes_the_index(tmp_path) -> None:
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(SCENARIO))
    manifest = tmp_path / "manifest.yaml"
    manifest.write_text(
        yaml.safe_dump(
            {
                "experiments": [
                    {
                        "id": "small",
                        "title": "small mass loss",
                        "figures": "8.11",
                        "thesis": "suppressed",
                        "scenario": str(scenario),
                        "runs": [
                            {"label": "PID only", "controller": "none"},
                            {"label": "transient", "controller": "transient"},
                        ],
                        "checks": [
                            {"run": "transient", "metric": "steady_1x_inner",
                             "relative_to": "PID only", "op": "<=", "value": 0.5,
                             "what": "halved"},
                            {"run": "transient", "metric": "settling", "op": "<=",
                             "value": 0, "what": "impossible bound"},
                        ],
                    }
                ]
            }
        )
    )  # fmt: skip
    out = tmp_path / "out"
    assert main(["--out", str(out), "--manifest", str(manifest), "--skip-faults"]) == 0
    index = (out / "index.md").read_text()
    assert "| [small mass loss](#small) | 1 of 2 |" in index
    assert "| halved |" in index and "| yes |" in index
    assert "| impossible bound |" in index and "| NO |" in index
    assert (out / "small" / "report" / "displacement.png").is_file()
    assert (out / "small" / "model.npz").is_file()
