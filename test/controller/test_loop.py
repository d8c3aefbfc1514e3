"""Synthesis, saturation with hold, divergence guard, supervisor modes and model file."""

import numpy as np
import pytest
import pywt

from amb_common.faults import FaultType
from amb_controller.basis import control_basis, measurement_basis
from amb_controller.config import ControllerConfig
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.identification import MarkovIdentifier, StepExperiment
from amb_controller.inverse import pseudo_inverse_series
from amb_controller.model_file import WaveletModel
from amb_controller.response import PrescribedResponse
from amb_controller.supervisor import (
    AUX_BEARING_CONTACT,
    COIL_FAILURE,
    Mode,
    WaveletControlSupervisor,
)
from amb_controller.synthesis import ForceLimiter, synthesize
from amb_controller.transient import TransientController
from amb_wavelet.synthesis import basis_function

N = 32


@pytest.mark.filterwarnings("ignore:Level value")
def test_synthesis_round_trips_through_pywt_periodised_analysis():
    basis = control_basis("db4", N, [1, 2, 3], n_axes=4, quadratures=["even"])
    rng = np.random.default_rng(0)
    u = rng.normal(size=basis.n_coefficients)
    force = synthesize(u, basis)
    # analyse each axis with PyWavelets (periodization) and read the coefficients back
    for axis in range(4):
        coeffs = pywt.wavedec(force[axis], "db4", mode="periodization", level=5)
        for p in (1, 2, 3):
            for q in range(1, 2 ** (p - 1) + 1):
                i = basis.labels.index(f"p{p}/q{q}/even/c{axis}")
                assert coeffs[p][q - 1] == pytest.approx(u[i], abs=1e-12)


def test_haar_control_waveforms_are_amb_wavelet_basis_functions():
    basis = control_basis("haar", N, [1, 2], n_axes=1, quadratures=["even"])
    r = 5
    for p, q in ((1, 1), (2, 1), (2, 2)):
        j = r - p + 1
        psi = basis_function("haar", j)
        expected = np.zeros(N)
        expected[(q - 1) * 2**j : q * 2**j] = psi
        i = basis.labels.index(f"p{p}/q{q}/even/c0")
        np.testing.assert_allclose(basis.weights[i, 0], expected, atol=1e-15)


def test_odd_waveform_is_seen_only_by_odd_analysis_at_one_x():
    # a force equal to the odd waveform, repeated every period, gives even = 0, odd = 1
    cb = control_basis("haar", N, [1], n_axes=1)
    mb = measurement_basis("haar", N, [1], n_channels=1)
    odd = cb.weights[cb.labels.index("p1/q1/odd/c0"), 0]
    periodic = np.tile(odd, 3)
    start = 2 * N + mb.offset
    window = periodic[start : start + mb.weights.shape[2]]
    coeffs = mb.weights[:, 0, :] @ window
    np.testing.assert_allclose(coeffs, [0.0, 1.0], atol=1e-12)


def test_force_limiter_scales_saturated_axis_only():
    basis = control_basis("haar", N, [1], n_axes=4, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=100.0, capacity=1000.0)
    u = np.array([10.0, 1000.0, -2000.0, 0.0])  # peaks u / sqrt(32)
    result = limiter.apply(u)
    peaks = np.abs(u) / np.sqrt(N)
    np.testing.assert_array_equal(result.saturated, peaks > 100.0)
    np.testing.assert_allclose(result.peak, np.minimum(peaks, 100.0), rtol=1e-12)
    np.testing.assert_allclose(result.coefficients[0], 10.0)
    assert np.max(np.abs(result.force)) <= 100.0 + 1e-9
    with pytest.raises(ValueError, match="capacity"):
        ForceLimiter(basis, limit=2000.0, capacity=1000.0)


def test_guard_trips_on_growth_and_bounds():
    guard = DivergenceGuard(
        GuardConfig(coefficient_bound=10.0, growth_factor=1.1, growth_periods=3)
    )
    for k in range(5):
        assert not guard.update(np.array([1.0 + 0.01 * k]))
    assert not guard.update(np.array([1.2]))
    assert not guard.update(np.array([1.4]))
    assert guard.update(np.array([1.6]))
    assert "grew" in guard.reason
    guard.reset()
    assert guard.update(np.array([11.0])) and "bound" in guard.reason
    guard = DivergenceGuard(GuardConfig(displacement_bound=0.5e-3))
    assert guard.update(np.zeros(2), displacement_peak=0.6e-3)


