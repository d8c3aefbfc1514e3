"""amb-sim writes a bag rosbags reads (every message deserialisable) and metrics.json."""

import json
import math
from pathlib import Path

import numpy as np
import pytest
from rosbags.rosbag2 import Reader

from amb_apps import sim_cli
from amb_controller.model_file import WaveletModel
from amb_tools.bag_types import typestore

SCENARIO = Path(__file__).resolve().parents[2] / "config/scenarios/mass_loss_first_critical.yaml"
SPR = 32


@pytest.fixture(scope="module")
def run_dir(tmp_path_factory):
    out = tmp_path_factory.mktemp("sim") / "run"
    code = sim_cli.main(
        ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--duration", "4.5",
         "--fault-monitor", "--out", str(out)]
    )  # fmt: skip
    assert code == 0
    return out


def test_bag_has_the_pipeline_topics_and_every_message_deserialises(run_dir):
    store = typestore()
    counts, commands, last_stamp_of_sample = {}, [], {}
    checked = 0
    with Reader(run_dir / "bag") as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        for conn, t_ns, raw in reader.messages():
            msg = store.deserialize_cdr(raw, conn.msgtype)
            stamp = msg.header.stamp.sec * 1_000_000_000 + msg.header.stamp.nanosec
            assert t_ns == stamp  # bag time = header stamp (simulated time)
            counts[conn.topic] = counts.get(conn.topic, 0) + 1
            if conn.topic == "/amb/measurement":
                last_stamp_of_sample[msg.sample_index] = stamp
            elif conn.topic == "/amb/control/command":
                commands.append((msg, stamp))
    assert topics["/amb/control/command"] == "amb_msgs/msg/ControlCommand"
    assert topics["/amb/control/status"] == "amb_msgs/msg/ControllerStatus"
    assert topics["/amb/wavelet/coefficients"] == "amb_msgs/msg/WaveletCoefficients"
    n_samples = counts["/amb/measurement"]
    n_periods = n_samples // SPR
    assert n_samples == n_periods * SPR and n_periods > 20
    assert counts["/amb/wavelet/coefficients"] == n_samples // 2  # every odd sample (Haar)
    assert counts["/amb/control/command"] == counts["/amb/control/status"] == n_periods
    for k, (msg, stamp) in enumerate(commands):
        assert msg.based_on_period == k and msg.period_index == k + msg.delay_periods
        assert msg.start_sample_index == msg.period_index * SPR
        assert len(msg.force) == 4 * SPR
        # stamp of the last measured sample of the period the command is based on
        assert stamp == last_stamp_of_sample[(k + 1) * SPR - 1]
        even = {a.axis: a.values[0] for a in msg.coefficients if a.quadrature == 0}
        force = np.asarray(msg.force).reshape(4, SPR)
        if not msg.hold and any(even.values()):
            odd = {a.axis: a.values[0] for a in msg.coefficients if a.quadrature == 1}
            d = SPR // 4
            # sample d: even waveform first half (+), odd waveform advanced by d: second half
            # force[axis * N + n]: Haar level 1, even waveform +1/sqrt(N) on the first half
            # period; the odd one is it advanced by N/4, so at sample N/4 it is -1/sqrt(N)
            expected = (even[0] - odd[0]) / math.sqrt(SPR)
            assert force[0, d] == pytest.approx(expected, rel=1e-9, abs=1e-12)
            checked += 1
    assert checked > 10


def test_metrics_file_has_per_sensor_and_per_bearing_figures(run_dir):
    m = json.loads((run_dir / "metrics.json").read_text())
    assert set(m["sensors"]) == {"x1", "y1", "x2", "y2", "x3", "y3", "x4", "y4"}
    assert m["fault_time"] == 4.0 and m["model_source"] == "fe"
    for s in m["sensors"].values():
        assert s["peak_after_fault"] >= s["steady_1x_amplitude"] > 0
    assert m["bearings"]["1"]["peak_total_force"] >= m["bearings"]["1"]["peak_wavelet_force"] > 0
    assert m["contact_source"].startswith("simulator truth")


def test_invalid_option_exits_2(tmp_path, capsys):
    code = sim_cli.main(["--scenario", str(SCENARIO), "--w", "1.5", "--out", str(tmp_path / "x")])
    assert code == 2
    assert "'w' = 1.5" in capsys.readouterr().err


