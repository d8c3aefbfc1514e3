"""Early action on a sudden unbalance (issue 18 item 4, amb_controller.early_action).

References: a synthetic linear plant whose responses are written here from a damped
two-mode impulse response (closed form), the measurements built by direct convolution
(``numpy.convolve``, not the module's block Toeplitz matrices), and, on the simulated rig,
the scenario's own fault (430 g cm at D1: the estimate must find it) and the period-rate
controller's peak.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from amb_controller.early_action import EarlyAction, EarlyActionConfig
from amb_controller.early_model import EarlyActionModel, EarlyModelBank
from amb_controller.early_stage import EarlyStage
from amb_controller.errors import ControllerValueError, ShapeError
from amb_controller.model_file import write_npz

N = 16  # samples per revolution
L = 6 * N
SIGMA = 0.2e-6


def _impulse(n: int, f: float, zeta: float, gain: float) -> np.ndarray:
    """Sampled impulse response of a damped mode, frequency ``f`` cycles per sample."""
    k = np.arange(n)
    w = 2 * math.pi * f
    return gain * np.exp(-zeta * w * k) * np.sin(w * math.sqrt(1 - zeta**2) * k)


def _synthetic_model() -> EarlyActionModel:
    """Two sensors, four axes, two planes; each path a mix of two damped modes."""
    rng = np.random.default_rng(3)
    h1, h2 = _impulse(L, 1 / N, 0.15, 1e-6), _impulse(L, 3 / N, 0.1, 0.4e-6)
    mix = rng.uniform(-1, 1, (2, 2, 4))  # (mode, sensor, axis)
    bearing = np.einsum("n,sa->nsa", h1, mix[0]) + np.einsum("n,sa->nsa", h2, mix[1])
    lp = 40 * N  # the plant runs on these too: longer than the module needs
    g1, g2 = _impulse(lp, 1 / N, 0.15, 1.0), _impulse(lp, 3 / N, 0.1, 0.5)
    planes = []
    for p in range(2):
        pair = []
        for c in range(2):  # a rotating force cos/sin from its onset through each mode
            k = np.arange(lp)
            drive = np.cos(2 * math.pi * k / N + c * math.pi / 2)
            w = rng.uniform(-1, 1, (2, 2))  # (mode, sensor)
            r1 = np.convolve(drive, g1)[:lp]
            r2 = np.convolve(drive, g2)[:lp]
            pair.append(np.outer(r1, w[0]) + np.outer(r2, w[1]))
        planes.append(np.stack(pair, axis=2) * (1 + p) * 1e-3)
    return EarlyActionModel(N, bearing, np.array(planes), ("P1", "P2"), (0, 1))


def _measure(model, n_periods, onset, plane, theta, force=None, offset_at=None):
    """Sensor samples: noise + the change's response (+ the force's, + a probe offset)."""
    rng = np.random.default_rng(11)
    n = n_periods * N
    y = rng.normal(0.0, SIGMA, (n, 2))
    g = model.plane_responses[plane]
    ln = min(n - onset, g.shape[0])
    y[onset : onset + ln] += g[:ln] @ theta
    if force is not None:
        h = model.bearing_markov
        for s in range(2):
            for a in range(4):
                y[:, s] += np.convolve(force[:, a], h[:, s, a])[:n]
    if offset_at is not None:
        y[offset_at:, 0] += 20 * SIGMA
    return y


def _run(early, y, force=None):
    force = np.zeros((len(y), 4)) if force is None else force
    found = []
    for m in range(len(y) // N):
        d = early.end_period(m, y[m * N : (m + 1) * N], force[m * N : (m + 1) * N])
        if d is not None:
            found.append(d)
    return found


@pytest.mark.parametrize("onset_phase", [3, 9, 14])
@pytest.mark.parametrize("plane", [0, 1])
def test_a_change_is_found_in_its_own_period_with_its_plane_and_unbalance(onset_phase, plane):
    """Onset, plane and unbalance from the samples of the fault's own period.

    The response is ~1e3 times the noise, so the estimate is exact to well under 1 % once
    two or more samples carry it; a loss two samples before the period's end leaves one
    sample of response (the first is zero: a force acts on the next sample), which fixes the
    onset and the plane but not the angle (one sample of a rotating force's response).
    """
    model = _synthetic_model()
    early = EarlyAction(model, EarlyActionConfig(), delay=1)
    onset = 20 * N + onset_phase
    theta = np.array([0.3, -0.2])  # kg m (me cos, me sin)
    found = _run(early, _measure(model, 26, onset, plane, theta))
    assert len(found) == 1
    d = found[0]
    assert d.plane == model.planes[plane]
    assert abs(d.onset_sample - onset) <= 1
    # the fault's period, or the next one when it came in the period's last samples
    assert d.period in (20, 21)
    assert d.first_period == d.period + 1
    if onset_phase < N - 2:
        assert d.me == pytest.approx(math.hypot(*theta), rel=0.01)
        assert d.angle == pytest.approx(math.atan2(theta[1], theta[0]), abs=0.01)


def test_noise_alone_and_a_probe_offset_are_not_an_unbalance():
    """A step on one probe is not a rotating force's response: the residual test refuses it."""
    model = _synthetic_model()
    early = EarlyAction(model, EarlyActionConfig(), delay=1)
    assert _run(early, _measure(model, 60, 0, 0, np.zeros(2))) == []
    early.reset()
    assert _run(early, _measure(model, 40, 0, 0, np.zeros(2), offset_at=25 * N + 5)) == []


def test_the_controller_s_own_force_is_not_a_change():
    """z removes the applied force's response: a feedback step does not trigger the test."""
    model = _synthetic_model()
    early = EarlyAction(model, EarlyActionConfig(), delay=1)
    force = np.zeros((40 * N, 4))
    force[22 * N :, 1] = 30.0 * np.cos(2 * math.pi * np.arange(18 * N) / N)
    y = _measure(model, 40, 0, 0, np.zeros(2), force=force)
    assert _run(early, y, force) == []


def test_the_plan_cancels_the_change_on_the_linear_plant():
    """Closed loop on the synthetic plant: after the plan the response is back to noise."""
    model = _synthetic_model()
    early = EarlyAction(model, EarlyActionConfig(force_budget=1.0), delay=1)
    onset, theta, n_per = 20 * N + 6, np.array([0.3, -0.2]), 34
    g = model.plane_responses[0]
    h = model.bearing_markov
    rng = np.random.default_rng(5)
    y = rng.normal(0.0, SIGMA, (n_per * N, 2))
    y[onset:] += g[: n_per * N - onset] @ theta
    free_peak = np.abs(y[onset:]).max()
    force = np.zeros((n_per * N, 4))
    for m in range(n_per):
        # the plant's response to the force applied so far (direct convolution)
        rows = slice(m * N, (m + 1) * N)
        seen = y[rows].copy()
        for s in range(2):
            for a in range(4):
                seen[:, s] += np.convolve(force[:, a], h[:, s, a])[rows]
        early.end_period(m, seen, force[rows])
        if m + 1 < n_per:
            force[(m + 1) * N : (m + 2) * N] = early.force(m + 1)
        y[rows] = seen
    assert len(early.detections) == 1 and early.detections[0].acted
    tail = np.abs(y[-4 * N :]).max()
    assert tail < 0.1 * free_peak


def test_the_plan_stands_down_when_it_would_reach_the_clearance():
    model = _synthetic_model()
    early = EarlyAction(replace(model, clearance=1e-9), EarlyActionConfig(), delay=1)
    found = _run(early, _measure(model, 26, 20 * N + 5, 0, np.array([0.3, -0.2])))
    assert len(found) == 1 and not found[0].acted
    assert not early.force(22).any()


def test_each_sensor_s_prediction_is_checked_against_its_own_clearance():
    """On the rig the outer probes read against the 0.9 mm retainers, the inner ones against the
    0.75 mm auxiliary bearings: a plan whose largest displacement is at a sensor with room to
    spare is applied where the smallest clearance for every sensor would refuse it."""
    model = _synthetic_model()
    config = EarlyActionConfig()
    y = _measure(model, 26, 20 * N + 5, 0, np.array([0.3, -0.2]))
    (free,) = _run(EarlyAction(model, config, delay=1), y)
    tight = (1 + config.gain_margin) * free.predicted_peak  # the largest sensor's share is 1
    shares = [
        _run(EarlyAction(replace(model, clearance=c), config, delay=1), y)[0].clearance_share
        for c in ((tight, math.inf), (math.inf, tight))
    ]
    largest = int(np.argmax(shares))
    other = 1 - largest
    ratio = shares[other]  # the other sensor's predicted peak over the largest one's
    assert shares[largest] == pytest.approx(1.0, rel=1e-9) and ratio < 0.95, shares
    per_sensor = [0.0, 0.0]
    per_sensor[largest] = 1.05 * tight
    per_sensor[other] = 0.5 * (1.0 + ratio) * tight  # between that sensor's need and `tight`
    (found,) = _run(EarlyAction(replace(model, clearance=tuple(per_sensor)), config, delay=1), y)
    expected = max(1 / 1.05, 2 * ratio / (1 + ratio))  # each sensor's peak over its clearance
    assert found.acted and found.clearance_share == pytest.approx(expected, rel=1e-9)
    (one,) = _run(EarlyAction(replace(model, clearance=min(per_sensor)), config, delay=1), y)
    assert not one.acted and one.clearance_share > 1.0


def test_the_clearance_check_reads_the_measured_motion_not_the_forceless_reference():
    """A feedback force that cancels a large steady unbalance is no motion of the rotor.

    The reference ``z`` has the applied force's response taken out: under a feedback law that
    cancels a steady unbalance, it is the uncontrolled response, while the rotor barely moves.
    The check adds the measured motion (contact_case2 of amb-compare: the law held the inner
    probes at 1 um, its reference was 353 um, and a plan that lowered the peak from 303 to
    271 um without a contact was refused). Here the force's response is 20 x the change's
    peak and the clearance only twice the predicted peak with its margin: on the reference
    the plan would stand down.
    """
    model = _synthetic_model()
    onset, theta = 20 * N + 5, np.array([0.3, -0.2])
    y = _measure(model, 26, onset, 0, theta)
    change_peak = float(np.abs(y[onset:]).max())
    k = np.arange(len(y))
    force = np.zeros((len(y), 4))
    force[:, 1] = np.cos(2 * math.pi * k / N)  # steady from the start, periodic in z
    h = model.bearing_markov
    unit = max(np.abs(np.convolve(force[:, 1], h[:, s, 1])[: len(y)])[L:].max() for s in range(2))
    force *= 20 * change_peak / unit
    free = EarlyAction(model, EarlyActionConfig(), delay=1)
    (probe,) = _run(free, y, force)  # infinite clearance: always acted
    assert probe.acted
    config = EarlyActionConfig()
    clearance = 2 * (1 + config.gain_margin) * probe.predicted_peak
    assert clearance < 20 * change_peak  # the forceless reference alone would not fit
    early = EarlyAction(replace(model, clearance=clearance), config, delay=1)
    (found,) = _run(early, y, force)
    assert found.acted and found.predicted_peak < 1.5 * change_peak
    assert early.force(found.first_period).any()


def test_the_stage_flags_the_axes_whose_command_the_limit_cut():
    """The plan added to the law's command may pass the force limit: the stage clips it and says
    on which axes (the command's ``saturated``), and leaves a command it adds nothing to as is.

    The law's force on the period the plan starts is set, on one axis, just inside the limit and
    in the plan's direction: the sum passes the limit there and nowhere else. (3 kN and the
    smoothing 2: the plan's peak is 143 N, its transient far inside its share of the limit.)
    """
    import copy

    model = _synthetic_model()
    y = _measure(model, 26, 20 * N + 5, 0, np.array([0.3, -0.2]))

    def first_plan(limit):
        stage = EarlyStage(model, EarlyActionConfig(transient_smoothing=2.0), delay=1)
        zeros = np.zeros((4, N))
        for m in range(26):
            for k in range(N):
                stage.sample(k, y[m * N + k])
            before = copy.deepcopy(stage)
            out, _, clipped = stage.end_period(m, m + 1, zeros, True, True, limit)
            if out.any():
                return out, clipped, before, m
            assert out is zeros and not clipped.any()  # nothing added: passed on as is
        raise AssertionError("no plan: the stage found no change")

    limit = np.full(4, 3000.0)
    plan, clipped, law_stage, period = first_plan(limit)
    assert not clipped.any() and (np.abs(plan) < 0.1 * limit[:, None]).all()
    axis = int(np.argmax(np.abs(plan).max(axis=1)))
    k = int(np.argmax(np.abs(plan[axis])))
    law = np.zeros((4, N))
    law[axis] = 0.99 * limit[axis] * np.sign(plan[axis, k])
    out, _, clipped = law_stage.end_period(period, period + 1, law, True, True, limit)
    expected = (np.abs(law + plan) > limit[:, None]).any(axis=1)
    assert expected[axis] and expected.sum() == 1
    np.testing.assert_array_equal(clipped, expected)
    np.testing.assert_array_equal(out, np.clip(law + plan, -limit[:, None], limit[:, None]))


def _applied_steps(early, detection, periods=8):
    """Largest sample-to-sample step of the planned force, from zero before it (np.diff)."""
    first = detection.first_period
    force = np.concatenate([early.force(m) for m in range(first - 1, first + periods)])
    return float(np.abs(np.diff(force, axis=0)).max())


@pytest.mark.parametrize("fraction", [0.5, 0.02])
def test_the_plan_steps_no_faster_than_the_amplifiers_allow(fraction):
    """(E4): the bound is ``slew_budget x slew_rate x 2 pi / (omega N)`` N per sample, here set
    to a ``fraction`` of the unbounded plan's largest step: at a half the plan is made smoother
    (a larger mu of the ladder), at 2 % even the smoothest is too fast and the plan is scaled
    down; either way its steps (differenced here from the forces it adds) keep within it."""
    model = _synthetic_model()
    y = _measure(model, 26, 20 * N + 5, 0, np.array([0.3, -0.2]))
    rough = EarlyActionConfig(transient_smoothing=0.0)
    free = EarlyAction(replace(model, omega=2 * math.pi * 20.0), rough, delay=1)
    (d0,) = _run(free, y)
    assert math.isinf(free.step_limit) and d0.smoothing == 0.0
    unbounded = _applied_steps(free, d0)
    assert d0.largest_step == pytest.approx(unbounded, rel=1e-6)
    omega = 2 * math.pi * 20.0
    sample_time = 2 * math.pi / (omega * N)
    config = replace(rough, slew_budget=0.5)
    limit = fraction * unbounded
    slew = limit / (config.slew_budget * sample_time)  # N/s
    early = EarlyAction(replace(model, omega=omega, slew_rate=slew), config, delay=1)
    assert early.step_limit == pytest.approx(limit, rel=1e-12)
    (d,) = _run(early, y)
    assert d.acted and d.smoothing > 0.0
    assert _applied_steps(early, d) <= limit * (1 + 1e-6)
    assert d.largest_step == pytest.approx(_applied_steps(early, d), rel=1e-6)
    if fraction == 0.02:  # scaled down: exactly at the bound
        assert d.smoothing == 16.0 and d.largest_step == pytest.approx(limit, rel=1e-9)


def test_bad_settings_and_shapes_are_refused():
    with pytest.raises(ControllerValueError, match="threshold"):
        EarlyActionConfig(threshold=1.0)
    with pytest.raises(ControllerValueError, match="arm_periods"):
        EarlyActionConfig(reference_periods=6, arm_periods=4)
    with pytest.raises(ControllerValueError, match="force_budget"):
        EarlyActionConfig(force_budget=0.0)
    with pytest.raises(ControllerValueError, match="slew_budget"):
        EarlyActionConfig(slew_budget=1.5)
    model = _synthetic_model()
    with pytest.raises(ShapeError, match="L_p"):
        replace(model, plane_responses=model.plane_responses[:, : L + N])
    with pytest.raises(ShapeError, match="sensors"):
        replace(model, sensors=(0,))
    with pytest.raises(ControllerValueError, match="slew_rate"):
        replace(model, slew_rate=0.0)
    early = EarlyAction(model, EarlyActionConfig(), delay=1)
    with pytest.raises(ShapeError):
        early.end_period(0, np.zeros((N, 3)), np.zeros((N, 4)))
    with pytest.raises(ControllerValueError, match="delay"):
        EarlyAction(model, EarlyActionConfig(), delay=0)


def _banked(model, omegas):
    """Copies of ``model`` at speeds ``omegas`` (rad/s); the k-th response scaled by k + 1."""
    return EarlyModelBank(
        tuple(
            replace(model, omega=w, plane_responses=model.plane_responses * (k + 1))
            for k, w in enumerate(omegas)
        )
    )


def test_the_bank_keeps_its_models_through_its_file_and_reads_a_single_model(tmp_path):
    model = _synthetic_model()
    bank = _banked(model, (110.0, 100.0, 105.0))
    np.testing.assert_array_equal(bank.omegas, [100.0, 105.0, 110.0])  # sorted
    back = EarlyModelBank.load(bank.save(tmp_path / "bank.npz"))
    np.testing.assert_array_equal(back.omegas, bank.omegas)
    for a, b in zip(back.models, bank.models, strict=True):
        np.testing.assert_array_equal(a.plane_responses, b.plane_responses)
        np.testing.assert_array_equal(a.bearing_markov, b.bearing_markov)
        assert (a.planes, a.sensors, a.objective) == (b.planes, b.sensors, b.objective)
        assert math.isinf(a.slew_rate)  # none given: not bounded, and kept so
    slewed = EarlyModelBank(tuple(replace(m, slew_rate=7.15e5) for m in bank.models))
    back = EarlyModelBank.load(slewed.save(tmp_path / "slewed.npz"))
    assert [m.slew_rate for m in back.models] == [7.15e5] * 3
    # a file of format 1 (one model, no leading axis: what amb-early-model wrote before banks)
    meta = {
        "format": "amb-early-action-1", "samples_per_rev": N, "planes": list(model.planes),
        "sensors": list(model.sensors), "objective": list(model.objective),
        "clearance": 1e-3, "omega": 42.0, "source": "fe",
    }  # fmt: skip
    old = write_npz(
        tmp_path / "one.npz", meta, bearing_markov=model.bearing_markov,
        plane_responses=model.plane_responses,
    )  # fmt: skip
    (one,) = EarlyModelBank.load(old).models
    assert one.omega == 42.0 and one.clearance == (1e-3, 1e-3) and math.isinf(one.slew_rate)
    # per sensor, none by the second (inf, null in the file's JSON)
    apart = replace(model, clearance=(8e-4, math.inf))
    assert EarlyActionModel.load(apart.save(tmp_path / "apart.npz")).clearance == (8e-4, math.inf)
    with pytest.raises(ShapeError, match="clearance"):
        replace(model, clearance=(1e-3, 1e-3, 1e-3))
    with pytest.raises(ControllerValueError, match="clearances must be > 0"):
        replace(model, clearance=(1e-3, 0.0))
    assert EarlyActionModel.load(old).omega == 42.0
    with pytest.raises(ControllerValueError, match="a bank of 3"):
        EarlyActionModel.load(tmp_path / "bank.npz")


def test_a_bank_refuses_models_that_differ_in_more_than_their_speed():
    model = _synthetic_model()
    with pytest.raises(ControllerValueError, match="distinct"):
        _banked(model, (100.0, 100.0))
    with pytest.raises(ShapeError, match="more than its responses"):
        EarlyModelBank((replace(model, omega=1.0), replace(model, omega=2.0, clearance=1e-3)))
    with pytest.raises(ControllerValueError, match="at least one"):
        EarlyModelBank(())


def test_the_bank_picks_the_nearest_model_within_the_tolerance_and_does_not_chatter():
    bank = _banked(_synthetic_model(), (100.0, 101.0, 102.0))
    tol = 0.006
    assert bank.select(100.2, tol) == 0
    assert bank.select(101.4, tol) == 1
    assert bank.select(102.5, tol) == 2  # 0.5 rad/s above 102; 0.6 % of 102.5 is 0.615
    assert bank.select(102.7, tol) is None  # 0.7 rad/s off, 0.616 allowed
    assert bank.select(98.9, tol) is None
    # at the midpoint the model in use is kept until another is a quarter spacing nearer
    assert bank.select(100.6, tol, current=0) == 0  # 0.6 vs 0.4 off: 0.2 < 0.25
    assert bank.select(100.7, tol, current=0) == 1  # 0.7 vs 0.3: 0.4 >= 0.25
    assert bank.select(100.4, tol, current=1) == 1
    assert bank.select(100.3, tol, current=1) == 0
    # one model of no recorded speed: always that one
    assert EarlyModelBank((_synthetic_model(),)).select(1234.0, tol) == 0


def test_the_stage_tests_with_the_model_of_the_measured_speed():
    """Two models whose responses differ by a factor 2: the change, made with the second,
    is estimated at its size only when the measured speed selects the second; at a speed
    far from both the stage tests nothing (and counts the idle periods)."""
    model = _synthetic_model()
    bank = _banked(model, (100.0, 120.0))
    theta = np.array([0.3, -0.2])
    y = _measure(replace(model, plane_responses=2 * model.plane_responses), 26, 20 * N + 5, 0,
                 theta)  # fmt: skip

    def run(omega):
        stage = EarlyStage(bank, EarlyActionConfig(), delay=1)
        for m in range(26):
            for k in range(N):
                stage.sample(k, y[m * N + k], omega)
            stage.end_period(m, m + 1, np.zeros((4, N)), True, True, np.full(4, 1e4))
        return stage

    at = run(120.3)
    assert at.model_omega == 120.0
    (d,) = at.detections
    assert d.me == pytest.approx(math.hypot(*theta), rel=0.01)
    wrong = run(100.1)
    assert wrong.model_omega == 100.0
    assert [d.me for d in wrong.detections] != pytest.approx([math.hypot(*theta)], rel=0.1)
    idle = run(110.0)
    assert idle.early is None and idle.detections == [] and idle.speed_idle_periods == 26


def test_a_large_change_the_model_fits_all_but_a_sliver_of_is_accepted():
    """The measured change is the model's response on a time axis stretched by 0.5 % (what a
    model 0.5 % off the running speed sees, unlike a gain error, which the estimate absorbs):
    for a large change the residual is many noise variances, yet a sliver of the innovation.
    ``max_unexplained`` accepts it; with it at 0 (the residual test alone) nothing is decided.
    The residual test still refuses a probe offset (the test above) and noise."""
    model = _synthetic_model()
    theta = np.array([0.9, -0.6])  # 3 x the loss above
    g = model.plane_responses
    k = np.arange(g.shape[1])
    stretched = np.apply_along_axis(lambda r: np.interp(k * 1.005, k, r), 1, g)
    y = _measure(replace(model, plane_responses=stretched), 26, 20 * N + 6, 0, theta)
    found = _run(EarlyAction(model, EarlyActionConfig(), delay=1), y)
    assert len(found) == 1 and found[0].residual > EarlyActionConfig().max_residual
    assert found[0].me == pytest.approx(math.hypot(*theta), rel=0.05)
    strict = EarlyAction(model, EarlyActionConfig(max_unexplained=0.0), delay=1)
    assert _run(strict, y) == []


def test_the_operator_is_told_which_model_is_in_use_and_when_none_is():
    from amb_controller.early_messages import model_change_message

    bank = _banked(_synthetic_model(), (100.0, 120.0))
    stage = EarlyStage(bank, EarlyActionConfig(), delay=1)

    def period(omega, stage=stage):
        for k in range(N):
            stage.sample(k, np.zeros(2), omega)
        stage.end_period(0, 1, np.zeros((4, N)), True, True, np.full(4, 1e3))
        return model_change_message(stage, omega)

    ok, text = period(120.2)
    assert ok and f"model of {120.0 / (2 * math.pi):.3f} Hz" in text
    assert "not slew-bounded" in text
    slewed = EarlyStage(
        EarlyModelBank(tuple(replace(m, slew_rate=1e5) for m in bank.models)),
        EarlyActionConfig(),
        delay=1,
    )
    ok, text = period(120.2, slewed)
    # 0.6 x 1e5 N/s over one sample of 2 pi / (120 rad/s x 16)
    limit = 0.6 * 1e5 * 2 * math.pi / (120.0 * N)
    assert ok and f"at most {limit:.0f} N per sample" in text
    ok, text = period(110.0)
    assert not ok and "no model within 0.5%" in text and "testing nothing" in text


def test_a_partial_period_is_tested_with_the_force_that_acted():
    # a realtime plant applied period 1's command from its sample 5 on (partial_commands): the
    # model's test of period 1 must take that force, zeros before sample 5; of a period reported
    # missing, zeros throughout; of a period run whole, the command itself
    stage = EarlyStage(_synthetic_model(), EarlyActionConfig(), delay=1)
    taken = []
    test_period = stage.early.end_period

    def spy(period, y, applied):
        taken.append((period, np.array(applied)))
        return test_period(period, y, applied)

    stage.early.end_period = spy
    command = np.arange(4 * N, dtype=float).reshape(4, N) + 1.0  # N per axis and sample
    limit = np.full(4, 1e4)
    for m, report in enumerate(("whole", "partial", "missing", "whole")):
        if report != "whole":
            stage.command_missing(m)
        if report == "partial":
            stage.command_resumed(m, 5)
        for k in range(N):
            stage.sample(k, np.zeros(8), 100.0)
        stage.end_period(m, m + 1, command, True, True, limit)
    expected = {1: command.copy(), 2: np.zeros((4, N)), 3: command}
    expected[1][:, :5] = 0.0
    for period, applied in taken[1:]:
        np.testing.assert_array_equal(applied.T, expected[period])
    assert [p for p, _ in taken] == [0, 1, 2, 3]
