"""
Stability of the wavelet transient controller (thesis section 8.4, eq. 8.11-8.16).

Sign convention
---------------
The thesis writes the loop as ``I - G B_u L`` in eq. 8.2/8.8 but as ``I + G B_u L`` in
eq. 8.12; only the latter reproduces the prescribed response of eq. 8.3 and the
``gamma`` of eq. 8.15, so we use: measured coefficients ``Q = G (F + B_u U)``,
``U = -L Q``, closed loop ``(I + G B_u L) Q = G F``.

With a perfect pseudo-inverse (``G B_u (G B_u)^* = I``) and the delayed controller of
eq. 8.10, ``I + G B_u L = (1 + alpha (z-1)(z^i - 1)) / (alpha (z-1) z^i)``, so the
nominal closed-loop poles are the zeros of ``1 + alpha(z)(z - 1)(z^i - 1)``, the
denominator of ``gamma`` (eq. 8.15). For ``alpha = w/(z - v)`` they are the roots of
``(z - v) + w (z - 1)(z^i - 1)``. The model-error transfer function is
``H = -B_u (G B_u)^* gamma`` (eq. 8.14); by the small-gain theorem the loop stays stable
for every stable additive plant error ``Delta`` with
``||Delta||_inf < 1 / ||(G B_u)^* gamma||_inf``. The printed criterion (8.16),
``(G B_u)^* gamma <= 1``, is this bound for ``||Delta||_inf = 1`` in the units of the
coefficients; we return the norm itself so the caller can compare it with a measured
model error.
"""

from __future__ import annotations

import numpy as np

from amb_controller.errors import ControllerValueError
from amb_controller.lti import DiscreteStateSpace, feedback, fir_state_space
from amb_controller.response import PrescribedResponse


def _check_delay(delay: int) -> int:
    if int(delay) != delay or delay < 0:
        raise ControllerValueError(f"delay must be an integer number of periods >= 0, got {delay}")
    return int(delay)


def characteristic_polynomial(alpha: PrescribedResponse, delay: int) -> np.ndarray:
    """
    Return the nominal closed-loop characteristic polynomial (denominator of eq. 8.15).

    ``z^-i den(z^-1) (1 + alpha(z)(z - 1)(z^i - 1))`` written in ascending powers of
    ``z^-1``: ``p = z^-i den + a (1 - z^-1)(1 - z^-i)`` with ``a = alpha.num[1:]``.

    Parameters
    ----------
    alpha : PrescribedResponse
        Prescribed response.
    delay : int
        Evaluation delay ``i`` in control periods.

    Returns
    -------
    numpy.ndarray
        Ascending coefficients in ``z^-1``; as descending coefficients in ``z`` they give
        the closed-loop poles with :func:`numpy.roots`.

    """
    i = _check_delay(delay)
    a = alpha.num[1:]
    delayed_den = np.concatenate((np.zeros(i), alpha.den))
    one_minus_zi = np.zeros(i + 1)
    one_minus_zi[0] += 1.0
    one_minus_zi[i] -= 1.0
    term = np.convolve(np.convolve(a, [1.0, -1.0]), one_minus_zi)
    n = max(delayed_den.size, term.size)
    return np.pad(delayed_den, (0, n - delayed_den.size)) + np.pad(term, (0, n - term.size))


def nominal_poles(alpha: PrescribedResponse, delay: int) -> np.ndarray:
    """
    Return the nominal closed-loop poles (zeros of ``1 + alpha (z-1)(z^i-1)``).

    Parameters
    ----------
    alpha : PrescribedResponse
        Prescribed response.
    delay : int
        Evaluation delay ``i`` in control periods.

    Returns
    -------
    numpy.ndarray of complex

    """
    p = np.trim_zeros(characteristic_polynomial(alpha, delay), "fb")
    return np.roots(p).astype(complex) if p.size > 1 else np.zeros(0, dtype=complex)


