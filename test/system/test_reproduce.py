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


def test_prediction_metrics_read_amb_predictions_summary() -> None:
    # a summary as amb-prediction writes it: the worst sensor's amplitude error, and the lead
    # of the prediction over the measured response (both settling times from the step)
    from amb_apps.reproduce import prediction_metrics

    summary = {
        "sensors": {
            "x1": {"amplitude_ratio": 1.04, "measured_final_1x": 400e-6},
            "x2": {"amplitude_ratio": 0.93, "measured_final_1x": 100e-6},
            # near a node (2 % of the largest): its ratio is left out
            "x3": {"amplitude_ratio": 2.3, "measured_final_1x": 8e-6},
        },
        "measured_settling_s": 1.5,
        "predicted_settling_s": 0.4,
    }
    m = prediction_metrics(summary)
    assert m["amplitude_error"] == pytest.approx(0.07, abs=1e-12)
    assert m["settling_lead_s"] == pytest.approx(1.1, abs=1e-12)
    # never settled, or no measured amplitude: the checks must fail, not pass on a None
    m = prediction_metrics(
        {"sensors": {"x1": {"amplitude_ratio": None, "measured_final_1x": 0.0}},
         "measured_settling_s": 1.0,
         "predicted_settling_s": None}
    )  # fmt: skip
    assert m["amplitude_error"] == float("inf")
    assert m["settling_lead_s"] == float("-inf")