def _supervised_loop(markov, sup, n_periods, disturbance, lost=(), report=True):
    """Coefficient-domain plant Q[k] = sum_j A_j (F + U)[k-j]; U = commands by target period.

    Commands for the periods in ``lost`` never reach the plant (zero force there); with
    ``report`` the supervisor is told when such a period starts, before its own step (the
    plant's ``STATUS_COMMAND_MISSING``).
    """
    n_u = markov.shape[2]
    u = np.zeros((n_periods + 10, n_u))
    q_all, cmds = [], []
    for k in range(n_periods):
        if k in lost:
            u[k] = 0.0
            if report:
                sup.command_missing(k)
        q = sum(markov[j] @ (disturbance[k - j] + u[k - j]) for j in range(min(k + 1, len(markov))))
        cmd = sup.step(k, q)
        u[cmd.target_period] = cmd.coefficients
        q_all.append(q)
        cmds.append(cmd)
    return np.array(q_all), cmds


def _one_axis_setup(limit=1000.0):
    basis = control_basis("haar", N, [1], n_axes=1, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=limit, capacity=1000.0)
    markov = np.array([0.3, 0.5, 0.2]).reshape(3, 1, 1) * 1e-5  # m per coefficient
    return basis, limiter, markov


def test_supervisor_identifies_then_controls():
    _, limiter, markov = _one_axis_setup()
    sup = WaveletControlSupervisor(limiter, delay=2)
    exp = StepExperiment(1, [0], amplitude=100.0, periods_per_step=8, start_period=2)
    sup.start_identification(exp, MarkovIdentifier(1, 1, order=4))
    disturbance = np.zeros((200, 1))
    k = 0
    u = np.zeros((300, 1))
    while sup.mode == Mode.IDENTIFYING:
        q = sum(markov[j] @ u[k - j] for j in range(min(k + 1, 3))) + 1e-6  # + background
        cmd = sup.step(k, q)
        u[cmd.target_period] = cmd.coefficients
        k += 1
    result = sup.identification_result
    np.testing.assert_allclose(result.markov[:3], markov, atol=1e-12)
    np.testing.assert_allclose(result.markov[3:], 0.0, atol=1e-12)
    inv = pseudo_inverse_series(result.markov, order=5)
    sup.set_controller(TransientController(inv, PrescribedResponse.exponential(0.75, 0.75), 2))
    assert sup.set_mode(Mode.ACTIVE)[0]
    disturbance[:] = 50.0
    q, _ = _supervised_loop(markov, sup, 150, disturbance)
    assert abs(q[-1, 0]) < 1e-3 * abs(q[5, 0])


def test_saturation_holds_controller_state():
    _, limiter, markov = _one_axis_setup(limit=5.0)  # 5 N: saturates at once
    ctrl = TransientController(
        pseudo_inverse_series(markov, order=5), PrescribedResponse.exponential(0.75, 0.75), 2
    )
    sup = WaveletControlSupervisor(limiter, delay=2, controller=ctrl)
    sup.set_mode(Mode.ACTIVE)
    _q, cmds = _supervised_loop(markov, sup, 40, np.full((40, 1), 500.0))
    saturated = [c for c in cmds if c.saturated.any()]
    assert saturated and all(c.hold for c in saturated)
    assert max(np.max(np.abs(c.force)) for c in cmds) <= 5.0 + 1e-9
    # held: the integrator never wound up beyond what one unsaturated step would give
    assert np.all(np.abs(ctrl.get_state().zi) < 1e3)