def is_nominally_stable(alpha: PrescribedResponse, delay: int, margin: float = 0.0) -> bool:
    """
    Return True if the nominal loop and the controller itself are stable.

    Checks that the nominal closed-loop poles, the poles of ``alpha`` (thesis section
    8.4: "any singularities in the prescribed transient response must lie within the
    unit circle") and the poles of the controller factor ``beta`` other than its
    integrator (the zeros of ``alpha``) all lie inside ``|z| < 1 - margin``.

    Parameters
    ----------
    alpha : PrescribedResponse
        Prescribed response.
    delay : int
        Evaluation delay ``i`` in control periods.
    margin : float
        Required distance from the unit circle.

    Returns
    -------
    bool

    """
    radius = 1.0 - margin
    groups = (nominal_poles(alpha, delay), alpha.poles(), alpha.controller_poles())
    return all(np.all(np.abs(g) < radius) for g in groups)


def gamma(alpha: PrescribedResponse, delay: int, z) -> np.ndarray:
    """
    Evaluate ``gamma(alpha(z)) = (1 - alpha (z-1)) / (1 + alpha (z-1)(z^i - 1))`` (eq. 8.15).

    Parameters
    ----------
    alpha : PrescribedResponse
        Prescribed response.
    delay : int
        Evaluation delay ``i``.
    z : array_like of complex
        Points of the z-plane.

    Returns
    -------
    numpy.ndarray of complex

    """
    i = _check_delay(delay)
    z = np.asarray(z, dtype=complex)
    az = alpha.evaluate(z) * (z - 1.0)
    return (1.0 - az) / (1.0 + az * (z**i - 1.0))


def robustness_norm(
    inverse_markov: np.ndarray,
    alphas: PrescribedResponse | list[PrescribedResponse],
    delay: int,
    n_points: int = 512,
) -> float:
    """
    Return ``||(G B_u)^* gamma||_inf`` on the unit circle (eq. 8.14-8.16).

    Parameters
    ----------
    inverse_markov : numpy.ndarray
        ``B^(0) .. B^(K)`` of eq. 6.35, shape ``(K+1, n_u, n_y)``.
    alphas : PrescribedResponse or list of PrescribedResponse
        One response for all measured channels or one per channel (diagonal alpha).
    delay : int
        Evaluation delay ``i``.
    n_points : int
        Frequency points on the upper half of the unit circle.

    Returns
    -------
    float
        The H-infinity norm (units: control coefficient per measured coefficient). The
        loop is robustly stable for additive plant errors with
        ``||Delta||_inf < 1 / norm``; eq. 8.16 asks ``norm <= 1``. Infinite when the
        nominal loop is unstable.

    """
    inverse_markov = np.asarray(inverse_markov)
    n_y = inverse_markov.shape[2]
    alpha_list = _alpha_list(alphas, n_y)
    if not all(is_nominally_stable(a, delay) for a in alpha_list):
        return float(np.inf)
    theta = np.linspace(0.0, np.pi, n_points)
    z = np.exp(1j * theta)
    zinv_powers = z[:, None] ** -np.arange(inverse_markov.shape[0])[None, :]
    b_of_z = np.einsum("fk,kij->fij", zinv_powers, inverse_markov)
    g = np.stack([gamma(a, delay, z) for a in alpha_list], axis=1)  # (f, n_y)
    h = b_of_z * g[:, None, :]
    return float(np.max(np.linalg.svd(h, compute_uv=False)[:, 0]))


def _alpha_list(alphas, n_channels: int) -> list[PrescribedResponse]:
    if isinstance(alphas, PrescribedResponse):
        return [alphas] * n_channels
    alphas = list(alphas)
    if len(alphas) != n_channels:
        raise ControllerValueError(
            f"expected one prescribed response or {n_channels} (one per measured channel), "
            f"got {len(alphas)}"
        )
    return alphas