def test_a_controller_its_own_model_says_diverges_is_reported_and_the_check_can_be_off(
    tmp_path, capsys
):
    # the outer probes with a first-order inverse at the third critical speed: a loop whose
    # radius on its own model is above 1 (measured 1.068 at the default delay; at i = 1 the
    # same loop diverges in the simulator, test/beyond/test_third_critical.py)
    third = SCENARIO.parent / "sync_force_150N_third_critical.yaml"
    common = ["--scenario", str(third), "--samples-per-rev", str(SPR), "--duration", "0.2",
              "--no-bag", "--sensors", "0,1,6,7", "--order", "1"]  # fmt: skip
    assert sim_cli.main([*common, "--out", str(tmp_path / "checked")]) == 0
    checked = json.loads((tmp_path / "checked" / "metrics.json").read_text())
    assert checked["model_radius"] > 1.0 and "spectral radius" in checked["refused"]
    assert "not set ACTIVE" in capsys.readouterr().err
    assert sim_cli.main([*common, "--max-model-radius", "0", "--out", str(tmp_path / "off")]) == 0
    off = json.loads((tmp_path / "off" / "metrics.json").read_text())
    assert off["refused"] == "" and off["model_radius"] == checked["model_radius"]


def test_a_deliberate_model_error_reaches_the_controller_and_not_the_model_file(tmp_path, capsys):
    """``--model-gain``/``--model-phase``: the controller runs on the perturbed model,
    ``model.npz`` stays the model (a run that reuses it gets no error), and the error is in
    metrics.json."""
    common = ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--duration", "0.5",
              "--no-bag", "--controller", "transient"]  # fmt: skip
    assert sim_cli.main([*common, "--out", str(tmp_path / "exact")]) == 0
    off = ["--model-gain", "0.7", "--model-phase", "-45"]
    assert sim_cli.main([*common, *off, "--out", str(tmp_path / "off")]) == 0
    exact = json.loads((tmp_path / "exact" / "metrics.json").read_text())
    wrong = json.loads((tmp_path / "off" / "metrics.json").read_text())
    assert exact["model_error"] == {"gain": 1.0, "phase_deg": 0.0}
    assert wrong["model_error"] == {"gain": 0.7, "phase_deg": -45.0}
    # a model with 0.7 of the plant's gain asks ~1 / 0.7 of the force for the same residual
    # unbalance (the loop converges on it from the start); its own-model loop is unchanged
    force = [m["bearings"]["1"]["peak_wavelet_force"] for m in (exact, wrong)]
    assert force[0] > 1.0 and force[1] > 1.2 * force[0]
    assert wrong["model_source"] == exact["model_source"] + " x0.7 -45deg"
    assert wrong["model_radius"] == pytest.approx(exact["model_radius"], rel=1e-6)
    # the loop around the model without the error is another loop (measured 0.80 -> 0.97)
    assert exact["radius_without_model_error"] is None
    assert abs(wrong["radius_without_model_error"] - wrong["model_radius"]) > 0.05
    a, b = (WaveletModel.load(tmp_path / d / "model.npz") for d in ("exact", "off"))
    assert np.array_equal(a.markov, b.markov) and a.source == b.source
    none = ["--scenario", str(SCENARIO), "--duration", "0.2", "--no-bag", "--controller", "none"]
    assert sim_cli.main([*none, "--model-gain", "0.7", "--out", str(tmp_path / "x")]) == 2
    assert "need a controller with a model" in capsys.readouterr().err
    assert sim_cli.main([*common, "--model-gain", "0", "--out", str(tmp_path / "y")]) == 2
    assert "gain must be > 0" in capsys.readouterr().err


def test_the_predictive_options_reach_its_configuration(tmp_path, capsys):
    common = ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--duration", "0.2",
              "--no-bag", "--controller", "predictive", "--output-basis", "sinusoid"]  # fmt: skip
    bad = sim_cli.main([*common, "--horizon", "4", "--moves", "5", "--out", str(tmp_path / "x")])
    assert bad == 2 and "'moves' = 5" in capsys.readouterr().err
    bad = sim_cli.main([*common, "--move-weight", "-1", "--out", str(tmp_path / "y")])
    assert bad == 2 and "'move_weight' = -1" in capsys.readouterr().err
    out = tmp_path / "ok"
    assert sim_cli.main([*common, "--horizon", "8", "--moves", "2", "--out", str(out)]) == 0
    metrics = json.loads((out / "metrics.json").read_text())
    assert metrics["refused"] == "" and 0.0 < metrics["model_radius"] < 0.98


