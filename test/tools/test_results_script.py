"""tools/results.py: its parsers on the output formats of the real commands, its failures, and
the anchors of docs/results.md that the code cites.

The samples below are what the commands print: amb-modal's text and python -m timeit's line as
captured from real runs; the others built with the format strings of the code that prints them
(bench/pipeline.py ``_row``, bench/plant_sim.py ``main``, amb-run's drain lines, the plant's
completion log line, tools/demo.sh with amb-report's comparison.md, the JSON of amb-prediction,
amb-fault-eval and amb-compare).
"""

from __future__ import annotations

import importlib.util
import json
import re
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
# The script's modules import each other by name, as when it runs (its directory on sys.path).
sys.path.insert(0, str(ROOT / "tools"))


def _load():
    spec = importlib.util.spec_from_file_location("amb_results_script", ROOT / "tools/results.py")
    module = importlib.util.module_from_spec(spec)
    sys.modules[spec.name] = module  # dataclasses look their module up
    spec.loader.exec_module(module)
    return module


R = _load()
C = importlib.import_module("results_commands")
P = importlib.import_module("results_parsers")
S = importlib.import_module("results_sections")

MODAL = """\
rig: /work/wt_facts/config/rig.yaml  model: pid_closed_loop  elements: 14
speed 0.00 Hz
  mode  1:     9.653 Hz  damping 0.1594  planar
  mode  2:    16.674 Hz  damping 0.1238  planar
  mode  3:    31.442 Hz  damping 0.1520  planar
  mode  4:    74.357 Hz  damping 0.1048  planar
critical speeds (Hz): 9.719, 16.735, 32.065, 77.680
sensitivity b1x: peak 9.373 (19.44 dB) at 9.3 Hz, ISO 14839-3 zone D
sensitivity b2y: peak 9.553 (19.60 dB) at 9.3 Hz, ISO 14839-3 zone D
"""

PLANT_BENCH = """\
plant core benchmark: 14 elements, internal rate >= 5000 Hz, 2.0 s simulated, median of 3, \
OPENBLAS_NUM_THREADS=1
case                                x real time  build s  stepwise  contact
11 Hz, 64 samples/rev, no contact          31.2    0.512      0.0%        0
11 Hz, 64 samples/rev, contact              2.5    0.001      3.1%      412
67 Hz, 32 samples/rev, no contact          25.0    0.400      0.0%        0
67 Hz, 32 samples/rev, contact              3.1    0.001      1.2%      150
ratio 11 Hz / 67 Hz without contact (same run): 1.25
target >= 20x real time without contact: met
"""

# bench/pipeline.py's output, as printed (--composed, 2026-12-06)
PIPELINE_BENCH = "\n".join(
    [
        "      case / run  lockstep RTF  rt p50 ms   p99 ms  p99/period  controlled  arr p99 ms"
        "  missing  late  partial  samples ctl  pub max ms  write max ms   load",
        "   67 Hz x 32 #1          5.97       1.76     3.21       21.5%      100.0%      -12.14"
        "        0     0        0       100.0%        8.43          0.73    0.8",
        "   11 Hz x 64 #1         20.73       1.32     1.63        1.8%      100.0%      -90.68"
        "        0     0        0       100.0%        6.42          7.43    0.8",
        "targets (#17): lock-step RTF >= 2 at 67 Hz x 32, >= 3 at 11 Hz x 64; realtime: 0 "
        "missing, 0 late, p99 <= 50% of the period",
    ]
)

PIPELINE_HOG = (
    "   67 Hz x 32 #1          6.15       1.51     3.26       21.8%      100.0%      -12.02"
    "        0     0        0       100.0%        5.02          4.15    1.1   7.1-11.1  "
    " 100.0%  100.0%   100.0%  100.0%      0.0     0\n"
)

RUN_STDOUT = """\
[amb-run] mass_loss_first_critical: starting plant_sim, wavelet_filterbank, fault_monitor
[amb-run] t_sim =    7.900 s  wall =    95.0 s  real-time factor =  0.09  commands missing 0
[amb-run] plant done at sample 4975; fault_monitor last_sample 3055, fault_monitor \
last_coefficient_sample -
[amb-run] draining (  1.0 s): fault_monitor last_sample 3120, fault_monitor \
last_coefficient_sample 3119 of 4975
[amb-run] drained in 35.2 s: every node processed the plant's last sample 4975 \
(wavelet_filterbank last_sample 4975, wavelet_controller last_sample 4975, fault_monitor \
last_sample 4975, fault_monitor last_coefficient_sample 4975)
[amb-run] done in 140.3 s wall; bag: /tmp/x/bag; logs: /tmp/x/logs
"""