def exponential_stability_map(w: np.ndarray, v: np.ndarray, delay: int) -> np.ndarray:
    """
    Map the nominal stability of ``alpha = w/(z - v)`` over a (w, v) grid (figure 8.3).

    Vectorised: the characteristic polynomials ``(z - v) + w (z - 1)(z^i - 1)`` of the
    whole grid are solved at once as eigenvalues of stacked companion matrices.

    Parameters
    ----------
    w : numpy.ndarray
        Gains, 1-D, all > 0.
    v : numpy.ndarray
        Decay ratios, 1-D, in [0, 1).
    delay : int
        Evaluation delay ``i`` in periods.

    Returns
    -------
    numpy.ndarray of bool
        Shape ``(len(v), len(w))``: True where all closed-loop poles satisfy ``|z| < 1``.

    """
    i = _check_delay(delay)
    w = np.asarray(w, dtype=float)
    v = np.asarray(v, dtype=float)
    if np.any(w <= 0) or np.any((v < 0) | (v >= 1)):
        raise ControllerValueError("stability map needs w > 0 and 0 <= v < 1 (eq. 8.6)")
    ww, vv = np.meshgrid(w, v)
    if i == 0:
        return np.ones_like(ww, dtype=bool)
    # Descending coefficients in z of w z^(i+1) - w z^i - w z + w + z - v (degree i + 1).
    deg = i + 1
    coeffs = np.zeros((*ww.shape, deg + 1))
    coeffs[..., 0] += ww  # z^(i+1)
    coeffs[..., 1] -= ww  # z^i
    coeffs[..., deg - 1] += 1.0 - ww  # z^1
    coeffs[..., deg] += ww - vv  # z^0
    monic = coeffs[..., 1:] / coeffs[..., :1]
    companion = np.zeros((*ww.shape, deg, deg))
    companion[..., 0, :] = -monic
    if deg > 1:
        idx = np.arange(deg - 1)
        companion[..., idx + 1, idx] = 1.0
    radius = np.max(np.abs(np.linalg.eigvals(companion)), axis=-1)
    return (radius < 1.0) & (vv < 1.0)


def closed_loop(plant: DiscreteStateSpace, controller: DiscreteStateSpace) -> DiscreteStateSpace:
    """
    Return the wavelet-domain closed loop of a plant model and a controller realisation.

    The exact check of stability: the poles of this system are the closed-loop poles of
    the identified (or modelled) loop, including truncation of the inverse and
    non-square plants, which the nominal analysis of eq. 8.9 assumes away.

    Parameters
    ----------
    plant : DiscreteStateSpace
        Control coefficients -> measured coefficients (``G B_u``).
    controller : DiscreteStateSpace
        Measured coefficients -> control coefficients, sign included (``-L``).

    Returns
    -------
    DiscreteStateSpace
        From disturbance coefficients (added to the control input) to measured ones.

    """
    return feedback(plant, controller)


def spectral_radius(system: DiscreteStateSpace) -> float:
    """Return the largest pole modulus of ``system`` (0 for a static system)."""
    poles = system.poles()
    return float(np.max(np.abs(poles))) if poles.size else 0.0


#: Default largest closed-loop spectral radius on the controller's own model with which it may go
#: ACTIVE (``ControllerConfig.max_model_radius``; :func:`own_model_radius`).
MAX_MODEL_RADIUS = 0.98


def own_model_radius(markov: np.ndarray, controller) -> float | None:
    """
    Return the exact closed-loop spectral radius of ``controller`` on the model ``markov``.

    The controller's realisation (``-L``, from measured to applied coefficients, delay
    included) closed around the FIR realisation of the model's Markov parameters ``G B_u``
    (:func:`closed_loop`). This is the loop eq. 8.12 describes with the model in place of the
    plant, including the truncation of the inverse (eq. 6.35) that the nominal poles of eq.
    8.15 assume away: a radius >= 1 means the controller diverges on the very model it was
    designed from, and a radius near 1 means an error the model cannot show (gain, phase,
    speed) is enough to make it diverge on the plant.

    The default limit, 0.98, is a loop mode that decays by 2 % per period: 114 periods
    (revolutions) to fall to 10 %, against 4 revolutions for the PID loop alone to settle at the
    first critical speed and 6 for the prescribed response ``w = v = 0.75`` (radius 2/3,
    eq. 8.15). Such a controller adds nothing a user wants, and the few per cent of model error
    an identification leaves (or a change of speed) move that pole across the unit circle.

    Parameters
    ----------
    markov : numpy.ndarray
        ``G^(0) .. G^(K)``, shape ``(K + 1, n_measured, n_control)`` (eq. 6.29).
    controller : object
        With ``state_space()`` (the transient controller, eq. 8.10, the proportional and
        moderated ones, eq. 7.7 and 7.9, the multi-level one).

    Returns
    -------
    float or None
        Largest closed-loop pole modulus; ``None`` for a controller without a realisation
        (the influence-coefficient baseline, open loop per window, eq. B.1).

    """
    realise = getattr(controller, "state_space", None)
    if realise is None:
        return None
    return spectral_radius(closed_loop(fir_state_space(markov), realise()))
