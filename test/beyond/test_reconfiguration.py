"""
HOLD on auxiliary-bearing contact (thesis section 3.3.2): hold-last or ramp-to-zero
(:class:`amb_controller.supervisor.WaveletControlSupervisor`, ``hold_ramp_periods``).

References: the linear ramp ``max(0, 1 - j/n)`` of the command at HOLD entry, written out
by hand for each HOLD period j; the force of a scaled command is the scaled force (the
synthesis is linear, eq. 6.7), checked on the synthesised samples; a static plant for the
resume-after-hold case.
"""

import numpy as np
import pytest

from amb_controller.basis import control_basis
from amb_controller.errors import ControllerValueError
from amb_controller.guard import DivergenceGuard, GuardConfig
from amb_controller.response import PrescribedResponse
from amb_controller.supervisor import AUX_BEARING_CONTACT, Mode, WaveletControlSupervisor
from amb_controller.synthesis import ForceLimiter
from amb_controller.transient import TransientController

N = 16
GAIN = 1e-6  # m sqrt(samples) per N sqrt(samples), static plant of one axis


def _supervisor(ramp: int) -> WaveletControlSupervisor:
    basis = control_basis("haar", N, [1], n_axes=1, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=1000.0, capacity=1000.0)
    ctl = TransientController(
        np.full((1, 1, 1), 1.0 / GAIN), PrescribedResponse.exponential(0.75, 0.75), 1
    )
    sup = WaveletControlSupervisor(limiter, 1, controller=ctl, hold_ramp_periods=ramp)
    assert sup.set_mode(Mode.ACTIVE)[0]
    return sup


def _run(sup, periods, disturbance, fault_at=None, resume_at=None):
    """Static plant q = G u + d, command k applied at k + 1; returns the commands."""
    applied = {}
    commands = []
    for k in range(periods):
        if k == fault_at:
            assert sup.on_fault(AUX_BEARING_CONTACT) == "hold"
        if k == resume_at:
            assert sup.set_mode(Mode.ACTIVE)[0]
        u = applied.get(k, np.zeros(1))
        cmd = sup.step(k, GAIN * u + disturbance)
        applied[cmd.target_period] = cmd.coefficients
        commands.append(cmd)
    return commands


def test_hold_last_repeats_the_last_command_for_ever():
    sup = _supervisor(ramp=0)
    cmds = _run(sup, 40, np.array([2e-5]), fault_at=20)
    last = cmds[19].coefficients
    assert abs(last[0]) > 1.0  # the controller was cancelling the disturbance
    for c in cmds[20:]:
        assert c.mode == Mode.HOLD and c.hold
        np.testing.assert_array_equal(c.coefficients, last)


@pytest.mark.parametrize("ramp", [1, 4, 7])
def test_ramp_to_zero_scales_the_held_command_linearly_to_zero(ramp):
    sup = _supervisor(ramp)
    cmds = _run(sup, 40, np.array([2e-5]), fault_at=20)
    held = cmds[19]
    for j, c in enumerate(cmds[20:], start=1):
        factor = max(0.0, 1.0 - j / ramp)
        assert c.mode == Mode.HOLD and c.hold
        np.testing.assert_allclose(c.coefficients, factor * held.coefficients, rtol=1e-12)
        np.testing.assert_allclose(c.force, factor * held.force, rtol=1e-12, atol=1e-12)
    assert np.all(cmds[20 + ramp - 1].force == 0.0) and np.all(cmds[-1].force == 0.0)


def test_resume_after_a_ramped_hold_restarts_the_controller_from_zero():
    d = np.array([2e-5])
    ramped = _run(_supervisor(4), 60, d, fault_at=20, resume_at=30)
    fresh = _run(_supervisor(4), 30, d)  # a controller started from zero at period 0
    # the integral state is not carried over the ramp: the resumed commands are those of a
    # fresh start on the same (zero-force) plant, not a jump back to the pre-hold force
    for k in range(30):
        np.testing.assert_allclose(
            ramped[30 + k].coefficients, fresh[k].coefficients, rtol=1e-9, atol=1e-12
        )
    # hold-last keeps the state: resuming continues from the held force (no restart)
    held = _run(_supervisor(0), 40, d, fault_at=20, resume_at=30)
    assert abs(held[30].coefficients[0] - held[19].coefficients[0]) < 0.01 * abs(
        held[19].coefficients[0]
    )


def test_guard_trip_still_zeroes_the_force_at_once():
    sup = _supervisor(ramp=10)
    sup.guard = DivergenceGuard(GuardConfig(coefficient_bound=5e-5))
    cmds = _run(sup, 10, np.array([2e-5]))
    assert abs(cmds[-1].coefficients[0]) > 1.0 and not sup.guard.tripped
    cmd = sup.step(10, np.array([1e-4]))  # beyond the bound: trip, HOLD with zero force
    assert cmd.guard_tripped and cmd.mode == Mode.HOLD and np.all(cmd.force == 0.0)
    assert np.all(sup.step(11, np.array([1e-4])).force == 0.0)


def test_negative_or_fractional_ramp_is_refused():
    basis = control_basis("haar", N, [1], n_axes=1, quadratures=["even"])
    limiter = ForceLimiter(basis, limit=1000.0, capacity=1000.0)
    for bad in (-1, 2.5):
        with pytest.raises(ControllerValueError, match="hold_ramp_periods"):
            WaveletControlSupervisor(limiter, 1, hold_ramp_periods=bad)