PLANT_LOG = (
    "[INFO] [1764000000.123456789] [plant_sim]: scenario mass_loss_first_critical complete at "
    "t = 8.0000 s (4976 samples) in 96.21 s wall, real-time factor 0.08; commands: applied 4974, "
    "missing 0, late 0, rejected 0\n"
)

DEMO_STDOUT = """\
[demo] 4/4 report

# Key metrics side by side

Fault time per bag: PID only: 3 s (scenario); PID + wavelet transient: 3 s (scenario). \
Definitions: `amb_controller/metrics.py` (...).

| metric | PID only | PID + wavelet transient | PID + wavelet transient / PID only |
|---|---:|---:|---:|
| steady 1 x amplitude at x2 (µm) | 40.1 | 3.2 | 0.080 |
| peak after the fault at x2 (µm) | 120.5 | 95.0 | 0.788 |
[demo] report: out/demo/report/report.md (figures and metrics.json beside it)
[demo] done in 74 s
"""


def _delays(n: int, onset: float) -> dict:
    return {
        "n": n,
        "detection_ms_median": 12.5,
        "detection_ms_max": 30.0,
        "detection_revs_max": 0.875,
        "decision_revs_median": 16.0,
        "decision_revs_max": 20.0,
        "onset_error_ms_median": 0.4,
        "onset_error_abs_supports_max": onset,
    }


def _summary(onset: float) -> dict:
    return {
        "confusion": {"MASS_LOSS": {"MASS_LOSS": 9}},
        "delays": {"MASS_LOSS": _delays(9, onset)},
        "false_alarms": 0,
        "simulated_s": 410.0,
        "false_alarms_per_hour": 0.0,
        "correct": 41,
        "total": 41,
        "before_calibration": 0,
        "cases": [],
        "first_answers": {
            "total": 54, "correct": 50, "correct_in_time": 46, "cases": 48, "cases_in_time": 45,
            "provisional": 41, "revised": 3, "false_alarms": 0,
        },
    }  # fmt: skip


FAULT_EVAL = json.dumps(
    {"wavelets": {w: _summary(o) for w, o in (("haar", 1.0), ("db2", 0.75), ("db4", 0.875))}},
    indent=2,
)

PREDICTION = json.dumps(
    {
        w: {
            "sensors": {
                f"x{k}": {
                    "measured_settling_s": 0.5,
                    "predicted_settling_s": 0.364,
                    "measured_final_1x": 8e-6,
                    "predicted_final_1x": 7.5e-6,
                    "amplitude_ratio": 0.94,
                }
                for k in (1, 2, 3, 4)
            },
            "measured_settling_s": 0.545,
            "predicted_settling_s": None if w == "db4" else 0.364,
            "period_s": 1 / 22,
        }
        for w in ("haar", "db2", "db4")
    },
    indent=1,
)


def _row(peak: float) -> dict:
    return {
        "peak": peak,
        "revs_to_10": None,
        "revs_to_10_1x": 12,
        "peak_1x": 87e-6,
        "peak_force": 43.0,
        "rms_force": 10.0,
        "contacts": 0,
        "residual_um": 12.2,
        "harmonics_um": {"2x": 0.1, "3x": 6.6, "5x": 2.2, "7x": 2.5},
        "model_radius": 0.798,
    }


COMPARISON = json.dumps(
    {
        "speeds_hz": {"mass_loss_1st": 9.719},
        "force_limit": 1000.0,
        "table": {"mass_loss_1st": {"wavelet_i1": _row(94.7e-6), "harmonic_i1": _row(91.1e-6)}},
        "limits_unavailable": {"mass_loss_1st": {"limit_i2": "clearance bound already exceeded"}},
        "robustness": None,
        "timing": {"transient": {"median_s": 2.1e-5, "p99_s": 4.0e-5}},
        "wall_time": 600.0,
        "figures": [],
    }
)

BOUND = json.dumps(
    {
        "force_limit": 1000.0,
        "cases": [
            {"scenario": "mass_loss_1st", "phase": "own", "delay": 1, "fault_phase": 0.891,
             "acts_after_rev": 0.109, "peak": 25.6e-6, "replay_peak": 25.6e-6,
             "floor": 25.6e-6, "pid_peak": 140.8e-6, "revs_below_10pct_pid": 2,
             "peak_force": 262.0},
            {"scenario": "contact_case2", "phase": "own", "delay": 2,
             "unavoidable": "clearance bound already exceeded"},
        ],
    }
)  # fmt: skip


def test_modal_parser_reads_the_critical_speeds_and_modes() -> None:
    r = P.parse_modal(MODAL)
    assert r["critical_speeds_hz"] == [9.719, 16.735, 32.065, 77.68]
    assert r["speed_hz"] == 0.0
    assert [m["frequency_hz"] for m in r["modes"]][:2] == [9.653, 16.674]
    assert r["sensitivity"][1] == {
        "axis": "b2y", "peak": 9.553, "peak_db": 19.6, "frequency_hz": 9.3, "zone": "D"
    }  # fmt: skip


