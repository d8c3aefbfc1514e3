"""
PlantSimulator: steady unbalance response vs the frequency-domain solution, the timing
contract, streaming (chunked equals batch), faults and speed profiles.
"""

import dataclasses
import itertools
import math

import numpy as np
import pytest

from amb_plant_sim.closed_loop import build_closed_loop
from amb_plant_sim.errors import SimulationError
from amb_plant_sim.scenario import scenario_from_dict
from amb_plant_sim.simulator import PlantSimulator

UNB = {"kind": "unbalance", "disk": "D1", "me": 1.0e-3, "angle": 0.5}


def _sim(rig, events, speed_hz=20.0, spr=32, **kw):
    sc = scenario_from_dict({"speed": {"hz": speed_hz}, "duration": 10.0, "events": events}, rig)
    return PlantSimulator(rig, sc, spr, **kw)


def test_steady_unbalance_response_matches_frequency_domain(rig):
    f_hz, spr = 20.0, 32
    omega = 2 * math.pi * f_hz
    # reference: continuous closed loop (eq. 2.47) solved in the frequency domain (eq. 2.52)
    cl = build_closed_loop(rig, omega)
    node = cl.plant.rotor.node_at(rig.disks[0].z)
    W = np.zeros(cl.B_f.shape[1], dtype=complex)
    c = UNB["me"] * omega**2 * np.exp(1j * UNB["angle"])
    W[2 * node], W[2 * node + 1] = c, -1j * c
    X = np.linalg.solve(1j * omega * np.eye(cl.A.shape[0]) - cl.A, cl.B_f @ W)
    Y_ref = cl.output(cl.plant.C_s) @ X  # x(t) = Re(Y e^{j omega t})
    # digital PID (zero-order hold at the internal rate): the error is first order in the step
    errors = []
    for rate in (20000.0, 40000.0, 160000.0):
        sim = _sim(rig, [UNB], f_hz, spr, internal_rate_min=rate)
        blk = sim.advance(80 * spr)
        last = blk.displacement[-20 * spr :]
        theta = blk.angle[-20 * spr :]
        Y_sim = 2.0 * np.mean(last * np.exp(-1j * theta)[:, None], axis=0)
        errors.append(np.max(np.abs(Y_sim - Y_ref)) / np.abs(Y_ref).max())
    assert np.abs(Y_ref).max() > 5e-6  # tens of micrometres: a real response
    assert errors[2] < 2e-3  # PID at 160 kHz: the continuous model within 0.2 %
    assert 1.6 < errors[0] / errors[1] < 2.4  # halving the step halves the error
    # the default internal rate (10 kHz) is within 3 %
    sim = _sim(rig, [UNB], f_hz, spr)
    last = sim.advance(80 * spr).displacement[-20 * spr :]
    Y_def = 2.0 * np.mean(last * np.exp(-1j * theta)[:, None], axis=0)
    np.testing.assert_allclose(np.abs(Y_def), np.abs(Y_ref), rtol=3e-2)


def test_sample_clock_and_angle(rig):
    sim = _sim(rig, [], 25.0, 16)
    blk = sim.advance(40)
    assert sim.fs == pytest.approx(400.0) and sim.omega == pytest.approx(2 * math.pi * 25.0)
    np.testing.assert_array_equal(blk.sample_index, np.arange(40))
    np.testing.assert_allclose(blk.time, np.arange(40) / 400.0, rtol=1e-12, atol=1e-15)
    np.testing.assert_allclose(blk.angle, 2 * math.pi * (np.arange(40) % 16) / 16)
    assert blk.displacement.shape == (40, 8) and blk.current.shape == (40, 4)
    assert blk.sample_index.dtype == np.int64


