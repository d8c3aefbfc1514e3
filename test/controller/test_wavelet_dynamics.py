"""
Wavelet-domain dynamics (chapter 6): numerical route, Haar closed form, and references.

Independent references: scipy.integrate.solve_ivp + quad of the continuous response on
the Haar pieces; scipy.signal.lsim (zero-order hold) sampled and projected with
PyWavelets (``wavedec`` zero mode = the causal filterbank; ``waverec`` periodization for
the control waveforms).
"""

import numpy as np
import pytest
import pywt
from scipy import integrate, signal

from amb_controller.basis import BasisSet, control_basis, measurement_basis
from amb_controller.wavelet_dynamics import (
    Pieces,
    haar_transfer_function,
    modal_residues,
    piecewise_transfer_function,
    wavelet_markov,
)

OMEGA = 2 * np.pi * 11.0  # 11 Hz running speed (first critical speed of the thesis rig)
T = 2 * np.pi / OMEGA


def _two_mode_plant():
    """Two lightly damped modes (11 Hz, 18 Hz), 2 force axes, 2 sensors: real 4-state model."""
    wn = 2 * np.pi * np.array([11.0, 18.0])
    zeta = np.array([0.05, 0.08])
    a = np.zeros((4, 4))
    for i in range(2):
        a[2 * i, 2 * i + 1] = 1.0
        a[2 * i + 1, 2 * i] = -(wn[i] ** 2)
        a[2 * i + 1, 2 * i + 1] = -2 * zeta[i] * wn[i]
    b = np.array([[0, 0], [1.0, 0.5], [0, 0], [-0.7, 1.0]]) * 1e-2  # 1/kg
    c = np.array([[1.0, 0, 1.0, 0], [0.8, 0, -0.6, 0]])
    return a, b, c


@pytest.mark.parametrize(
    ("p", "q", "a_", "b_"), [(1, 1, 1, 1), (2, 2, 1, 1), (1, 1, 3, 2), (3, 4, 2, 1)]
)
def test_haar_closed_form_equals_numerical_continuous_route(p, q, a_, b_):
    a, b, c = _two_mode_plant()
    n = 64
    control = control_basis("haar", n, [a_], n_axes=2, quadratures=["even"])
    measured = measurement_basis("haar", n, [p], n_channels=2, quadratures=["even"])
    markov = wavelet_markov(a, b, c, T, control, measured, 10, projection="continuous")
    # pick the rows/cols of translation q (measured) and b (control)
    rows = [i for i, lab in enumerate(measured.labels) if lab.startswith(f"p{p}/q{q}/")]
    cols = [i for i, lab in enumerate(control.labels) if lab.startswith(f"p{a_}/q{b_}/")]
    poles, residues = modal_residues(a, b, c)
    closed = haar_transfer_function(poles, residues, n, T, p, q, a_, b_).markov(10)
    scale = np.max(np.abs(closed))
    np.testing.assert_allclose(markov[:, rows][:, :, cols], closed, atol=1e-9 * scale)


def test_haar_closed_form_matches_quadrature_of_ode_solution():
    # Single mode, Haar level-1 force over period 0; the response is integrated by
    # solve_ivp piece by piece and projected on the level-2 (q = 2) Haar by quad.
    wn, zeta = 2 * np.pi * 11.0, 0.05
    a = np.array([[0.0, 1.0], [-(wn**2), -2 * zeta * wn]])
    b = np.array([[0.0], [1.0]])
    c = np.array([[1.0, 0.0]])
    n = 32
    s_in = np.sqrt(1 / n)
    pieces = [(0.0, T / 2, s_in), (T / 2, T, -s_in), (T, 5 * T, 0.0)]
    sols = []
    x0 = np.zeros(2)
    for t_a, t_b, f in pieces:
        sol = integrate.solve_ivp(
            lambda t, x, f=f: a @ x + b[:, 0] * f,
            (t_a, t_b),
            x0,
            rtol=1e-12,
            atol=1e-16,
            dense_output=True,
        )
        sols.append((t_a, t_b, sol.sol))
        x0 = sol.y[:, -1]

    def y(t):
        for t_a, t_b, s in sols:
            if t_a <= t <= t_b:
                return (c @ s(t))[0]
        raise AssertionError

    h = T / n
    s_out = np.sqrt(2 / n)  # level p = 2
    expected = []
    for m in range(4):
        t0 = m * T + T / 2  # q = 2: second half of the period
        plus = integrate.quad(y, t0, t0 + T / 4, epsabs=1e-16, epsrel=1e-11, limit=200)[0]
        minus = integrate.quad(y, t0 + T / 4, t0 + T / 2, epsabs=1e-16, epsrel=1e-11, limit=200)[0]
        expected.append(s_out * (plus - minus) / h)
    poles, residues = modal_residues(a, b, c)
    closed = haar_transfer_function(poles, residues, n, T, 2, 2, 1, 1).markov(4)[:, 0, 0]
    np.testing.assert_allclose(closed, expected, rtol=1e-7, atol=1e-9 * np.max(np.abs(expected)))