def test_timeit_parser_converts_to_seconds() -> None:
    assert P.parse_timeit("200000 loops, best of 5: 1.06 usec per loop\n") == pytest.approx(1.06e-6)
    assert P.parse_timeit("2000 loops, best of 5: 80.5 usec per loop\n") == pytest.approx(80.5e-6)
    assert P.parse_timeit("1 loop, best of 5: 1.2 sec per loop\n") == pytest.approx(1.2)


def test_plant_bench_parser_reads_the_four_cases_and_the_threads() -> None:
    r = P.parse_plant_bench(PLANT_BENCH)
    assert r["threads"] == "1"
    assert r["rows"][(11, 64, "contact")] == {
        "x_real_time": 2.5, "build_s": 0.001, "stepwise_pct": 3.1, "contact_samples": 412
    }  # fmt: skip
    assert r["rows"][(67, 32, "no contact")]["x_real_time"] == 25.0


def test_pipeline_bench_parser_reads_each_row_including_nan() -> None:
    rows = P.parse_pipeline_bench(PIPELINE_BENCH)
    assert [r["case"] for r in rows] == ["67 Hz x 32", "11 Hz x 64"]
    assert rows[0]["rtf"] == 5.97 and rows[0]["p99_of_period"] == pytest.approx(0.215)
    assert rows[0]["controlled"] == pytest.approx(1.0) and rows[0]["arrival_p99_ms"] == -12.14
    assert (rows[0]["missing"], rows[0]["late"], rows[0]["partial"]) == (0, 0, 0)
    assert (rows[0]["pub_max_ms"], rows[0]["write_max_ms"], rows[0]["load"]) == (8.43, 0.73, 0.8)
    assert rows[1]["write_max_ms"] == 7.43 and "hog_s" not in rows[0]
    (hog,) = P.parse_pipeline_bench(PIPELINE_HOG)
    assert hog["hog_s"] == (7.1, 11.1) and hog["during"] == pytest.approx(1.0)
    assert hog["during_samples"] == pytest.approx(1.0) and hog["write_max_ms"] == 4.15
    assert (hog["recover_periods"], hog["lost"], hog["missing"]) == (0.0, 0, 0)


def test_run_parser_reads_the_drain_and_the_plant_line() -> None:
    r = P.parse_run(RUN_STDOUT, PLANT_LOG)
    assert r["last_sample"] == 4975
    assert r["at_plant_end"] == {
        "fault_monitor last_sample": 3055,
        "fault_monitor last_coefficient_sample": None,
    }
    assert r["drained_s"] == 35.2 and r["drain_timeout_s"] is None
    assert r["wall_s"] == 140.3 and r["real_time_factor"] == 0.08 and r["sim_s"] == 8.0


def test_demo_parser_keeps_the_key_metrics_table() -> None:
    r = P.parse_demo(DEMO_STDOUT)
    assert r["wall_s"] == 74
    assert r["table"][0].startswith("| metric | PID only |") and len(r["table"]) == 4
    assert r["fault_time"].startswith("Fault time per bag")


def test_json_parsers_accept_the_commands_documents() -> None:
    parts = P.parse_fault_eval(FAULT_EVAL)
    assert list(parts) == ["haar", "db2", "db4"]
    assert parts["db2"]["delays"]["MASS_LOSS"]["onset_error_abs_supports_max"] == 0.75
    single = P.parse_fault_eval(json.dumps({**_summary(1.0), "cases": [{"wavelet": "haar"}]}))
    assert list(single) == ["haar"]
    assert P.parse_prediction(PREDICTION)["db4"]["predicted_settling_s"] is None
    assert P.parse_compare(COMPARISON)["table"]["mass_loss_1st"]["wavelet_i1"]["peak"] == 94.7e-6
    assert P.parse_bound(BOUND)["cases"][0]["floor"] == 25.6e-6


@pytest.mark.parametrize(
    "parser",
    [P.parse_modal, P.parse_timeit, P.parse_plant_bench, P.parse_pipeline_bench, P.parse_demo,
     P.parse_fault_eval, P.parse_prediction, P.parse_compare, P.parse_bound],
)  # fmt: skip
def test_parsers_refuse_unrecognised_output(parser) -> None:
    with pytest.raises(P.ResultsError, match="cannot parse the output: expected"):
        parser("Traceback (most recent call last):\n  ...\nValueError: boom\n")