def test_measurement_is_taken_before_the_force_of_its_sample(rig):
    sim = _sim(rig, [], 20.0, 32)
    wf = np.zeros((20, 4))
    wf[10, 0] = 100.0  # one-sample force pulse at b1x
    blk = sim.advance(20, wavelet_force=wf)
    d = blk.truth["true_displacement"]
    assert np.all(d[:11] == 0.0)  # sample 10 is measured before its force acts
    assert abs(d[11, 2]) > 1e-8  # the inner sensor next to bearing 1 moves after it
    assert blk.bearing_force[10, 0] == pytest.approx(100.0)  # applied from t_10
    assert blk.current[10, 0] == pytest.approx(100.0 / rig.amb.Ki)


def test_chunked_equals_batch_and_reset_repeats(rig):
    events = [UNB, {"kind": "mass_loss", "time": 0.1, "disk": "D4", "me": 2e-3, "angle": 1.0}]
    sc = scenario_from_dict(
        {"speed": {"hz": 15.0}, "duration": 1.0, "events": events, "measurement_noise": 1e-6},
        rig,
    )
    sim = PlantSimulator(rig, sc, 64, seed=3)
    rng = np.random.default_rng(0)
    wf = 20.0 * rng.standard_normal((300, 4))
    whole = sim.advance(300, wf)
    sim.reset()
    parts = [sim.advance(k, wf[a : a + k]) for a, k in ((0, 1), (1, 100), (101, 77), (178, 122))]
    for name in ("displacement", "current", "bearing_force", "time", "angle"):
        joined = np.concatenate([getattr(p, name) for p in parts])
        ref = getattr(whole, name)
        np.testing.assert_allclose(joined, ref, rtol=1e-9, atol=1e-12 * np.abs(ref).max())
    sim.reset()
    again = sim.advance(300, wf)
    np.testing.assert_array_equal(again.displacement, whole.displacement)
    other = PlantSimulator(rig, sc, 64, seed=4).advance(300, wf)
    assert not np.array_equal(other.displacement, whole.displacement)  # noise is seeded


def test_chunked_equals_batch_through_contact_with_noise(rig):
    """A contact cuts the linear chunks short: the noise drawn for the samples after the cut
    is given back, so each sample's noise, and the run, do not depend on the calls' lengths."""
    sc = scenario_from_dict(
        {"speed": {"hz": 15.0}, "duration": 1.0, "events": [UNB], "measurement_noise": 1e-6},
        rig,
    )
    sim = PlantSimulator(rig, sc, 32, seed=5)
    wf = np.zeros((320, 4))
    wf[64:, 0] = 900.0  # pushes the rotor onto auxiliary bearing 1 along x
    whole = sim.advance(320, wf)
    assert whole.truth["contact"].any()  # the premise: the run touches
    sim.reset()
    cuts = (0, 3, 70, 71, 150, 200, 320)
    parts = [sim.advance(b - a, wf[a:b]) for a, b in itertools.pairwise(cuts)]
    joined = np.concatenate([p.displacement for p in parts])
    ref = whole.displacement
    # same arithmetic but for matrix products over other row counts (last bits)
    np.testing.assert_allclose(joined, ref, rtol=0, atol=1e-12 * np.abs(ref).max())


def test_mass_loss_changes_the_response_only_after_onset(rig):
    ml = {"kind": "mass_loss", "time": 0.25, "disk": "D1", "me": 4.3e-3, "angle": 0.0}
    base = _sim(rig, [UNB], 20.0, 32).advance(640)
    lost = _sim(rig, [UNB, ml], 20.0, 32).advance(640)
    onset = int(np.ceil(0.25 * 640 - 1e-9))
    # the event cuts the run's linear chunks differently: matrix products over other row
    # counts may differ in the last bit on some BLAS kernels, a leak of the loss would not
    np.testing.assert_allclose(
        lost.displacement[: onset + 1],
        base.displacement[: onset + 1],
        rtol=0,
        atol=1e-12 * np.abs(base.displacement).max(),
    )
    assert np.abs(lost.displacement[-32:]).max() > 3 * np.abs(base.displacement[-32:]).max()
    assert lost.truth["events_active"][onset, 1] and not lost.truth["events_active"][onset - 1, 1]


