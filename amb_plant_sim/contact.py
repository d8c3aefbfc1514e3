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

import math
from dataclasses import dataclass
from typing import NamedTuple

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


class BearingContact(NamedTuple):
    """
    Contact at one bearing (:func:`contact_at`), plain floats for the step-by-step hot path.

    ``force`` ``(f_x, f_y)`` N; ``normal_force`` ``f_c`` N; ``friction_force`` along ``t`` N;
    ``tangent`` ``t``; ``surface_speed`` ``r'.t + Omega R`` m/s; ``d_position`` (N/m) and
    ``d_velocity`` (N s/m) the 2 x 2 Jacobians as ``((a, b), (c, d))``
    (:class:`ContactResult`).
    """

    force: tuple[float, float]
    normal_force: float
    friction_force: float
    tangent: tuple[float, float]
    surface_speed: float
    d_position: tuple[tuple[float, float], tuple[float, float]]
    d_velocity: tuple[tuple[float, float], tuple[float, float]]


def contact_at(
    rx: float,
    ry: float,
    vx: float,
    vy: float,
    clearance: float,
    omega: float,
    params: ContactData,
    race_surface_speed: float = 0.0,
) -> BearingContact | None:
    """
    Contact force at one bearing, or ``None`` when the journal does not touch (eq. 5.5).

    Parameters
    ----------
    rx, ry : float
        Journal position relative to the bearing centre, m.
    vx, vy : float
        Journal velocity, m/s.
    clearance : float
        Radial clearance, m.
    omega : float
        Running speed, rad/s.
    params : ContactData
    race_surface_speed : float
        ``u_r``, m/s.

    Returns
    -------
    BearingContact or None
        The force law of the module docstring; Jacobians at fixed contact direction and slip.
    """
    d = math.hypot(rx, ry)
    delta = d - clearance
    if not delta > 0.0:
        return None
    nx, ny = rx / d, ry / d
    tx, ty = -ny, nx
    if params.model == "hertz":
        root = math.sqrt(delta)
        k = params.hertz_stiffness * delta * root
        dk = 1.5 * params.hertz_stiffness * root
    else:
        k = params.penalty_stiffness * delta
        dk = params.penalty_stiffness
    raw = k + params.damping * (vx * nx + vy * ny)
    pushing = raw > 0.0
    f_c = raw if pushing else 0.0
    surf = vx * tx + vy * ty + omega * params.rotor_radius
    mu = params.friction * math.tanh((surf - race_surface_speed) / params.slip_velocity_scale)
    ex, ey = nx + mu * tx, ny + mu * ty  # force = -f_c (ex, ey)
    gp = -dk if pushing else 0.0
    gv = -params.damping if pushing else 0.0
    return BearingContact(
        (-f_c * ex, -f_c * ey),
        f_c,
        -f_c * mu,
        (tx, ty),
        surf,
        ((gp * ex * nx, gp * ex * ny), (gp * ey * nx, gp * ey * ny)),
        ((gv * ex * nx, gv * ex * ny), (gv * ey * nx, gv * ey * ny)),
    )


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
    Contact forces at ``k`` clearance bearings (:func:`contact_at` at each).

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
    v = np.asarray(velocity, float)
    c = np.broadcast_to(np.asarray(clearance, float), r.shape[:1])
    u = np.zeros(r.shape[0]) if race_surface_speed is None else np.asarray(race_surface_speed)
    k = r.shape[0]
    force = np.zeros((k, 2))
    fn = np.zeros(k)
    ft = np.zeros(k)
    tan = np.zeros((k, 2))
    surf = np.zeros(k)
    kp = np.zeros((k, 2, 2))
    kv = np.zeros((k, 2, 2))
    for b in range(k):
        hit = contact_at(r[b, 0], r[b, 1], v[b, 0], v[b, 1], c[b], omega, params, u[b])
        if hit is None:
            continue
        force[b], fn[b], ft[b], tan[b], surf[b] = hit[:5]
        kp[b], kv[b] = hit.d_position, hit.d_velocity
    delta = np.hypot(r[:, 0], r[:, 1]) - c
    return ContactResult(force, np.maximum(delta, 0.0), fn, ft, delta > 0.0, tan, surf, kp, kv)


def race_speed_after(
    race_speed: float,
    friction_force: float,
    rolling_speed: float,
    race_radius: float,
    h: float,
    params: ContactData,
) -> float:
    """:func:`race_step` at one bearing, plain floats (the step-by-step hot path)."""
    J = params.race_inertia
    w1 = (race_speed - h * friction_force * race_radius / J) / (1.0 + h * params.race_drag / J)
    before, after = float(rolling_speed - race_speed), float(rolling_speed - w1)
    if friction_force != 0.0 and (before > 0) - (before < 0) != (after > 0) - (after < 0):
        return rolling_speed  # the step passed (or left) the rolling speed: it rolls
    return w1


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
    w0, f_t, roll, r_r = np.broadcast_arrays(
        *(np.asarray(a, float) for a in (race_speed, friction_force, rolling_speed, race_radius))
    )
    args = zip(w0.flat, f_t.flat, roll.flat, r_r.flat, strict=True)
    out = [race_speed_after(*a, h, params) for a in args]
    return np.array(out).reshape(w0.shape)