def test_parsers_refuse_documents_without_their_keys() -> None:
    with pytest.raises(P.ResultsError, match="correct"):
        P.parse_fault_eval(json.dumps({"wavelets": {"haar": {"total": 1}}}))
    with pytest.raises(P.ResultsError, match="peak"):
        P.parse_compare(json.dumps({"table": {"k": {"r": {}}}, "speeds_hz": {}, "timing": {}}))
    with pytest.raises(P.ResultsError, match="floor"):
        P.parse_bound(json.dumps({"force_limit": 1.0, "cases": [{"peak": 1.0}]}))
    with pytest.raises(P.ResultsError, match="plant's 'complete at"):
        P.parse_run(RUN_STDOUT, "")


def test_sections_render_tables_from_the_samples(tmp_path: Path) -> None:
    def out(text: str) -> object:
        return C.Output(C.Command(["x"]), text, "", 0, 0.1)

    lines = S.BY_NAME["modal"].report([out(MODAL)], tmp_path)
    assert "| 9.719 | 16.735 | 32.065 | 77.680 |" in lines
    lines = S.BY_NAME["fault-eval"].report([out(FAULT_EVAL)] * 3, tmp_path)
    assert "| haar | 41/41 | 0 | 410.0 | 0.00 |" in lines
    assert "| haar | 45/48 | 94% | 41 | 3 | 0 | 41/41 |" in lines  # provisional classes
    assert "| db4 | 410.0 | 0 | 41 |" in lines  # long healthy running
    assert any("(`config/scenarios/healthy_long`; provisional" in ln for ln in lines)
    long = json.loads(FAULT_EVAL)
    for part in long["wavelets"].values():
        part["cases"] = [{"speed_hz": 11.0}, {"speed_hz": 67.64}]
    lines = S.BY_NAME["fault-eval"].report(
        [out(FAULT_EVAL)] * 2 + [out(json.dumps(long))], tmp_path
    )
    assert any(": 205 s each at 11, 67.64 Hz;" in ln for ln in lines)  # 410 s over two runs
    run = tmp_path / "run"
    (run / "logs").mkdir(parents=True)
    (run / "logs" / "plant_sim.log").write_text(PLANT_LOG)
    (run / "comparison.json").write_text(COMPARISON)
    text = "\n".join(S.BY_NAME["drain"].report([out(RUN_STDOUT)], tmp_path))
    assert (
        "drained in 35.2 s" in text and "| fault_monitor last_sample | 3055 | 1920 | 30.0 |" in text
    )
    text = "\n".join(S.BY_NAME["compare"].report([out("")], tmp_path))
    assert "| wavelet_i1 | 94.7 | - | 12 |" in text
    assert "No limit_i2 row: clearance bound already exceeded." in text
    (run / "bound.json").write_text(BOUND)
    text = "\n".join(S.BY_NAME["bound"].report([out("")], tmp_path))
    row = "| mass_loss_1st | 1 | 0.891 (own) | 0.109 | 25.6 | 25.6 | 25.6 | 140.8 | 2 | 262 |"
    assert row in text
    assert "| contact_case2 | 2 | own | clearance bound already exceeded |" in text


def test_a_failing_command_is_reported_with_its_status_and_output(tmp_path: Path) -> None:
    cmd = C.Command([sys.executable, "-c", "print('partial'); raise SystemExit(3)"])
    with pytest.raises(P.ResultsError, match=r"(?s)exited with status 3 .*partial"):
        C.run_command("demo", cmd, tmp_path)
    with pytest.raises(P.ResultsError, match="not on PATH"):
        C.run_command("demo", C.Command(["amb-no-such-command"]), tmp_path)


def test_document_keeps_the_sections_it_does_not_regenerate() -> None:
    args = R.build_parser().parse_args([])
    blocks = {s.name: R.placeholder(s, args) for s in S.SECTIONS}
    blocks["modal"] = '<!-- meta {"date": "2026-01-01T00:00:00+00:00", "commit": "abc", ' \
        '"load_before": 1.0} -->\nkept\n'  # fmt: skip
    text = R.render_document(blocks)
    again = R.read_blocks(text)
    assert set(again) == set(S.BY_NAME)
    assert again["modal"].strip().endswith("kept")
    assert "| [modal](#modal) |" in text and "not generated yet" in text


def test_every_cited_anchor_exists_in_docs_results_md() -> None:
    document = (ROOT / "docs" / "results.md").read_text()
    anchors = set(re.findall(r'<a id="([^"]+)"></a>', document))
    assert anchors == set(S.BY_NAME), "docs/results.md is not the script's: run `make results`"
    cited = R.citations()
    assert cited, "no docs/results.md#<section> citation found in the code"
    missing = {name: files for name, files in cited.items() if name not in anchors}
    assert not missing, f"cited anchors missing from docs/results.md: {missing}"
