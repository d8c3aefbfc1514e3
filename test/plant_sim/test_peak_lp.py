"""
PeakProgram against closed forms on a first-order system ``y+ = a y + b u + d``.

After a step disturbance ``d`` at sample 0 the free response is ``d (1 - a^n) / (1 - a)``. A
force from ``k0`` on, ``|u| <= U``, either holds ``y`` where it is at ``k0`` (when
``b U >= d - (1 - a) y_k0``: the peak is ``y_k0``) or, with ``u = -U`` throughout (the best
it can do), lets it rise towards ``(d - b U) / (1 - a)``: the peak is then the value at the
window's last sample.
"""

import numpy as np
import pytest

from amb_plant_sim.errors import BoundExceededError
from amb_plant_sim.peak_lp import Family, PeakProgram

A, B, D = 0.9, 0.5, 1.0
K0, PERIOD, REVS, TAIL = 6, 4, 3, 2
END = K0 + (REVS + TAIL) * PERIOD


def _free(n=END):
    k = np.arange(n)
    return (D * (1 - A**k) / (1 - A))[:, None]


def _markov(n=END):
    m = np.zeros((n, 1, 1))
    m[1:, 0, 0] = B * A ** np.arange(n - 1)
    return m


def _identity(n=END):
    m = np.zeros((n, 1, 1))
    m[0, 0, 0] = 1.0  # the force itself as an output
    return m


def _objective():
    return Family("objective", _free(), _markov(), None, 0, 1e-9)


def _force_output(bound, cut):
    return Family("force", np.zeros((END, 1)), _identity(), np.array([bound]), K0, 1e-9, cut)


def _rising_peak(U):
    y_k0 = D * (1 - A**K0) / (1 - A)
    y_inf = (D - B * U) / (1 - A)
    return y_inf + (y_k0 - y_inf) * A ** (END - 1 - K0)


def test_enough_force_holds_the_output_where_the_force_first_acts():
    y_k0 = D * (1 - A**K0) / (1 - A)
    prog = PeakProgram([_objective()], K0, REVS, TAIL, PERIOD, added_limit=10.0)
    sol = prog.solve()
    assert sol.peak == pytest.approx(y_k0, rel=1e-7)
    assert np.abs(sol.outputs["objective"][K0:]).max() <= y_k0 * (1 + 1e-7)


@pytest.mark.parametrize("cut", [False, True])
def test_too_little_force_rises_to_the_closed_form(cut):
    U = 0.2  # b U = 0.1 < d - (1 - a) y_k0 = a^k0 = 0.53
    prog = PeakProgram([_objective()], K0, REVS, TAIL, PERIOD, added_limit=U)
    assert prog.solve().peak == pytest.approx(_rising_peak(U), rel=1e-7)
    # the same limit as a bounded output family (all rows at once, or by cutting planes)
    prog = PeakProgram(
        [_objective(), _force_output(U, cut)], K0, REVS, TAIL, PERIOD, added_limit=10.0
    )
    sol = prog.solve()
    assert sol.peak == pytest.approx(_rising_peak(U), rel=1e-7)
    assert np.abs(sol.force).max() <= U * (1 + 1e-7)


def test_least_force_at_the_optimal_peak_is_the_holding_force():
    y_k0 = D * (1 - A**K0) / (1 - A)
    prog = PeakProgram([_objective()], K0, REVS, TAIL, PERIOD, added_limit=10.0)
    sol = prog.solve(cap=y_k0 * (1 + 1e-9), least_force=True)
    # holding y at y_k0 needs u = -(d - (1 - a) y_k0) / b every sample; anything less rises
    hold = -(D - (1 - A) * y_k0) / B
    np.testing.assert_allclose(sol.force[:, 0], hold, rtol=1e-6)


def test_settling_revolutions_by_bisection():
    # with U large the force can put y at 0 at k0 + 1 and hold it there (u = -d / b)
    prog = PeakProgram([_objective()], K0, REVS, TAIL, PERIOD, added_limit=10.0)
    peak = prog.solve().peak
    revs, sol = prog.settle(peak, level=1e-3)
    # from sample k0 + 1 = 7 on: revolutions of 4 samples from 0 -> 2 (samples 8 on); 7 is
    # in revolution 1 and y_6 > level, so revolution 1 cannot be below it from its start
    assert revs == 2
    assert np.abs(sol.outputs["objective"][revs * PERIOD : END]).max() <= 1e-3 + 1e-8
    assert sol.peak <= peak * (1 + 1e-5)


def test_a_bound_already_exceeded_before_the_force_acts_is_an_error():
    bounded = Family("objective2", _free(), _markov(), np.array([0.5]), 0, 1e-9)
    with pytest.raises(BoundExceededError, match="before the first sample"):
        PeakProgram([_objective(), bounded], K0, REVS, TAIL, PERIOD, added_limit=10.0)


def test_infeasible_bound_returns_none():
    # y must stay below 0.9 y_k0 from k0 + 1 on, with a force too weak to pull it down
    y_k0 = D * (1 - A**K0) / (1 - A)
    bounded = Family("cap", _free(), _markov(), np.array([0.9 * y_k0]), K0 + 1, 1e-9, True)
    prog = PeakProgram([_objective(), bounded], K0, REVS, TAIL, PERIOD, added_limit=0.01)
    assert prog.solve() is None
