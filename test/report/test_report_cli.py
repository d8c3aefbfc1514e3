"""amb-report on amb-sim bags: every figure, metrics equal to amb-sim's, missing topics.

References from outside the code under test: amb-sim's own ``metrics.json`` (computed from
the in-memory run, not from the bag), PyWavelets for the 1 x Haar coefficients, the bag's own
stamps for the fault-event times.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import pywt
from PIL import Image
from rosbags.rosbag2 import Reader

from amb_apps import report_cli, sim_cli
from amb_apps.report_metrics import NOT_IN_BAG, bag_metrics, choose_fault_time
from amb_common import topics
from amb_tools.bag_read import read_bag
from amb_tools.bag_writer import BagWriter

pytestmark = pytest.mark.slow  # command lines writing figures

#: The streams' names in amb-sim's bags (the root namespace).
MEASUREMENT = topics.absolute(topics.MEASUREMENT)
COEFFICIENTS = topics.absolute(topics.COEFFICIENTS)

FIGURES = ("displacement", "coefficients_1x", "forces", "orbits", "fault_timeline")
LABELS = ("PID only", "PID + wavelet")
#: ControllerConfig keys the bag carries (ControllerStatus, ControlCommand, coefficients).
CONTROLLER_KEYS = ("controller", "wavelet", "samples_per_rev", "delay_periods")


@pytest.fixture(scope="module")
def report(sim_pid, sim_wavelet, scenario, tmp_path_factory) -> Path:
    out = tmp_path_factory.mktemp("report") / "out"
    code = report_cli.main(
        [str(sim_pid / "bag"), str(sim_wavelet / "bag"), "--labels", ",".join(LABELS),
         "--scenario", str(scenario), "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    return out


def _assert_same_metrics(ours: dict, ref: dict) -> None:
    """Every amb-sim key is in ours and equal, except the documented not-in-bag fields."""
    missing = set(ref) - set(ours)
    assert missing <= set(NOT_IN_BAG), f"keys amb-sim writes but amb-report does not: {missing}"
    for key, value in ref.items():
        if key in NOT_IN_BAG or key == "contact_source":
            continue
        assert ours[key] == value, f"{key}: report {ours[key]!r} != amb-sim {value!r}"
    assert ours["contact_count"] is None and ref["contact_count"] is not None
    assert "not in the bag" in ours["contact_source"]
    for key in CONTROLLER_KEYS:
        assert ours["controller"][key] == ref["controller"][key], key


def test_every_figure_is_written_and_linked(report) -> None:
    md = (report / "report.md").read_text()
    for name in FIGURES:
        png = report / f"{name}.png"
        with Image.open(png) as im:
            assert im.format == "PNG" and im.size[0] >= 1000 and im.size[1] >= 500
        assert png.stat().st_size < 400_000, f"{png.name} is {png.stat().st_size} bytes"
        assert f"]({name}.png)" in md
    for slug in ("PID_only", "PID_wavelet"):
        assert (report / f"levels_{slug}.png").is_file()
        assert f"({slug}/metrics.json)" in md
    assert "Not drawn" not in md


@pytest.mark.parametrize("label", LABELS)
def test_metrics_equal_amb_sim(report, sim_pid, sim_wavelet, label) -> None:
    run = sim_pid if label == "PID only" else sim_wavelet
    slug = "PID_only" if label == "PID only" else "PID_wavelet"
    ours = json.loads((report / slug / "metrics.json").read_text())
    ref = json.loads((run / "metrics.json").read_text())
    _assert_same_metrics(ours, ref)
    assert ours["fault_time_source"] == "scenario"
    assert ours["missing_topics"] == ([] if run is sim_wavelet else ["/amb/fault/events"])


def test_fault_events_round_trip_the_monitor_fields(report, sim_wavelet) -> None:
    ours = json.loads((report / "PID_wavelet" / "metrics.json").read_text())["fault_events"]
    ref = json.loads((sim_wavelet / "metrics.json").read_text())["fault_events"]
    assert len(ref) >= 1 and ref[0]["fault_type"] == "MASS_LOSS"
    assert ours == ref  # including decision_sample_index, rebuilt from the header stamp


def test_comparison_table_holds_the_metrics_side_by_side(report, sim_pid, sim_wavelet) -> None:
    text = (report / "comparison.md").read_text()
    a = json.loads((sim_pid / "metrics.json").read_text())
    b = json.loads((sim_wavelet / "metrics.json").read_text())
    row = next(ln for ln in text.splitlines() if ln.startswith("| steady 1 x amplitude at x2"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    pid, wav = a["sensors"]["x2"]["steady_1x_amplitude"], b["sensors"]["x2"]["steady_1x_amplitude"]
    assert float(cells[1]) == pytest.approx(pid * 1e6, abs=0.05)
    assert float(cells[2]) == pytest.approx(wav * 1e6, abs=0.05)
    assert float(cells[3]) == pytest.approx(wav / pid, abs=5e-4)
    row = next(ln for ln in text.splitlines() if ln.startswith("| peak wavelet force, bearing 1"))
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert float(cells[2]) == pytest.approx(b["bearings"]["1"]["peak_wavelet_force"], abs=0.05)
    assert float(cells[1]) == 0.0  # PID only: no wavelet force


def test_one_x_coefficients_match_pywavelets(sim_wavelet, spr) -> None:
    """Even 1 x phasor of period k = Haar detail of that revolution (pywt.downcoef)."""
    data = read_bag(sim_wavelet / "bag")
    x = data.measurements.displacement
    assert data.one_x.level == int(math.log2(spr))
    n_periods = x.shape[0] // spr
    assert data.one_x.even.shape == (n_periods, 8) and data.one_x.present.all()
    ref = np.array(
        [
            pywt.downcoef("d", x[k * spr : (k + 1) * spr, c], "haar", level=data.one_x.level)[0]
            for k in range(n_periods)
            for c in range(8)
        ]
    ).reshape(n_periods, 8)
    scale = np.abs(ref).max()
    np.testing.assert_allclose(data.one_x.even, ref, rtol=0, atol=1e-9 * scale)


def test_fault_time_comes_from_the_first_fault_event_without_a_scenario(sim_wavelet) -> None:
    data = read_bag(sim_wavelet / "bag")
    m = bag_metrics(data, choose_fault_time(data))
    assert m["fault_time_source"] == "first_fault_event"
    onset = m["fault_events"][0]["onset_sample_index"]
    hit = np.flatnonzero(data.measurements.sample_index == onset)
    assert m["fault_time"] == data.measurements.time[hit[0]]
    assert m["fault_time_candidates"] == {"first_fault_event": m["fault_time"]}
    # the user's value wins over the scenario's and the bag's
    fault = choose_fault_time(data, user=1.5, scenario=2.0)
    assert (fault.time, fault.source) == (1.5, "user")
    fault = choose_fault_time(data, scenario=2.0)
    assert (fault.time, fault.source) == (2.0, "scenario")


def _copy_topics(src: Path, dst: Path, keep: set[str] | None = None, prefix: str = "") -> None:
    """Copy the topics ``keep`` (None: all) of bag ``src`` to ``dst``, each renamed
    ``prefix + topic`` (``/rig1``: the bag of a system run in namespace ``/rig1``)."""
    with Reader(src) as reader, BagWriter(dst) as writer:
        for conn in reader.connections:
            if keep is None or conn.topic in keep:
                writer.add_topic(prefix + conn.topic, conn.msgtype)
        for conn, t_ns, raw in reader.messages():
            if keep is None or conn.topic in keep:
                writer.write_raw(prefix + conn.topic, t_ns, raw)


def test_bag_without_coefficients_reports_what_is_there(sim_wavelet, scenario, tmp_path):
    bag = tmp_path / "meas_only"
    _copy_topics(sim_wavelet / "bag", bag, {MEASUREMENT})
    out = tmp_path / "rep"
    code = report_cli.main([str(bag), "--scenario", str(scenario), "--out", str(out)])
    assert code == 0
    for name in ("displacement", "forces", "orbits", "fault_timeline"):
        assert (out / f"{name}.png").is_file(), name
    assert not (out / "coefficients_1x.png").exists()
    md = (out / "report.md").read_text()
    assert "Not drawn: no 1 x level coefficients" in md
    assert COEFFICIENTS in md and "/amb/control/command" in md  # listed as missing
    ours = json.loads((out / "meas_only" / "metrics.json").read_text())
    ref = json.loads((sim_wavelet / "metrics.json").read_text())
    assert set(ours["missing_topics"]) == {
        COEFFICIENTS,
        "/amb/control/command",
        "/amb/control/status",
        "/amb/fault/events",
    }
    for name, s in ref["sensors"].items():
        assert ours["sensors"][name]["peak_after_fault"] == s["peak_after_fault"]
        assert ours["sensors"][name]["steady_1x_amplitude"] == s["steady_1x_amplitude"]
        assert ours["sensors"][name]["settling_revolutions"] is None
    assert ours["bearings"] == ref["bearings"]


def test_bag_with_coefficients_only_still_gives_settling(sim_wavelet, scenario, tmp_path):
    bag = tmp_path / "coef_only"
    _copy_topics(sim_wavelet / "bag", bag, {COEFFICIENTS})
    out = tmp_path / "rep"
    result = report_cli.make_report([bag], out, scenario=scenario)
    (m,) = result.values()
    ref = json.loads((sim_wavelet / "metrics.json").read_text())
    assert (out / "coefficients_1x.png").is_file()
    assert not (out / "displacement.png").exists()
    assert "Not drawn: no /amb/measurement" in (out / "report.md").read_text()
    for name, s in ref["sensors"].items():
        assert m["sensors"][name]["settling_revolutions"] == s["settling_revolutions"]
        assert m["sensors"][name]["peak_after_fault"] is None
    assert m["bearings"] is None


def test_invalid_arguments_exit_2_with_a_reason(sim_pid, tmp_path, capsys) -> None:
    code = report_cli.main([str(sim_pid / "bag"), "--labels", "a,b", "--out", str(tmp_path)])
    assert code == 2
    assert "2 label(s) for 1 bag(s)" in capsys.readouterr().err
    code = report_cli.main([str(tmp_path), "--out", str(tmp_path / "o")])
    assert code == 2
    assert "not a rosbag2 folder" in capsys.readouterr().err


def test_bag_with_commands_only_gives_the_applied_wavelet_force(sim_wavelet, scenario, tmp_path):
    bag = tmp_path / "cmd_only"
    _copy_topics(sim_wavelet / "bag", bag, {COEFFICIENTS, "/amb/control/command"})
    result = report_cli.make_report([bag], tmp_path / "rep", scenario=scenario)
    (m,) = result.values()
    ref = json.loads((sim_wavelet / "metrics.json").read_text())
    for b in ("1", "2"):
        peak = m["bearings"][b]["peak_wavelet_force"]
        assert peak == ref["bearings"][b]["peak_wavelet_force"] and peak > 1.0
        assert m["bearings"][b]["peak_total_force"] is None
    assert (tmp_path / "rep" / "forces.png").is_file()


def test_bag_of_a_system_in_a_namespace_reports_the_same(
    sim_wavelet, sim_pid, scenario, tmp_path, capsys
):
    """The bag of a system run in ``/rig1`` (``/rig1/amb/...``) gives amb-sim's metrics; in a bag
    holding two systems, ``--namespace`` says which one to report."""
    bag = tmp_path / "rig1"
    _copy_topics(sim_wavelet / "bag", bag, prefix="/rig1")
    data = read_bag(bag)
    assert data.namespace == "/rig1" and data.missing == []
    out = tmp_path / "rep"
    assert report_cli.main([str(bag), "--scenario", str(scenario), "--out", str(out)]) == 0
    ours = json.loads((out / "rig1" / "metrics.json").read_text())
    assert set(ours["bag_counts"]) == {topics.absolute(t, "/rig1") for t in topics.STREAM_TYPES}
    ref = json.loads((sim_wavelet / "metrics.json").read_text())
    _assert_same_metrics(_at_the_root(ours, "/rig1", sim_wavelet / "bag"), ref)
    for name in FIGURES:
        assert (out / f"{name}.png").is_file(), name

    both = tmp_path / "two_rigs"
    with BagWriter(both) as writer:
        for src, prefix in ((sim_wavelet / "bag", "/rig1"), (sim_pid / "bag", "/rig2")):
            with Reader(src) as reader:
                for conn in reader.connections:
                    writer.add_topic(prefix + conn.topic, conn.msgtype)
                for conn, t_ns, raw in reader.messages():
                    writer.write_raw(prefix + conn.topic, t_ns, raw)
    code = report_cli.main([str(both), "--out", str(tmp_path / "ambiguous")])
    assert code == 2
    assert "2 namespaces ['/rig1', '/rig2']" in capsys.readouterr().err
    out = tmp_path / "rep2"
    args = [str(both), "--namespace", "/rig2", "--scenario", str(scenario), "--out", str(out)]
    assert report_cli.main(args) == 0
    ours = json.loads((out / "two_rigs" / "metrics.json").read_text())
    assert ours["missing_topics"] == ["/rig2/amb/fault/events"]  # PID only: no fault monitor
    ref = json.loads((sim_pid / "metrics.json").read_text())
    _assert_same_metrics(_at_the_root(ours, "/rig2", sim_pid / "bag"), ref)


def _at_the_root(metrics: dict, ns: str, bag: Path) -> dict:
    """The metrics of a copy of ``bag`` under namespace ``ns``, as if read from ``bag``."""
    out = dict(metrics, bag=str(bag))
    out["bag_counts"] = {t.removeprefix(ns): n for t, n in metrics["bag_counts"].items()}
    out["missing_topics"] = [t.removeprefix(ns) for t in metrics["missing_topics"]]
    return out


#: amb-report's folders of the three bags of :func:`report_with_sinusoid` (slugs of the labels).
SLUGS = ("PID_only", "PID_wavelet", "PID_sinusoid")


@pytest.fixture(scope="module")
def report_with_sinusoid(sim_pid, sim_wavelet, scenario, spr, tmp_path_factory) -> tuple:
    """amb-report over three bags: PID only, the Haar-force run, and the same law with a 1 x
    sinusoidal force (``--output-basis sinusoid``, no harmonics of its own): (the report's
    folder, the three amb-sim folders, their labels)."""
    from .conftest import DURATION

    sinusoid = tmp_path_factory.mktemp("report_sim") / "sinusoid"
    args = ["--scenario", str(scenario), "--samples-per-rev", str(spr), "--duration",
            str(DURATION), "--controller", "transient", "--model", "fe", "--output-basis",
            "sinusoid", "--out", str(sinusoid)]  # fmt: skip
    assert sim_cli.main(args) == 0
    out = tmp_path_factory.mktemp("report3") / "out"
    bags = [str(run / "bag") for run in (sim_pid, sim_wavelet, sinusoid)]
    labels = [*LABELS, "PID + sinusoid"]
    code = report_cli.main(
        [*bags, "--labels", ",".join(labels), "--scenario", str(scenario), "--out", str(out)]
    )
    assert code == 0
    return out, (sim_pid, sim_wavelet, sinusoid), labels


def test_revolutions_below_10_percent_of_pid_counted_from_the_displacement(
    report_with_sinusoid,
) -> None:
    """Reference: each bag's inner displacement, revolution by revolution, against 10 % of the
    PID-only run's steady 1 x amplitude as amb-sim computed it. The bags give both answers: a
    count (the sinusoidal force's run) and "not reached" (PID only, whose peak stays at its
    steady amplitude). The Haar-force run is counted as it comes: its force's odd harmonics
    leave it close to the level (measured 13.6 um in its last revolutions against 13.3 um)."""
    out, runs, labels = report_with_sinusoid
    pid = json.loads((runs[0] / "metrics.json").read_text())
    level = 0.1 * max(pid["sensors"][n]["steady_1x_amplitude"] for n in ("x2", "y2", "x3", "y3"))
    expected = []
    for run, label, folder in zip(runs, labels, SLUGS, strict=True):
        ours = json.loads((out / folder / "metrics.json").read_text())
        data = read_bag(run / "bag")
        spr = data.samples_per_rev
        x = data.measurements.displacement[:, 2:6]
        k_f = ours["fault_period"]
        peaks = [np.abs(x[k * spr : (k + 1) * spr]).max() for k in range(k_f, len(x) // spr)]
        above = [i for i, p in enumerate(peaks) if p > level]
        count = None if above and above[-1] == len(peaks) - 1 else (above[-1] + 1 if above else 0)
        assert ours["revs_below_10pct_pid"] == count, label
        assert "10 % of PID only's steady 1 x" in ours["revs_below_10pct_pid_source"]
        expected.append(count)
    assert expected[0] is None and expected[2] is not None  # both answers are checked
    row = next(
        ln for ln in (out / "comparison.md").read_text().splitlines()
        if ln.startswith("| revolutions until below 10 % of PID")
    )  # fmt: skip
    cells = [c.strip() for c in row.strip("|").split("|")]
    assert cells[1:] == ["not reached" if n is None else str(n) for n in expected]


def test_revolutions_below_pid_need_exactly_one_pid_bag() -> None:
    bag = {"controller": {"controller": "transient"}, "inner_revolution_peaks": [1e-4, 1e-6]}
    metrics = [dict(bag), dict(bag)]
    report_cli.add_below_pid(metrics)
    assert metrics[0]["revs_below_10pct_pid"] is None
    assert "0 PID-only bags" in metrics[0]["revs_below_10pct_pid_source"]