def test_g0_closed_form_equals_numerical_route():
    a, b, c = _two_mode_plant()
    n = 32
    constant = BasisSet(np.ones((2, 2, n)) * np.eye(2)[:, :, None], 0, ("f0/c0", "f0/c1"))
    measured = measurement_basis("haar", n, [1], n_channels=2, quadratures=["even"])
    markov = wavelet_markov(a, b, c, T, constant, measured, 6, projection="continuous")
    poles, residues = modal_residues(a, b, c)
    closed = haar_transfer_function(poles, residues, n, T, 1, 1, None, None).markov(6)
    np.testing.assert_allclose(markov, closed, atol=1e-9 * np.max(np.abs(closed)))


def _lsim_coefficients(a, b, c, n, wavelet, p, quadrature_delay, n_periods, force_axis, waveform):
    """Reference: lsim with ZOH, then pywt.wavedec(mode='zero') of the sampled output."""
    h = T / n
    t = np.arange(n * n_periods) * h
    u = np.zeros((t.size, b.shape[1]))
    u[:n, force_axis] = waveform
    _, y, _ = signal.lsim((a, b, c, np.zeros((c.shape[0], b.shape[1]))), u, t, interp=False)
    r = int(np.log2(n))
    j = r - p + 1
    out = []
    for delay in quadrature_delay:
        yd = np.vstack([np.zeros((delay, y.shape[1])), y[: y.shape[0] - delay]])
        coeffs = pywt.wavedec(yd, wavelet, mode="zero", level=j, axis=0)[1]  # detail level j
        out.append(coeffs)
    return out


@pytest.mark.filterwarnings("ignore:Level value")
@pytest.mark.parametrize("wavelet", ["haar", "db2", "db4"])
def test_sampled_route_matches_lsim_and_pywt(wavelet):
    a, b, c = _two_mode_plant()
    n, p, n_periods = 32, 1, 6
    control = control_basis(wavelet, n, [p], n_axes=2)
    measured = measurement_basis(wavelet, n, [p], n_channels=2)
    markov = wavelet_markov(a, b, c, T, control, measured, n_periods, projection="sampled")
    d = n // 4
    # control waveform of (p=1, q=1, odd, axis 1): pywt periodization, advanced by d
    coeffs = pywt.wavedec(np.zeros(n), wavelet, mode="periodization", level=5)
    coeffs = [np.zeros_like(x) for x in coeffs]
    coeffs[1][0] = 1.0
    waveform = np.roll(pywt.waverec(coeffs, wavelet, mode="periodization"), -d)
    col = control.labels.index("p1/q1/odd/c1")
    even, odd = _lsim_coefficients(a, b, c, n, wavelet, p, [0, d], n_periods, 1, waveform)
    # one level-R coefficient per period: translation index m = period index
    for quad, ref in (("even", even), ("odd", odd)):
        for channel in range(2):
            row = measured.labels.index(f"p1/q1/{quad}/c{channel}")
            expected = ref[:n_periods, channel]
            scale = np.max(np.abs(expected))
            np.testing.assert_allclose(markov[:, row, col], expected, atol=1e-8 * scale)


def test_sampled_projection_converges_to_continuous():
    a, b, c = _two_mode_plant()
    errors = []
    for n in (32, 128, 512):
        control = control_basis("haar", n, [1], n_axes=2, quadratures=["even"])
        measured = measurement_basis("haar", n, [1], n_channels=2, quadratures=["even"])
        s = wavelet_markov(a, b, c, T, control, measured, 4, projection="sampled")
        k = wavelet_markov(a, b, c, T, control, measured, 4, projection="continuous")
        errors.append(np.max(np.abs(s - k)) / np.max(np.abs(k)))
    assert errors[0] > 3.5 * errors[1] > 3.5**2 * errors[2]


def test_transfer_function_evaluate_equals_markov_sum():
    a, b, c = _two_mode_plant()
    poles, residues = modal_residues(a, b, c)
    tf = haar_transfer_function(poles, residues, 64, T, 1, 1, 1, 1)
    z = np.array([3.0 + 1.0j, -2.5])
    markov = tf.markov(200)
    direct = np.einsum("k,kpm->pm", z[0] ** -np.arange(200.0), markov)
    np.testing.assert_allclose(tf.evaluate(z)[0], direct, rtol=1e-10)
    # z-poles are e^{lambda T}: inside the unit circle for a stable plant
    assert np.all(np.abs(tf.z_poles) < 1)


def test_piecewise_from_samples_equals_haar_pieces():
    a, b, c = _two_mode_plant()
    poles, residues = modal_residues(a, b, c)
    n = 16
    h = T / n
    w = control_basis("haar", n, [2], n_axes=1, quadratures=["even"]).weights[1, 0]
    force = Pieces.from_samples(w, h)
    out = Pieces.from_samples(measurement_basis("haar", n, [1], 1, ["even"]).weights[0, 0], h)
    generic = piecewise_transfer_function(poles, residues, T, h, force, out).markov(5)
    haar = haar_transfer_function(poles, residues, n, T, 1, 1, 2, 2).markov(5)
    np.testing.assert_allclose(generic, haar, atol=1e-10 * np.max(np.abs(haar)))