def test_the_early_action_from_a_model_file_reports_the_scenario_s_loss(tmp_path, capsys):
    """``--early FILE`` (amb-early-model's file): the 430 g cm loss at D1 in metrics.json.

    Reference: the scenario's own mass-loss event (disk, me, onset); 5 % on me as in
    test/beyond/test_compare.py (the likelihood ratio of a loss late in its period).
    """
    from amb_apps import early_model_cli
    from amb_common.rig import load_rig
    from amb_plant_sim.scenario import load_scenario

    model = tmp_path / "early.npz"
    args = ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--out", str(model)]
    assert early_model_cli.main(args) == 0
    assert early_model_cli.main([*args[:-1], str(tmp_path / "no" / "x.npz")]) == 2
    out = tmp_path / "run"
    common = ["--scenario", str(SCENARIO), "--samples-per-rev", str(SPR), "--duration", "4.5",
              "--no-bag", "--controller", "predictive", "--output-basis", "sinusoid"]  # fmt: skip
    assert sim_cli.main([*common, "--early", str(model), "--out", str(out)]) == 0
    (found,) = json.loads((out / "metrics.json").read_text())["early_detections"]
    scenario = load_scenario(SCENARIO, load_rig())
    loss = next(e for e in scenario.events if e.kind == "mass_loss")
    assert found["plane"] == loss.get("disk") and found["acted"]
    assert found["me"] == pytest.approx(loss.get("me"), rel=0.05)
    assert found["period"] == math.ceil(loss.time * scenario.speed_hz * SPR) // SPR
    bad = sim_cli.main([*common[:-4], "--controller", "harmonic", "--early", str(model),
                        "--out", str(tmp_path / "h")])  # fmt: skip
    assert bad == 2 and "early action" in capsys.readouterr().err


def test_amb_early_model_writes_a_bank_over_a_band_and_refuses_bad_speeds(tmp_path, capsys):
    """``--band 1``: every speed from 1 % below to 1 % above the scenario's has a model within
    the early action's tolerance (0.5 % of the speed), the scenario's own among them;
    ``--speeds`` lists and ranges; bad input exits 2 with a reason."""
    from amb_apps import early_model_cli
    from amb_common.rig import load_rig
    from amb_controller.early_model import EarlyModelBank
    from amb_plant_sim.scenario import load_scenario

    hz = load_scenario(SCENARIO, load_rig()).speed_hz
    common = ["--scenario", str(SCENARIO), "--samples-per-rev", "16"]
    out = tmp_path / "band.npz"
    assert early_model_cli.main([*common, "--band", "1", "--out", str(out)]) == 0
    bank = EarlyModelBank.load(out)
    band = 2 * math.pi * hz * np.linspace(0.99, 1.01, 401)
    assert all(bank.select(w, 0.005) is not None for w in band)
    assert np.min(np.abs(bank.omegas / (2 * math.pi) - hz)) < 1e-9 * hz
    assert len(bank.models) <= 5  # no more than the tolerance needs
    out = tmp_path / "list.npz"
    assert early_model_cli.main([*common, "--speeds", "9,10:11:0.5", "--out", str(out)]) == 0
    np.testing.assert_allclose(EarlyModelBank.load(out).omegas / (2 * math.pi),
                               [9.0, 10.0, 10.5, 11.0], rtol=1e-12)  # fmt: skip
    capsys.readouterr()
    for bad, words in (
        (["--speeds", "10:9:0.5"], "HI >= LO"),
        (["--speeds", "ten"], "expected HZ"),
        (["--speeds", "0"], "> 0 Hz"),
        (["--band", "60"], "(0, 50]"),
    ):
        assert early_model_cli.main([*common, *bad, "--out", str(tmp_path / "x.npz")]) == 2
        assert words in capsys.readouterr().err