def test_sensor_faults(rig):
    events = [
        UNB,
        {
            "kind": "sensor_fault",
            "time": 0.1,
            "plane": 1,
            "axis": "x",
            "mode": "offset",
            "value": 1e-4,
        },
        {"kind": "sensor_fault", "time": 0.1, "plane": 1, "axis": "y", "mode": "zero"},
        {"kind": "sensor_fault", "time": 0.1, "plane": 4, "axis": "x", "mode": "stuck"},
        {
            "kind": "sensor_fault",
            "time": 0.1,
            "plane": 4,
            "axis": "y",
            "mode": "noise",
            "value": 1e-5,
        },
    ]
    blk = _sim(rig, events, 20.0, 32).advance(200)
    on = blk.time >= 0.1
    d, true = blk.displacement, blk.truth["true_displacement"]
    np.testing.assert_allclose(d[on, 0] - true[on, 0], 1e-4, rtol=1e-12)
    assert np.all(d[on, 1] == 0.0)
    assert np.all(d[on, 6] == d[np.argmax(on), 6]) and np.ptp(true[on, 6]) > 1e-6
    assert 0.5e-5 < np.std(d[on, 7] - true[on, 7]) < 2e-5
    np.testing.assert_array_equal(d[~on], true[~on])
    np.testing.assert_array_equal(d[:, 2:6], true[:, 2:6])  # other channels untouched


def test_stuck_inner_sensor_feeds_the_pid(rig):
    ev = {"kind": "sensor_fault", "time": 0.05, "plane": 2, "axis": "x", "mode": "zero"}
    blk = _sim(rig, [UNB, ev], 20.0, 32).advance(64)
    assert np.all(blk.truth["step_by_step"][blk.time >= 0.05])
    assert np.all(blk.displacement[blk.time >= 0.05, 2] == 0.0)


def test_channel_loss_removes_the_force_of_that_axis(rig):
    ev = {"kind": "amb_channel_loss", "time": 0.05, "axis": "b2y", "coils": "both"}
    blk = _sim(rig, [UNB, ev], 20.0, 32).advance(100)
    on = blk.time >= 0.05
    assert np.all(blk.truth["amb_force"][on, 3] == 0.0)
    before = (blk.time > 0.02) & ~on
    assert np.all(blk.truth["amb_force"][before, 3] != 0.0)


def test_speed_profile_run_up(rig):
    rig = dataclasses.replace(
        rig, simulation=dataclasses.replace(rig.simulation, speed_quantum=0.25)
    )
    sc = scenario_from_dict(
        {
            "speed_profile": [{"time": 0.0, "hz": 10.0}, {"time": 1.0, "hz": 20.0}],
            "duration": 1.0,
            "events": [UNB],
        },
        rig,
    )
    sim = PlantSimulator(rig, sc, 16)
    blk = sim.advance(60)
    f = blk.omega / (2 * math.pi)
    assert f[0] == pytest.approx(10.0) and np.all(np.diff(f) >= -1e-9)
    # each sample advances the angle by 2 pi / 16 at the speed of that sample
    np.testing.assert_allclose(np.diff(blk.time), 1.0 / (16 * f[:-1]), rtol=1e-9)
    np.testing.assert_allclose(blk.angle, 2 * math.pi * (np.arange(60) % 16) / 16)
    assert f[-1] > 13.0 and np.all(blk.truth["step_by_step"])
    expected_f = 10.0 + 10.0 * blk.time  # the profile, rounded to the speed quantum
    np.testing.assert_allclose(f, expected_f, atol=rig.simulation.speed_quantum)


def test_invalid_calls_are_refused(rig):
    sim = _sim(rig, [], 20.0, 32)
    with pytest.raises(SimulationError, match="shape"):
        sim.advance(5, wavelet_force=np.zeros((4, 4)))
    with pytest.raises(SimulationError, match="n_samples"):
        sim.advance(0)
    with pytest.raises(SimulationError, match="power of two"):
        PlantSimulator(rig, sim.scenario, 48)
    with pytest.raises(ValueError, match="unknown event kind"):
        sim.inject({"kind": "earthquake"})
