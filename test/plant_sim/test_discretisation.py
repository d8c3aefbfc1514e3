"""
Exact discretisation (matrix exponential) against scipy.integrate.solve_ivp, and the lifted
sample map against the internal-step recursion.
"""

import math

import numpy as np
import pytest
import scipy.integrate

from amb_plant_sim.closed_loop import build_plant
from amb_plant_sim.discretize import discretise, step_matrices
from amb_plant_sim.pid import discretize_zoh, pid_state_space
from amb_plant_sim.rotor import build_rotor


@pytest.fixture(scope="module")
def plant(rig):
    # the minimum mesh keeps the stiffest mode low enough for an explicit reference solver
    return build_plant(rig, 2 * math.pi * 30.0, rotor=build_rotor(rig, 9))


def _reference(plant, x0, i, f, a, W, h):
    n_f = plant.B_f.shape[1]

    def rhs(t, x):
        sync = (W * np.exp(1j * plant.omega * t)).real
        return plant.A @ x + plant.B_i @ i + plant.B_f @ (f + sync) + plant.B_a @ a

    sol = scipy.integrate.solve_ivp(
        rhs, (0.0, h), x0, method="DOP853", rtol=1e-13, atol=1e-22, max_step=h / 50
    )
    assert sol.success and n_f == W.size
    return sol.y[:, -1]


def test_step_matrices_equal_solve_ivp(plant):
    rng = np.random.default_rng(1)
    nx = plant.n_states
    n_f = plant.B_f.shape[1]
    h = 1.0 / 6000.0
    x0 = np.zeros(nx)
    x0[: nx // 2] = 1e-4 * rng.standard_normal(nx // 2)  # displacements ~0.1 mm
    x0[nx // 2 :] = 1e-2 * rng.standard_normal(nx // 2)  # velocities ~1 cm/s
    i = rng.standard_normal(4)  # A
    f = 50.0 * rng.standard_normal(n_f)  # N
    a = np.array([0.3, -0.2])  # m/s^2
    W = 100.0 * (rng.standard_normal(n_f) + 1j * rng.standard_normal(n_f))
    st = step_matrices(plant, h)
    x1 = st.Phi @ x0 + st.Gi @ i + st.Gf @ f + st.Ga @ a + (st.Psi @ W).real
    ref = _reference(plant, x0, i, f, a, W, h)
    err = np.linalg.norm(x1 - ref) / np.linalg.norm(ref)
    assert 0.0 <= err < 1e-9, err


def test_pid_zoh_equals_solve_ivp(rig):
    pid = pid_state_space(rig.pid, rig.amb.Ki)
    h = 1.0 / 5000.0
    d = discretize_zoh(pid, h)
    xk0 = np.array([1e-5, 2e-4, -3e-5, 1e-4, 0.0, -1e-4, 2e-5, 5e-5])
    y = np.array([1e-4, -2e-4, 3e-5, 0.0])
    sol = scipy.integrate.solve_ivp(
        lambda t, x: pid.A @ x + pid.B @ y, (0, h), xk0, method="DOP853", rtol=1e-13, atol=1e-20
    )
    np.testing.assert_allclose(d.A @ xk0 + d.B @ y, sol.y[:, -1], rtol=1e-10, atol=1e-18)


def test_lifted_sample_map_equals_step_recursion(rig, plant):
    pid = pid_state_space(rig.pid, rig.amb.Ki)
    rows = plant.position_rows([0, 3])
    d = discretise(plant, pid, 32, 5000.0, rows, 4)
    rng = np.random.default_rng(2)
    ns = d.F.shape[0]
    s0 = 1e-5 * rng.standard_normal(ns)
    u = rng.standard_normal(d.layout.size)
    lay = d.layout
    nx = plant.n_states
    x, xk = s0[:nx].copy(), s0[nx:].copy()
    W = u[lay.w_re] + 1j * u[lay.w_im]
    st, pd = d.step, d.pid
    currents = []
    for j in range(d.n_sub):
        y = plant.C_in @ x + u[lay.o] + u[lay.noise][4 * j : 4 * j + 4]
        i = pd.C @ xk + pd.D @ y + u[lay.i_w]
        currents.append(i)
        sync = (st.Psi @ (W * np.exp(1j * plant.omega * j * st.h))).real
        x = st.Phi @ x + st.Gi @ i + st.Gf @ u[lay.f_e] + st.Ga @ u[lay.a_b] + sync
        xk = pd.A @ xk + pd.B @ y
    s1 = d.F @ s0 + d.G @ u
    np.testing.assert_allclose(s1, np.r_[x, xk], rtol=1e-10, atol=1e-12 * np.abs(s1).max())
    mon = d.Ms @ s0 + d.Mu @ u
    np.testing.assert_allclose(mon[d.cur_idx], np.array(currents), rtol=1e-9, atol=1e-12)
    assert d.n_sub * 32 * 30.0 >= 5000.0
