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
                             "value": 0, "what": "impossible bound",
                             "why_not": "a response takes  time\n to settle"},
                        ],
                    }
                ]
            }
        )
    )  # fmt: skip
    out = tmp_path / "out"
    assert main(["--out", str(out), "--manifest", str(manifest), "--skip-faults"]) == 0
    index = (out / "index.md").read_text()
    # the summary names the check not reproduced and its reason, on one line
    why = "**impossible bound**: a response takes time to settle"
    assert f"| [small mass loss](#small) | 1 of 2 | {why} |" in index
    assert "| halved |" in index and "| yes |" in index
    assert "| impossible bound |" in index and "| NO |" in index
    assert (out / "small" / "report" / "displacement.png").is_file()
    assert (out / "small" / "model.npz").is_file()


def _sensor(ratio, final, measured_s, predicted_s) -> dict:
    return {"amplitude_ratio": ratio, "measured_final_1x": final,
            "measured_settling_s": measured_s, "predicted_settling_s": predicted_s}  # fmt: skip


def test_prediction_metrics_read_amb_predictions_summary() -> None:
    # a summary as amb-prediction writes it: the worst sensor's amplitude error, and the lead
    # of the prediction over the measured response (each sensor's settling times from the step)
    from amb_apps.reproduce import prediction_metrics

    summary = {
        "sensors": {
            "x1": _sensor(1.04, 400e-6, 0.25, 0.30),
            "x2": _sensor(0.93, 100e-6, 0.40, 0.35),
            # near a node (2 % of the largest): its ratio and its slow settling are left out
            "x3": _sensor(2.3, 8e-6, 1.5, 0.4),
        },
    }
    m = prediction_metrics(summary)
    assert m["amplitude_error"] == pytest.approx(0.07, abs=1e-12)
    # the slowest of x1 and x2: measured 0.40 s, predicted 0.35 s
    assert m["measured_settling_s"] == 0.40 and m["predicted_settling_s"] == 0.35
    assert m["settling_lead_s"] == pytest.approx(0.05, abs=1e-12)
    # never settled, or no measured amplitude: the checks must fail, not pass on a None
    m = prediction_metrics({"sensors": {"x1": _sensor(None, 0.0, 1.0, None)}})
    assert m["amplitude_error"] == float("inf")
    assert m["settling_lead_s"] == float("-inf")


def test_rebound_is_the_rise_after_the_first_fall() -> None:
    from amb_apps.reproduce import rebound

    assert rebound([1.0, 3.0, 2.0, 1.5, 1.0]) == 0.0  # falls without rising again
    assert rebound([1.0, 2.0, 3.0, 3.0]) == 0.0  # grows to its peak and stays
    # peak 4; falls to 1, climbs back to 3: half the peak
    assert rebound([2.0, 4.0, 1.0, 3.0, 2.0]) == pytest.approx(0.5, abs=1e-15)
    # the rise counts from the lowest point before it, not from the peak
    assert rebound([4.0, 2.0, 3.0, 1.0, 2.5]) == pytest.approx(0.375, abs=1e-15)
    assert rebound([]) == 0.0 and rebound([0.0, 0.0]) == 0.0


def test_index_says_why_a_check_failed_and_prints_bounds_in_their_unit(tmp_path) -> None:
    from amb_apps.reproduce import _checks, fault_metrics
    from amb_apps.reproduce_index import write_index

    exp = {
        "id": "ex", "title": "an experiment", "figures": "8.1", "thesis": "it works",
        "checks": [
            {"run": "a", "metric": "steady_1x_inner", "op": "<=", "value": 1e-5,
             "what": "below 10 um", "why_not": "never here"},
            {"run": "a", "metric": "peak_inner", "op": "<=", "value": 1e-3,
             "what": "below 1 mm", "why_not": "shown only if it fails"},
        ],
    }  # fmt: skip
    faults = {
        "id": "f", "kind": "faults", "title": "faults", "figures": "5.1", "thesis": "found",
        "checks": [
            {"run": "haar", "metric": "misclassified", "op": "<=", "value": 0, "what": "all"},
            {"run": "haar", "metric": "false_alarms", "op": "<=", "value": 0, "what": "none"},
        ],
    }  # fmt: skip
    results = {"a": {"steady_1x_inner": 2.9e-5, "peak_inner": 1.1e-4, "settling": 15,
                     "rebound": 0.01, "peak_wavelet_force": 44.0, "contacts": 0,
                     "model_radius": None}}  # fmt: skip
    summary = {  # one wavelet's part of amb-fault-eval --json, two of three mass losses right
        "total": 3, "correct": 2, "false_alarms": 1, "simulated_s": 12.0,
        "confusion": {"MASS_LOSS": {"MASS_LOSS": 2, "SENSOR_FAULT": 1}},
        "delays": {"MASS_LOSS": {"detection_ms_median": 2.5, "detection_revs_max": 0.1,
                                 "decision_revs_median": 8.0, "decision_revs_max": 9.5,
                                 "onset_error_abs_supports_max": 1.0}},
    }  # fmt: skip
    assert fault_metrics(summary) == {"misclassified": 1, "false_alarms": 1}
    done = {
        "ex": {"results": results, "checks": _checks(exp, results), "folder": tmp_path / "ex"},
        "f": {"results": {"haar": fault_metrics(summary)},
              "checks": _checks(faults, {"haar": fault_metrics(summary)}),
              "folder": tmp_path / "f", "summaries": {"haar": summary}},
    }  # fmt: skip
    broken = {"id": "b", "title": "a broken run", "figures": "7.1", "thesis": "-", "checks": []}
    manifest = {"experiments": [exp, faults, broken]}
    freq = {"critical": ([11.0, 18.0], [9.9, 18.9])}
    index = write_index(tmp_path, manifest, done, {"b": "amb-sim failed (1);\n see b.log"}, freq)
    index = index.read_text()
    assert "| critical speeds | 11 / 18 | 9.90 / 18.90 | -10.0 % / +5.0 % |" in index
    assert "| a broken run | run failed | amb-sim failed (1); see b.log |" in index
    assert "| [an experiment](#ex) | 1 of 2 | **below 10 um**: never here |" in index
    assert "shown only if it fails" not in index
    assert "| below 10 um | 29.0 µm | <= 10.0 µm | NO |" in index
    why = "**all**: no reason recorded<br>**none**: no reason recorded"
    assert f"| [faults](#f) | 0 of 2 | {why} |" in index
    row = "| haar | MASS_LOSS | 3 | 2 | 2.5 ms / 0.10 rev | 8.0 / 9.5 rev | 1.0 supports |"
    assert row in index
    assert "false alarms: 1 in 12 s" in index


def test_model_frequencies_are_the_rig_model_s_own() -> None:
    from amb_apps.reproduce import model_frequencies
    from amb_common.rig import load_rig
    from amb_plant_sim.modal import critical_speeds, natural_frequencies

    got = model_frequencies()
    rig = load_rig()
    assert got["natural"] == ([11.0, 18.0, 29.0, 67.0], natural_frequencies(rig, 4))
    assert got["critical"] == ([11.0, 18.0, 29.0], critical_speeds(rig, 3))