@pytest.mark.parametrize("delay", [1, 2, 3])
def test_a_lost_command_undoes_the_step_that_made_it(delay):
    _, limiter, markov = _one_axis_setup()
    inverse = pseudo_inverse_series(markov, order=5)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    sup = WaveletControlSupervisor(
        limiter, delay=delay, controller=TransientController(inverse, alpha, delay)
    )
    sup.set_mode(Mode.ACTIVE)
    disturbance = np.full((60, 1), 50.0)
    lost = {20, 21, 30}
    q, _ = _supervised_loop(markov, sup, 45, disturbance, lost)
    # the same measurements into a twin controller that skips the steps whose command was lost
    twin = TransientController(inverse, alpha, delay)
    for k in range(45):
        if k + delay in lost:
            twin.skip(k)
        else:
            twin.step(k, q[k])
    state = sup.controller.get_state()
    np.testing.assert_allclose(state.zi, twin.get_state().zi, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(state.history, twin.get_state().history, rtol=1e-12, atol=0.0)
    assert all(not sup.applied(p).any() for p in lost if p >= 45 - delay - 1)


def test_lost_commands_do_not_wind_up_the_integrators():
    # Rotor converged on a step disturbance, then 20 periods of lost commands (a controller
    # stall or restart behind the plant's watchdog): the response goes to the uncontrolled
    # level. When commands return it must not go beyond it.
    _, limiter, markov = _one_axis_setup()
    inverse = pseudo_inverse_series(markov, order=5)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    disturbance = np.zeros((120, 1))
    disturbance[5:] = 50.0
    uncontrolled = abs(markov.sum(axis=0)[0, 0] * 50.0)  # G(1) d: PID alone, steady
    lost = set(range(40, 60))
    peaks = {}
    for report in (True, False):
        sup = WaveletControlSupervisor(
            limiter, delay=1, controller=TransientController(inverse, alpha, 1)
        )
        sup.set_mode(Mode.ACTIVE)
        q, _ = _supervised_loop(markov, sup, 120, disturbance, lost, report=report)
        assert abs(q[39, 0]) < 0.01 * uncontrolled  # converged before the loss
        peaks[report] = np.max(np.abs(q[60:, 0]))
        assert abs(q[-1, 0]) < 0.01 * uncontrolled  # and again after
    # reported: the integrators held the force that last acted (0.45 of it here)
    assert peaks[True] < 0.5 * uncontrolled
    assert peaks[False] > 3.0 * uncontrolled  # unreported, they wound up (3.8 here)


def test_guard_trip_zeroes_force_and_fault_holds():
    _, limiter, markov = _one_axis_setup()
    ctrl = TransientController(
        np.full((1, 1, 1), -1e5), PrescribedResponse.exponential(0.3, 0.5), 2
    )
    guard = DivergenceGuard(GuardConfig(growth_factor=1.05, growth_periods=4, noise_floor=1e-9))
    sup = WaveletControlSupervisor(limiter, delay=2, controller=ctrl, guard=guard)
    sup.set_mode(Mode.ACTIVE)
    _q, cmds = _supervised_loop(markov, sup, 80, np.full((80, 1), 1.0))  # wrong-sign model
    tripped = [c for c in cmds if c.guard_tripped]
    assert tripped and tripped[-1].mode == Mode.HOLD
    assert np.all(tripped[-1].force == 0.0)
    assert not sup.set_mode(Mode.ACTIVE)[0]
    sup.reset()
    assert sup.set_mode(Mode.ACTIVE)[0]
    sup.step(0, np.zeros(1))
    last = sup.step(1, np.array([1e-6]))
    assert sup.on_fault(AUX_BEARING_CONTACT) == "hold" and sup.mode == Mode.HOLD
    held = sup.step(2, np.array([5e-6]))
    np.testing.assert_allclose(held.coefficients, last.coefficients)
    assert held.hold
    assert sup.on_fault(COIL_FAILURE) == "off" and sup.mode == Mode.OFF  # an actuator lost
    assert ControllerConfig(samples_per_rev=64).fault_actions == {2: "hold", 5: "off"}


def test_a_hold_on_a_provisional_contact_is_left_when_it_is_revised_or_withdrawn():
    """Issue 19: the reconfiguration acts on the earliest class; when the decision revises a
    provisional contact (or withdraws it), the HOLD it caused is left for ACTIVE."""
    _, limiter, _ = _one_axis_setup()
    ctrl = TransientController(np.full((1, 1, 1), 1e5), PrescribedResponse.exponential(0.3, 0.5), 2)
    sup = WaveletControlSupervisor(limiter, delay=2, controller=ctrl)
    assert sup.set_mode(Mode.ACTIVE)[0]
    assert sup.on_fault(AUX_BEARING_CONTACT, "withdrawn") == "ignore"  # void: no action
    assert sup.mode == Mode.ACTIVE
    # revised to a mass loss at the decision: control resumes
    assert sup.on_fault(AUX_BEARING_CONTACT, "provisional") == "hold" and sup.mode == Mode.HOLD
    assert sup.on_fault(FaultType.MASS_LOSS, "final", revised=True) == "resume"
    assert sup.mode == Mode.ACTIVE
    # confirmed at the decision: it holds on
    assert sup.on_fault(AUX_BEARING_CONTACT, "provisional") == "hold"
    assert sup.on_fault(AUX_BEARING_CONTACT, "final") == "hold" and sup.mode == Mode.HOLD
    # withdrawn (another fault's consequence): control resumes
    assert sup.set_mode(Mode.ACTIVE)[0]
    assert sup.on_fault(AUX_BEARING_CONTACT, "provisional") == "hold"
    assert sup.on_fault(AUX_BEARING_CONTACT, "withdrawn") == "resume"
    assert sup.mode == Mode.ACTIVE
    # a HOLD on a final contact is not left on a later revision of another episode
    assert sup.on_fault(AUX_BEARING_CONTACT) == "hold"
    assert sup.on_fault(FaultType.MASS_LOSS, "final", revised=True) == "ignore"
    assert sup.mode == Mode.HOLD
    # revised to a coil failure: resumed, then off as a coil failure asks
    assert sup.set_mode(Mode.ACTIVE)[0]
    assert sup.on_fault(AUX_BEARING_CONTACT, "provisional") == "hold"
    assert sup.on_fault(COIL_FAILURE, "final", revised=True) == "off"
    assert sup.mode == Mode.OFF


def test_model_file_round_trip(tmp_path):
    rng = np.random.default_rng(1)
    model = WaveletModel(
        markov=rng.normal(size=(6, 16, 8)),
        inverse=rng.normal(size=(6, 8, 16)),
        wavelet="haar",
        samples_per_rev=64,
        omega=2 * np.pi * 11,
        levels=(1,),
        control_labels=tuple(f"c{i}" for i in range(8)),
    )
    path = model.save(tmp_path / "model.npz")
    loaded = WaveletModel.load(path)
    np.testing.assert_array_equal(loaded.markov, model.markov)
    np.testing.assert_array_equal(loaded.inverse, model.inverse)
    assert loaded.omega == model.omega and loaded.date == model.date
    assert loaded.control_labels == model.control_labels
    loaded.check_compatible("haar", 64, 2 * np.pi * 11.2)
    with pytest.raises(ValueError, match="identify again at this speed"):
        loaded.check_compatible("haar", 64, 2 * np.pi * 18)
    with pytest.raises(ValueError, match="cannot read"):
        WaveletModel.load(tmp_path / "missing.npz")


@pytest.mark.parametrize("position", [1, 8, 16, 31])
def test_a_command_applied_from_a_later_sample_is_recorded_as_its_share(position):
    # Haar at 1 x running speed: the even waveform is +-1/sqrt(N) on every sample, so the
    # command's force with its first `position` samples zeroed projects back on it as
    # c (N - position) / N (closed form: sum of w_n^2 over the samples that ran)
    _, limiter, markov = _one_axis_setup()
    inverse = pseudo_inverse_series(markov, order=5)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    sup = WaveletControlSupervisor(
        limiter, delay=2, controller=TransientController(inverse, alpha, 2)
    )
    sup.set_mode(Mode.ACTIVE)
    disturbance = np.full((20, 1), 50.0)
    _supervised_loop(markov, sup, 10, disturbance)
    target = 10 + 1  # commanded by the step of period 9, not yet applied
    sent = sup.applied(target).copy()
    assert abs(sent[0]) > 1.0
    assert not sup.command_resumed(target, position)  # not reported missing: nothing to do
    assert sup.command_missing(target)
    assert not sup.applied(target).any()
    assert sup.command_resumed(target, position)
    np.testing.assert_allclose(sup.applied(target), sent * (N - position) / N, rtol=1e-12)
    assert not sup.command_resumed(target, position + 1 if position < N - 1 else 1)  # once


@pytest.mark.parametrize(("position", "as_if"), [(8, "applied"), (16, "applied"), (17, "lost")])
def test_a_partly_applied_command_counts_as_applied_or_lost_whichever_is_nearer(position, as_if):
    # eq. 8.10's controller knows a step as made or undone: a command that acted on at least
    # half of its period is taken as applied (the undo is taken back), else as lost
    _, limiter, markov = _one_axis_setup()
    inverse = pseudo_inverse_series(markov, order=5)
    alpha = PrescribedResponse.exponential(0.75, 0.75)
    q = _supervised_loop(
        markov,
        WaveletControlSupervisor(
            limiter, delay=2, controller=TransientController(inverse, alpha, 2)
        ),
        30,
        np.full((40, 1), 50.0),
    )[0]
    lost, states = 14, {}
    for case in ("partial", "applied", "lost"):
        sup = WaveletControlSupervisor(
            limiter, delay=2, controller=TransientController(inverse, alpha, 2)
        )
        sup.set_mode(Mode.ACTIVE)
        for k in range(30):
            if k == lost and case != "applied":
                assert sup.command_missing(k)
                if case == "partial":
                    assert sup.command_resumed(k, position)
            sup.step(k, q[k])
        states[case] = sup.controller.get_state()
    np.testing.assert_allclose(states["partial"].zi, states[as_if].zi, rtol=1e-12, atol=0.0)
    np.testing.assert_allclose(
        states["partial"].history, states[as_if].history, rtol=1e-12, atol=0.0
    )
    other = "lost" if as_if == "applied" else "applied"
    assert not np.allclose(states["partial"].zi, states[other].zi, rtol=1e-6, atol=0.0)
