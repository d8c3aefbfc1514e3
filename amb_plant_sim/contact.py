"""
Rotor/clearance-bearing contact forces (eq. 5.5, section 5.2).

For a journal at position ``r`` (m) relative to the bearing centre, with radial clearance
``c``, the penetration is ``delta = |r| - c``. While ``delta > 0`` the bearing pushes the rotor
back along ``-n`` (``n = r/|r|``) with the normal force

    f_c = k delta^1.5 + d delta'     (Hertzian point contact, ``model: hertz``), or
    f_c = k delta     + d delta'     (``model: penalty``),

clipped at zero (the bearing cannot pull), and Coulomb friction ``mu f_c`` acts along the
tangent ``t = (-n_y, n_x)`` against the slip velocity of the rotor surface on the bearing,
``v_s = r'.t + Omega R - u_r`` (surface speed of the spinning journal plus the whirl velocity,
less the surface speed ``u_r`` of the bearing's race: zero for a bronze retainer, the inner
race's ``omega_r (R + c)`` for a rolling auxiliary bearing, whose race the friction spins up,
:func:`race_step`). With ``sign`` regularised as ``tanh(v_s / v_0)``:

    f = -f_c n - mu f_c tanh(v_s / v_0) t,

which is eq. (5.5), ``f_x + j f_y = (-f_c - j mu f_c) P(t) e^{j theta}``, for ``v_s > 0``
(``theta`` the contact angle, ``P(t)`` the contact indicator).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from amb_common.rig import ContactData


@dataclass(frozen=True)
class ContactResult:
    """
    Contact state at ``k`` bearings.

    Attributes
    ----------
    force : ndarray (k, 2)
        Force on the rotor, N.
    penetration : ndarray (k,)
        ``max(delta, 0)``, m.
    normal_force : ndarray (k,)
        ``f_c``, N.
    friction_force : ndarray (k,)
        Signed tangential force on the rotor along ``t``, ``-mu f_c tanh(v_s / v_0)``, N (its
        reaction drives the bearing's race).
    in_contact : ndarray (k,) bool
    tangent : ndarray (k, 2)
        ``t`` where touching (zero elsewhere).
    surface_speed : ndarray (k,)
        The journal's surface speed along ``t``, ``r'.t + Omega R``, m/s, where touching: the
        race rolls when its own surface speed equals it.
    d_position, d_velocity : ndarray (k, 2, 2)
        Jacobians of ``force`` with respect to the journal position (N/m) and velocity
        (N s/m) at fixed contact direction and slip sign, for the linearly implicit step.
    """

    force: NDArray[np.float64]
    penetration: NDArray[np.float64]
    normal_force: NDArray[np.float64]
    friction_force: NDArray[np.float64]
    in_contact: NDArray[np.bool_]
    tangent: NDArray[np.float64]
    surface_speed: NDArray[np.float64]
    d_position: NDArray[np.float64]
    d_velocity: NDArray[np.float64]


def contact_forces(
    position: NDArray[np.float64],
    velocity: NDArray[np.float64],
    centre: NDArray[np.float64],
    clearance: NDArray[np.float64],
    omega: float,
    params: ContactData,
    race_surface_speed: NDArray[np.float64] | None = None,
) -> ContactResult:
    """
    Contact forces at ``k`` clearance bearings.

    Parameters
    ----------
    position, velocity : ndarray (k, 2)
        Journal ``[x, y]`` (m) and ``[x', y']`` (m/s) at each bearing.
    centre : ndarray (k, 2)
        Bearing centre (misalignment offset), m.
    clearance : ndarray (k,)
        Radial clearance, m.
    omega : float
        Running speed, rad/s (spin sense +z, x towards y).
    params : ContactData
        Stiffness, damping, friction, regularisation, journal radius.
    race_surface_speed : ndarray (k,), optional
        Surface speed of each bearing's race in the spin sense, m/s (``u_r``); zero (a race
        at rest) if omitted.

    Returns
    -------
    ContactResult
    """
    r = np.asarray(position, float) - np.asarray(centre, float)
    d = np.hypot(r[:, 0], r[:, 1])
    delta = d - np.asarray(clearance, float)
    touching = delta > 0.0
    force = np.zeros_like(r)
    fn = np.zeros(d.shape)
    ft = np.zeros(d.shape)
    tan = np.zeros_like(r)
    surf = np.zeros(d.shape)
    kp = np.zeros((r.shape[0], 2, 2))
    kv = np.zeros((r.shape[0], 2, 2))
    if np.any(touching):
        n = r[touching] / d[touching, None]
        t = np.stack([-n[:, 1], n[:, 0]], axis=1)
        v = np.asarray(velocity, float)[touching]
        dl = delta[touching]
        if params.model == "hertz":
            k = params.hertz_stiffness * dl**1.5
            dk = 1.5 * params.hertz_stiffness * np.sqrt(dl)
        else:
            k = params.penalty_stiffness * dl
            dk = np.full(dl.shape, params.penalty_stiffness)
        raw = k + params.damping * np.sum(v * n, axis=1)
        pushing = raw > 0.0
        f_c = np.where(pushing, raw, 0.0)
        v_s = np.sum(v * t, axis=1) + omega * params.rotor_radius
        tan[touching] = t
        surf[touching] = v_s
        if race_surface_speed is not None:
            v_s = v_s - np.asarray(race_surface_speed, float)[touching]
        mu = params.friction * np.tanh(v_s / params.slip_velocity_scale)
        direction = n + mu[:, None] * t  # force = -f_c * direction
        force[touching] = -f_c[:, None] * direction
        fn[touching] = f_c
        ft[touching] = -f_c * mu
        outer = direction[:, :, None] * n[:, None, :]  # direction n^T
        kp[touching] = -(np.where(pushing, dk, 0.0))[:, None, None] * outer
        kv[touching] = -(np.where(pushing, params.damping, 0.0))[:, None, None] * outer
    return ContactResult(force, np.maximum(delta, 0.0), fn, ft, touching, tan, surf, kp, kv)


def race_step(
    race_speed: NDArray[np.float64],
    friction_force: NDArray[np.float64],
    rolling_speed: NDArray[np.float64],
    race_radius: NDArray[np.float64],
    h: float,
    params: ContactData,
) -> NDArray[np.float64]:
    """
    Advance the inner-race speed of rolling auxiliary bearings over one step of ``h`` s.

    The race (polar inertia ``J``, viscous drag ``c`` from its balls and seals, bore radius
    ``R_r``, the journal's radius plus the clearance) is driven by the reaction of the
    friction on the rotor:

        J omega_r' = -f_t R_r - c omega_r,

    integrated implicitly in the drag (``omega_r <- (omega_r - h f_t R_r / J) / (1 + h c / J)``)
    and with the friction acting only until the race rolls: a step that would carry the race
    past the rolling speed (no slip, ``omega_r R_r = r'.t + Omega R``) ends at it. Friction
    with ``v_0`` of a few mm/s makes this equation stiff (time constant ``J v_0 / (mu f_c R_r^2)``
    of microseconds), so an explicit step would chatter about the rolling speed.

    Parameters
    ----------
    race_speed : ndarray (k,)
        ``omega_r`` at the start of the step, rad/s.
    friction_force : ndarray (k,)
        Tangential force on the rotor along ``t`` (:attr:`ContactResult.friction_force`), N.
    rolling_speed : ndarray (k,)
        Race speed at which the contact rolls without slip, rad/s.
    race_radius : ndarray (k,)
        ``R_r``, m.
    h : float
        Step, s.
    params : ContactData
        ``race_inertia`` (kg m^2), ``race_drag`` (N m s).

    Returns
    -------
    ndarray (k,)
        ``omega_r`` at the end of the step, rad/s.
    """
    J = params.race_inertia
    w0 = np.asarray(race_speed, float)
    f_t = np.asarray(friction_force, float)
    w1 = (w0 - h * f_t * np.asarray(race_radius, float) / J) / (1.0 + h * params.race_drag / J)
    roll = np.asarray(rolling_speed, float)
    driven = f_t != 0.0
    passed = driven & (np.sign(roll - w0) != np.sign(roll - w1))
    return np.where(passed, roll, w1)
